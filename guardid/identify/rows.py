"""Logs -> identification rows under one :class:`ConditioningOptions`.

:func:`stacked_rows` conditions each run on its own with the same options, computes the base
regressor of the usable rows and stacks the runs. An automatic cut-off is chosen once for
all runs (:mod:`guardid.identify.cutoff`, scored by :func:`cutoff_scores`).
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np

from guardid.conditioning import condition
from guardid.conditioning import momentum as mom
from guardid.conditioning.filters import (
    DEFAULT_ORDER,
    decimation_factor,
    is_uniform,
    zero_phase_lowpass,
)
from guardid.conditioning.options import ConditioningOptions
from guardid.conditioning.parallel import parallel_filter
from guardid.conditioning.stiction import guard_periods
from guardid.conditioning.units import counts_per_joint_rev
from guardid.dynamics import ChainModel, build_model
from guardid.errors import GuardidError
from guardid.estimators import ColumnNoise
from guardid.identify.cutoff import (
    MIN_BLOCKS,
    CutoffChoice,
    ParallelChoice,
    choose_cutoff_cv,
    choose_parallel_filter,
    motion_bandwidth,
)

STICTION_GUARD_SHARE = 0.95
"""guardid logs: rows closer to a stuck / reversing sample than the span that holds this
share of the low-pass's impulse response are dropped (stick/slip of the PID-tracked joints
smeared by the filter; :func:`~guardid.conditioning.stiction.guard_periods`: 1.04 cut-off
periods at order 4). Measured on the guard robot (``bench/bench_std_check.py``, 20 seeds):
0.6 periods left the pan's Fv1 and Fc1 biased by 1.3-1.4 std on the default excitation;
this guard, 0.4-0.5 std, at the price of a third of the rows (std about 1.3x larger). The
Coulomb columns low-passed like the effort with a narrower guard did worse there."""
STOP_GUARD_SHARE = 0.99
"""Rows closer to a sample at a joint's position limit (a hard stop: contact force and
impact, not in the model) than the span holding this share are dropped (about 1.75 cut-off
periods at order 4). Applies to every log whose robot has position limits."""
STICTION_GUARD_PERIODS = guard_periods(DEFAULT_ORDER, STICTION_GUARD_SHARE)
"""The stiction guard at the default order [cut-off periods] (for callers)."""
MIN_ROWS_PER_PARAMETER = 10
"""A cut-off candidate is eligible only if its conditioning keeps more rows than this many
per identified parameter (at its own decimation) [-]."""
MOST_ROWS_DROPPED = 0.25
"""Warn when fewer than this fraction of the conditioned samples are usable [-] (a robot with
stick/slip loses more than half of them to the stiction guard as a matter of course: the
guard robot's optimised excitation keeps 38 %)."""
PARALLEL_EDGE_PERIODS = 3.0
"""The parallel filter spreads the rows at the ends (filter transients, stencil edges) over
about this many of its periods: rows that close to the first-stage's ends are dropped [-]
(the padding of :func:`~guardid.conditioning.filters.zero_phase_lowpass` too)."""
POWER_BEYOND_CUTOFF = 0.1
"""Warn when the low-pass removes more than this fraction of the effort's power [-]."""


@dataclass
class Rows:
    """Stacked identification rows and how they were made.

    ``cond``: the runs' conditioned signals joined; ``A`` (M, n, b') base regressor of the
    identified columns; ``y`` (M, n) effort minus the known torque [N m | N | effort unit];
    ``options``: the options used, cut-off resolved; ``choice``: the cut-off's
    cross-validation (None when given); ``warnings``: doubts about the conditioning;
    ``runs``: per run its own conditioned signals (the momentum form: what
    :func:`momentum_rows_of` needs); ``acceleration_rows``: the same runs in the
    acceleration form, made once when a method fits only in it (iv, didim:
    :func:`guardid.identify.pipeline.closed_loop_rows`), else None; ``column_noise``: the
    encoder rounding's noise in the identified columns of ``A`` and in ``y`` (the momentum
    form, :func:`quantisation_noise_of`), which LS and WLS remove, else None.
    """

    cond: object
    A: np.ndarray
    y: np.ndarray
    options: ConditioningOptions
    choice: CutoffChoice | None = None
    warnings: list[str] = field(default_factory=list)
    runs: list = field(default_factory=list)
    acceleration_rows: Rows | None = None
    column_noise: ColumnNoise | None = None

    def __iter__(self):  # (cond, A, y), as before
        return iter((self.cond, self.A, self.y))


def free_columns(model, description) -> list[int]:
    """Indices of the identified base parameters (friction offsets declared absent with
    ``offset: null`` are left out)."""
    fixed = {
        f"Fo{j + 1}"
        for j, joint in enumerate(description.joints)
        if joint.friction is not None and not getattr(joint.friction, "offset_modelled", True)
    }
    return [i for i, name in enumerate(model.base.names) if name not in fixed]


def drive_gain(description) -> np.ndarray:
    """Current-to-torque gain (n,) [N m/A]; 1 for a joint without drive (torque source)."""
    gains = []
    for j in description.joints:
        d = j.drive
        gains.append(1.0 if d is None else d.gear_ratio * d.efficiency * d.kt)
    return np.array(gains)


def _smooth_joints(description) -> np.ndarray:
    """(n,) bool: joints whose friction model is smooth at zero velocity."""
    return np.array(
        [j.friction is not None and j.friction.model != "sign" for j in description.joints]
    )


def _smooth_or_none(description) -> np.ndarray:
    """(n,) bool: joints without friction or with a friction model smooth at zero velocity
    (their rows near zero velocity are kept by default)."""
    return np.array([j.friction is None or j.friction.model != "sign" for j in description.joints])


def condition_kwargs(options, fs_hz, cutoff_hz, effort_is_torque, description) -> dict:
    """Keyword arguments of :func:`guardid.conditioning.condition` for ``options`` with the
    cut-off ``cutoff_hz`` [Hz] (every automatic choice resolved; see ConditioningOptions)."""
    o = options
    kw = {"cutoff_hz": float(cutoff_hz), "order": o.order, "edge_s": o.edge_s}
    if effort_is_torque:
        kw["align_period_mean"] = False
    guard = o.stiction_guard_s
    if guard is None:
        guard = (
            0.0 if effort_is_torque else guard_periods(o.order, STICTION_GUARD_SHARE) / cutoff_hz
        )
    kw["stiction_guard_s"] = guard
    limits = position_limits(description)
    if limits is not None:
        kw["position_limits"] = limits
        kw["stop_guard_s"] = guard_periods(o.order, STOP_GUARD_SHARE) / cutoff_hz
    kw["flat_is_stuck"] = (not effort_is_torque) if o.flat_is_stuck is None else o.flat_is_stuck
    if o.decimate is not None:
        kw["decimate"] = o.decimate
    elif effort_is_torque:
        kw["decimate"] = decimation_factor(fs_hz, cutoff_hz)
    else:
        kw["decimate"] = max(1, int(fs_hz / (2.0 * cutoff_hz)))
    if o.parallel_filter_hz:
        kw["decimate"] = 1  # decimation happens after the parallel filter
    if o.stiction_threshold is not None:
        kw["stiction_threshold"] = o.stiction_threshold
    else:  # smooth friction holds through zero velocity: keep those joints' rows
        kw["stiction_threshold"] = np.where(_smooth_joints(description), 0.0, np.nan)
    return kw


def position_limits(description) -> np.ndarray | None:
    """(n, 2) joint position limits [rad | m] of ``description`` (NaN where none), or None
    when no joint has one."""
    rows = []
    for j in description.joints:
        pos = j.limits.position if j.limits is not None else None
        rows.append((np.nan, np.nan) if pos is None else (float(pos[0]), float(pos[1])))
    out = np.array(rows, dtype=float)
    return None if np.all(np.isnan(out)) else out


def _gain(description, in_current_units, effort_is_torque):
    if in_current_units:
        return None
    return np.ones(len(description.joints)) if effort_is_torque else drive_gain(description)


ROWS_CHUNK = 32768
"""Samples whose regressor is formed at a time in :func:`_rows_of` (its temporaries, the
full regressor before the base projection, stay a few tens of MB on long logs)."""


def _rows_of(model, description, cond, free, in_current_units, mask=None):
    """(A (M, n, b'), y (M, n), y_raw (M, n)) on the rows of ``mask`` (default all)."""
    m = slice(None) if mask is None else mask
    q, qd, qdd, tau = cond.q[m], cond.qd[m], cond.qdd[m], cond.tau[m]
    tau_raw = None if cond.tau_raw is None else cond.tau_raw[m]
    A = y = raw = None
    for s in range(0, max(len(q), 1), ROWS_CHUNK):  # per sample: the same values in chunks
        c = slice(s, s + ROWS_CHUNK)
        A_c, y_c, raw_c = _rows_chunk(model, q[c], qd[c], qdd[c], tau[c],
                                      None if tau_raw is None else tau_raw[c], free,
                                      in_current_units)  # fmt: skip
        if A is None:
            if len(q) <= ROWS_CHUNK:
                return A_c, y_c, raw_c
            A = np.empty((len(q), *A_c.shape[1:]))
            y = np.empty((len(q), *y_c.shape[1:]))
            raw = None if raw_c is None else np.empty((len(q), *raw_c.shape[1:]))
        A[c], y[c] = A_c, y_c
        if raw is not None:
            raw[c] = raw_c
    return A, y, raw


def _rows_chunk(model, q, qd, qdd, tau, tau_raw, free, in_current_units):
    A_all = model.base_regressor(q, qd, qdd)
    known = model.known_torque(q, qd, qdd)
    fixed = [i for i in range(A_all.shape[2]) if i not in free]
    if fixed and not in_current_units:
        known = known + A_all[:, :, fixed] @ model.base.values(model.params)[fixed]
    raw = None if tau_raw is None else tau_raw - known
    return A_all[:, :, free], tau - known, raw


def identification_rows(
    t_s,
    q_rad,
    effort,
    description,
    options: ConditioningOptions | None = None,
    *,
    in_current_units: bool = False,
    effort_is_torque: bool = False,
    highest_harmonic_hz: float | None = None,
):
    """(conditioned, A (M, n, b'), y (M, n)) of one run: :func:`stacked_rows` on it alone."""
    return tuple(
        stacked_rows(
            [(t_s, q_rad, effort)],
            description,
            options,
            in_current_units=in_current_units,
            effort_is_torque=effort_is_torque,
            highest_harmonic_hz=highest_harmonic_hz,
        )  # fmt: skip
    )


def condition_run(run, description, options, cutoff_hz, in_current_units, effort_is_torque,
                   model, free, friction_filter=False, fallback=True):  # fmt: skip
    """One run (t, q, effort[, qd]) conditioned under ``options`` at ``cutoff_hz`` [Hz]:
    (conditioned signals, A (M, n, b'), y (M, n), y_raw (M, n), A_plain (M, n, b')) on every
    conditioned (decimated) sample; the usable rows are ``cond.mask``.

    With ``friction_filter`` the regressor is computed on every sample before decimation;
    its Coulomb (and Stribeck) columns are low-passed with the same zero-phase filter as the
    effort: the filtered effort carries the friction jump at a reversal smeared over about a
    cut-off period, and so does the column then (parallel filtering of the one strongly
    nonlinear term). ``A_plain`` is the regressor without that (the model's prediction).
    Falls back to no stiction guard when the guard would leave too few rows (3 per
    identified parameter; said in the notes), unless ``fallback`` is False (the cut-off's
    cross-validation: a candidate that keeps too few rows with the guard is not eligible,
    rather than scored on rows the friction model does not hold on).
    """
    t, q, effort, *rest = run
    t = np.asarray(t, dtype=float)
    fs = 1.0 / float(np.median(np.diff(t)))
    kw = condition_kwargs(options, fs, cutoff_hz, effort_is_torque, description)
    k = kw.pop("decimate")
    gain = _gain(description, in_current_units, effort_is_torque)
    kw["qd_measured"] = rest[0] if rest else None
    cols = friction_columns(model, free)
    full_rate = bool(cols and friction_filter)  # those columns are filtered at every sample

    def conditioned(k):
        """The run conditioned at every sample; with k > 1 and no column to filter only
        every k-th sample is kept (the regressor is per sample: the same rows, and the
        full-rate signals and regressor, k times larger, are never held)."""
        every = k if k > 1 and not full_rate else 1
        return condition(t, q, effort, gain=gain, decimate=1, keep_every=every, **kw), every

    cond, every = conditioned(k)
    if (fallback and (cond.mask if every > 1 else cond.mask[::k]).sum() <= 3 * len(free)
            and options.stiction_guard_s is None and not effort_is_torque):  # fmt: skip
        kw.update(stiction_guard_s=0.0, flat_is_stuck=False)
        if options.decimate is None and not options.parallel_filter_hz:
            k = decimation_factor(fs, cutoff_hz)
        cond, every = conditioned(k)
        cond.notes.append("too few rows with the stiction guard: guard disabled")
    A, y, raw = _rows_of(model, description, cond, free, in_current_units)
    plain = A
    if cols and friction_filter:
        A = A.copy()
        block = A[:, :, cols]
        flat = zero_phase_lowpass(block.reshape(len(block), -1), fs, cutoff_hz, options.order)
        A[:, :, cols] = flat.reshape(block.shape)
        cond.notes.append("Coulomb columns low-passed like the effort")
    if k > 1:
        fields = ("t", "q", "qd", "qdd", "tau", "mask", "stiction", "tau_raw")
        dropped = {key: int(round(v / k)) for key, v in cond.dropped.items()}
        kept = {} if every > 1 else {f: _kept(getattr(cond, f), k) for f in fields}
        cond = replace(
            cond, decimation=k, **kept, dropped=dropped,
            notes=[*cond.notes, f"decimated by {k}: {fs / k:.4g} Hz"],
        )  # fmt: skip
        if every == 1:
            A, y, raw, plain = A[::k], y[::k], raw[::k], plain[::k]
    return cond, A, y, raw, plain


def _kept(x, k):
    """Every k-th row of ``x`` as its own array (the full-rate one can then be freed)."""
    return None if x is None else np.ascontiguousarray(x[::k])


def friction_columns(model, free) -> list[int]:
    """Positions (among the identified columns) of the Coulomb and Stribeck columns of the
    joints with a smooth friction model (a sign model's rows near reversals are dropped:
    its jump is never inside the rows, and a stuck joint does not follow it anyway)."""
    names = [model.base.names[i] for i in free]
    smooth = {
        str(j + 1)
        for j, joint in enumerate(model.description.joints)
        if joint.friction is not None and joint.friction.model != "sign"
    }
    return [i for i, n in enumerate(names) if n.startswith(("Fc", "Fs")) and n[2:] in smooth]


def _parallel(cond, A_all, y, free, hz, decimate=None):
    """Gautier's parallel filter at ``hz`` [Hz] on the regressor and the torque of every
    conditioned sample, then decimation by ``decimate`` (default: new Nyquist >= 2 hz;
    docs/FOREIGN_LOGS.md)."""
    fs = 1.0 / float(np.median(np.diff(cond.t)))
    if not 0.0 < hz < 0.5 * fs:
        raise GuardidError(f"--parallel-filter: {hz:g} Hz must be in (0, {0.5 * fs:g}) Hz")
    sig = (cond.q, cond.qd, cond.qdd, cond.stiction)
    k, (A_all, y, tau, mask, q, qd, qdd, stuck) = parallel_filter(
        fs, hz, A_all, y, cond.tau, cond.mask, *sig, decimate=decimate
    )
    t = cond.t[::k]
    usable = cond.t[cond.mask] if cond.mask.any() else cond.t
    edge = PARALLEL_EDGE_PERIODS / hz
    mask = mask & (t >= usable[0] + edge) & (t <= usable[-1] - edge)
    note = f"parallel filter {hz:.3g} Hz on the regressor and the torque, then decimation by {k}"
    raw = None if cond.tau_raw is None else cond.tau_raw[::k]
    cond = replace(
        cond, t=t, q=q, qd=qd, qdd=qdd, tau=tau, mask=mask, stiction=stuck, tau_raw=raw,
        decimation=cond.decimation * k, notes=[*cond.notes, note],
    )  # fmt: skip
    return cond, A_all[mask], y[mask]


def cutoff_scores(runs, description, options, cands, blocks, in_current_units, effort_is_torque):
    """Per candidate cut-off [Hz]: (held-out relative rms error of the measured effort,
    full-data LS estimate) by K-fold cross-validation over ``blocks`` contiguous time blocks
    per run (:mod:`guardid.identify.cutoff`)."""
    model = build_model(description)
    free = free_columns(model, description)
    t0 = np.asarray(runs[0][0], dtype=float)
    fs = 1.0 / float(np.median(np.diff(t0)))
    common = options.with_(parallel_filter_hz=None)
    k = condition_kwargs(common, fs, max(cands), effort_is_torque, description)["decimate"]
    common = replace(common, decimate=k, parallel_filter_hz=None)
    flags = (in_current_units, effort_is_torque, model, free)
    middle = cands[len(cands) // 2]  # evaluation rows: those usable under the middle one
    # only their masks are kept (a long log's conditioned signals need not stay in memory)
    ref = [condition_run(r, description, common, middle, *flags)[0].mask for r in runs]
    variants = [options.friction_filter]
    if options.friction_filter is None:
        variants = [False, True] if friction_columns(model, free) else [False]
    scores, thetas, chosen = [], [], []
    for fc in cands:
        best = (np.inf, None, False)
        # rows the final fit would keep at this candidate's own decimation
        k_own = condition_kwargs(options.with_(parallel_filter_hz=None), fs, fc, effort_is_torque,
                                 description)["decimate"]  # fmt: skip
        for ff in variants:
            parts = []  # (block id, A_fit, y_fit, A_eval, y_raw_eval)
            for r_i, (run, rc) in enumerate(zip(runs, ref, strict=True)):
                c, A, y, raw, plain = condition_run(run, description, common, fc, *flags, ff,
                                                     fallback=False)  # fmt: skip
                n, fit = len(c.t), c.mask
                del c  # only its mask is needed here
                block = np.minimum((np.arange(n) * blocks) // max(n, 1), blocks - 1)
                evaluate = rc[:n] if len(rc) >= n else np.zeros(n, bool)
                for b in range(blocks):
                    sel = block == b
                    parts.append(((r_i, b), A[sel & fit], y[sel & fit],
                                  plain[sel & evaluate], raw[sel & evaluate]))  # fmt: skip
                del A, y, raw, plain  # before the next candidate's are made
            score, theta = _kfold(parts, min_rows=3 * len(free))
            if sum(len(p[1]) for p in parts) * k / max(k_own, 1) <= MIN_ROWS_PER_PARAMETER * len(
                free
            ):  # too few rows left at its own decimation: not eligible
                score = np.nan
            if not score >= best[0]:  # NaN never wins
                best = (score, theta, bool(ff))
        scores.append(best[0] if np.isfinite(best[0]) else np.nan)
        thetas.append(best[1])
        chosen.append(best[2])
    return scores, thetas, chosen


def _kfold(parts, min_rows: int):
    """Held-out relative rms error over all parts (each left out once) and the full fit;
    NaN when a fold keeps ``min_rows`` fitting rows or fewer."""
    p = parts[0][1].shape[2]
    total = sum(len(A) for _, A, _, _, _ in parts)
    normals = []
    for _, A, y, _, _ in parts:
        a = A.reshape(-1, p)
        normals.append((a.T @ a, a.T @ y.reshape(-1)))
    G = sum(n[0] for n in normals)
    h = sum(n[1] for n in normals)
    theta_full = _solve(G, h)
    res2 = ref2 = 0.0
    for (_, A, _, Ae, ye), (g, v) in zip(parts, normals, strict=True):
        if len(ye) == 0:
            continue
        theta = _solve(G - g, h - v) if total - len(A) > min_rows else None
        if theta is None:
            return np.nan, theta_full
        r = ye - Ae @ theta
        res2 += float(np.sum(r**2))
        ref2 += float(np.sum(ye**2))
    return (np.sqrt(res2 / ref2) if ref2 > 0 else np.nan), theta_full


def _solve(G, h):
    """Solution of G theta = h with column scaling; None if singular."""
    d = np.sqrt(np.clip(np.diag(G), 1e-300, None))
    try:
        x = np.linalg.solve(G / np.outer(d, d), h / d)
    except np.linalg.LinAlgError:
        return None
    return x / d


def stacked_rows(
    runs,
    description,
    options: ConditioningOptions | None = None,
    *,
    in_current_units: bool = False,
    effort_is_torque: bool = False,
    highest_harmonic_hz: float | None = None,
) -> Rows:
    """Rows of several runs (t [s] (N,), q (N, n), effort (N, n)), each conditioned on its
    own under the same ``options`` and stacked (times shifted so that they keep increasing).

    ``options.cutoff_hz`` None: in the momentum form 2 x ``highest_harmonic_hz`` [Hz] (the
    excitation's highest harmonic from a guardid log header; else 2 x the positions'
    bandwidth), at least 2 Hz (:func:`guardid.conditioning.momentum.momentum_cutoff`); in the
    acceleration form chosen by cross-validation over the runs
    (:func:`guardid.identify.cutoff.choose_cutoff_cv`, informed by ``highest_harmonic_hz``).
    The form: ``options.equation``, or :func:`resolve_equation`'s default.
    ``effort_is_torque``: the effort is measured joint torque (gain 1, instantaneous
    samples); ``in_current_units``: no current-to-torque gain (y in the effort's unit).
    """
    options = options or ConditioningOptions()
    runs = list(runs)
    model = build_model(description)
    free = free_columns(model, description)
    options, why = resolve_equation(options, runs, model, effort_is_torque)
    if options.equation == "momentum":
        return _momentum_rows(runs, description, options, model, free, in_current_units,
                              effort_is_torque, highest_harmonic_hz)  # fmt: skip
    choice = None
    cutoff = options.cutoff_hz
    if cutoff is None:
        fs = 1.0 / float(np.median(np.diff(np.asarray(runs[0][0], dtype=float))))

        def score(cands, blocks):
            return cutoff_scores(runs, description, options, cands, blocks, in_current_units,
                                 effort_is_torque)  # fmt: skip

        choice = choose_cutoff_cv(runs, score, fs, highest_harmonic_hz)
        cutoff = choice.cutoff_hz
    ff = options.friction_filter
    if ff is None:
        ff = bool(choice.friction_filter) if choice is not None else False
    used = replace(options, cutoff_hz=float(cutoff), friction_filter=ff)
    parallel = None
    if options.cutoff_hz is None and options.parallel_filter_hz is None:
        flags = (in_current_units, effort_is_torque, model, free)
        parallel = _auto_parallel(runs, description, used, *flags)
        if parallel.hz is not None:
            used = replace(used, parallel_filter_hz=parallel.hz, decimate=parallel.decimate)
    conds, As, ys = [], [], []
    for run in runs:
        c, A, y, _, _ = condition_run(run, description, used, cutoff, in_current_units,
                                       effort_is_torque, model, free, ff)  # fmt: skip
        if used.parallel_filter_hz:
            c, A, y = _parallel(c, A, y, free, used.parallel_filter_hz, used.decimate)
        else:
            A, y = A[c.mask], y[c.mask]
        conds.append(c)
        As.append(A)
        ys.append(y)
    A, y = _stacked(As, ys, free)
    joined = _join(conds)
    if choice is not None:
        joined.notes.insert(0, f"cut-off {cutoff:g} Hz: {choice.reason}")
        if parallel is not None:
            joined.notes.insert(1, parallel.reason)
    else:
        joined.notes.insert(0, f"cut-off {cutoff:g} Hz set by the caller")
    joined.notes.insert(1, f"equation: acceleration form ({why})")
    return Rows(joined, A, y, used, choice, _doubts(conds, choice))


def _stacked(As, ys, free):
    """The runs' rows stacked; one-line error when too few for the parameters."""
    A, y = np.concatenate(As), np.concatenate(ys)
    if len(A) <= len(free):
        raise GuardidError(
            f"only {len(A)} usable rows after conditioning (need more than {len(free)}): "
            "the run is too short or the joints hardly move"
        )
    return A, y


def momentum_unsuitable(runs, model, effort_is_torque, options) -> str:
    """Why the momentum form is not the automatic choice for these runs ('' when it is)."""
    if not isinstance(model, ChainModel):
        return "not a serial chain"
    if effort_is_torque:
        return "measured torque samples: the momentum form needs period means of the current"
    if options.parallel_filter_hz or options.friction_filter:
        return "a parallel or friction filter was asked for"
    for run in runs:
        t = np.asarray(run[0], dtype=float)
        steps = np.diff(t)
        ticks = steps / np.median(steps)
        if not is_uniform(t) and np.any(np.abs(ticks - np.round(ticks)) > 1e-6):
            return "uneven time stamps"
    return ""


def resolve_equation(options, runs, model, effort_is_torque):
    """(options with the equation form and the filter order resolved, why that form)."""
    eq = options.equation
    why = momentum_unsuitable(runs, model, effort_is_torque, options) if eq is None else ""
    if eq is None:
        eq = "acceleration" if why else "momentum"
        why = why or "the default for motor-current logs on a tick grid"
    else:
        why = "asked for"
        if eq == "momentum" and not isinstance(model, ChainModel):
            raise GuardidError("equation momentum: only for serial chains (give acceleration)")
        if eq == "momentum" and (options.parallel_filter_hz or options.friction_filter):
            raise GuardidError("equation momentum: no parallel or friction filter (its one "
                               "filter is on both sides already)")  # fmt: skip
    order = options.order
    if order is None:
        order = mom.DEFAULT_ORDER if eq == "momentum" else DEFAULT_ORDER
    return replace(options, equation=eq, order=int(order)), why


def _momentum_rows(runs, description, options, model, free, in_current_units, effort_is_torque,
                   highest_harmonic_hz) -> Rows:  # fmt: skip
    """:func:`stacked_rows` in the momentum form (:mod:`guardid.conditioning.momentum`)."""
    t0 = np.asarray(runs[0][0], dtype=float)
    fs = 1.0 / float(np.median(np.diff(t0)))
    cutoff = options.cutoff_hz
    if cutoff is None:
        band = motion_bandwidth(runs, highest_harmonic_hz)
        cutoff = mom.momentum_cutoff(fs, band, bool(highest_harmonic_hz))
        src = "the excitation's highest harmonic" if highest_harmonic_hz else "the positions' "
        src += "" if highest_harmonic_hz else "99.5 % energy bandwidth"
        factor = mom.HARMONIC_FACTOR if highest_harmonic_hz else mom.SPECTRUM_FACTOR
        reason = (f"cut-off {cutoff:g} Hz of the momentum form's filter: {factor:g} x {src} "
                  f"({band:.3g} Hz), at least {mom.MIN_CUTOFF_HZ:g} Hz")  # fmt: skip
    else:
        reason = f"cut-off {cutoff:g} Hz of the momentum form's filter, set by the caller"
    used = replace(options, cutoff_hz=float(cutoff), friction_filter=False)
    gain = _gain(description, in_current_units, effort_is_torque)
    limits = position_limits(description)
    thr = options.stiction_threshold
    if thr is None:  # smooth friction holds through zero velocity
        thr = np.where(_smooth_joints(description), 0.0, np.nan)
    flat = (not effort_is_torque) if options.flat_is_stuck is None else options.flat_is_stuck
    fixed = [i for i in range(len(model.base.names)) if i not in free]
    base = model.base.values(model.params)
    conds, As, ys, noises = [], [], [], []
    for run in runs:
        t, q, effort, *rest = run
        cond, A_all, y = mom.condition_momentum(
            t, q, effort, model, gain=gain, cutoff_hz=cutoff, order=used.order,
            decimate=options.decimate, effort_is_torque=effort_is_torque, stiction_threshold=thr,
            flat_is_stuck=flat, position_limits=limits, velocity=rest[0] if rest else None,
        )  # fmt: skip
        if fixed and not in_current_units:
            y = y - A_all[:, :, fixed] @ base[fixed]
        m = cond.mask
        noises.append(quantisation_noise_of(cond, rest, description, options, model, free,
                                            base if fixed and not in_current_units else None,
                                            gain))  # fmt: skip
        conds.append(cond)
        As.append(A_all[m][:, :, free])
        ys.append(y[m])
    A, y = _stacked(As, ys, free)
    joined = _join(conds)
    joined.notes.insert(0, reason)
    noise, note = _noise_of_runs(noises)
    joined.notes.append(note)
    used = replace(used, quantisation=noise is not None)
    choice = CutoffChoice(float(cutoff), reason.split(": ", 1)[-1], [float(cutoff)])
    return Rows(joined, A, y, used, choice if options.cutoff_hz is None else None,
                _doubts(conds, None), conds, column_noise=noise)  # fmt: skip


def quantisation_noise_of(cond, rest, description, options, model, free, base, gain):
    """(S (n, b', b'), c (n, b')) of one run's momentum rows (:func:`mom.quantisation_noise`
    on the identified columns; ``base`` (b,) the description's base values when the fixed
    columns' part was taken off y, else None), or a string saying why there is none:
    ``options.quantisation`` False (True, as None: where the log allows), measured
    velocities, a joint without an encoder, or positions off the encoder's grid (not whole
    counts: the rounding is not that one)."""
    if options.quantisation is False:
        return "off (--no-quantisation-compensation)"
    why = ""
    if rest:
        why = "the log's measured velocities are used"
    elif any(j.encoder is None for j in description.joints):
        why = "a joint without an encoder in the robot description"
    else:
        res = 2.0 * np.pi / counts_per_joint_rev(description)
        off = ~mom.on_grid(cond.momentum.q, res)
        if off.any():
            names = ", ".join(description.joints[j].name for j in np.flatnonzero(off))
            why = f"positions of {names} off the encoder's grid"
    if why:
        return why
    damping = mom.electrical_damping(description, gain)
    S, c = mom.quantisation_noise(cond.momentum, model, res, damping)
    fixed = [i for i in range(S.shape[1]) if i not in free]
    cross = c[:, free]
    if base is not None and fixed:  # y less the fixed columns: their noise is in y
        cross = cross - S[:, free][:, :, fixed] @ base[fixed]
    return S[:, free][:, :, free], cross


def _noise_of_runs(noises):
    """(ColumnNoise summed over the runs or None, a note for the conditioning notes)."""
    why = [n for n in noises if isinstance(n, str)]
    if why:
        return None, f"encoder quantisation not compensated: {why[0]}"
    S = sum(n[0] for n in noises)
    c = sum(n[1] for n in noises)
    what = ("encoder quantisation compensated (bias-compensated LS and WLS): the rounding's "
            f"noise in the columns estimated from {mom.QUANTISATION_DRAWS} draws on at most "
            f"{mom.QUANTISATION_WINDOWS} windows of {mom.QUANTISATION_WINDOW_TICKS} ticks per "
            "run")  # fmt: skip
    return ColumnNoise(S, c, what), what


def momentum_rows_of(rows: Rows, run: int, q, model, free) -> np.ndarray:
    """(M_run, n, b') run ``run``'s usable rows of the momentum form recomputed from other
    positions ``q`` (N, n) on the same ticks (e.g. its closed loop simulated, for
    instruments): the measured run's cuts, filter and kept rows, velocities from ``q``."""
    cond = rows.runs[run]
    A_all = mom.rows_like(cond.momentum, model, np.asarray(q, dtype=float))
    return A_all[cond.mask][:, :, free]


def predicted_effort(cond, model, theta) -> np.ndarray:
    """(M, n) the effort that ``model`` with base parameters ``theta`` (b,) predicts on the
    usable rows of ``cond`` (either equation form; zero on a joint's cut rows)."""
    m = cond.mask
    if getattr(cond, "equation", "acceleration") == "momentum":
        return mom.regressor_rows(cond.momentum, model)[m] @ theta
    q, qd, qdd = cond.q[m], cond.qd[m], cond.qdd[m]
    return model.base_regressor(q, qd, qdd) @ theta + model.known_torque(q, qd, qdd)


def _auto_parallel(runs, description, used, in_current_units, effort_is_torque, model, free):
    """The parallel filter chosen from the data (:func:`choose_parallel_filter`) for the
    runs conditioned under ``used`` (cut-off resolved). Off when some row inside the ends
    was dropped (near zero velocity, stuck): the filter mixes neighbouring samples, so the
    model must hold on every one of them."""
    off_msg = "parallel filter off: rows near zero velocity were dropped"
    if used.stiction_threshold is None and not np.all(_smooth_or_none(description)):
        return ParallelChoice(None, f"{off_msg} (sign friction; the filter would mix them "
                              "back in)")  # fmt: skip
    flags = (in_current_units, effort_is_torque, model, free, used.friction_filter)
    fine = [condition_run(r, description, replace(used, decimate=1), used.cutoff_hz, *flags)
            for r in runs]  # fmt: skip
    inside = sum(c.dropped.get(k, 0) for c, *_ in fine for k in c.dropped if "velocity" in k)
    if inside:
        return ParallelChoice(None, f"{off_msg} (the filter would mix them back in)")

    off = [condition_run(r, description, used, used.cutoff_hz, *flags) for r in runs]
    blocks = max(1, -(-MIN_BLOCKS // len(runs)))

    def block_of(t, c):
        span = max(float(c.t[-1] - c.t[0]), 1e-300)
        return np.minimum(((t - c.t[0]) / span * blocks).astype(int), blocks - 1)

    def score(hz):
        if hz is None:
            fits = [(A[c.mask], y[c.mask], c.t[c.mask]) for c, A, y, _, _ in off]
        else:
            k = parallel_decimation(fine[0][0], hz)
            fits = [_parallel(c, A, y, free, hz, k) for c, A, y, _, _ in fine]
            fits = [(A, y, c.t[c.mask]) for c, A, y in fits]
        parts = []
        for (A, y, t), (c, _, _, raw, plain) in zip(fits, off, strict=True):
            fit_block, eval_block = block_of(t, c), block_of(c.t, c)
            for b in range(blocks):
                ev = c.mask & (eval_block == b)
                parts.append((b, A[fit_block == b], y[fit_block == b], plain[ev], raw[ev]))
        held_out, _ = _kfold(parts, min_rows=3 * len(free))
        A = np.concatenate([f[0] for f in fits])
        y = np.concatenate([f[1] for f in fits])
        return covariance_log_volume(A, y), held_out

    choice = choose_parallel_filter(used.cutoff_hz, score)
    if choice.hz is not None:
        choice.decimate = parallel_decimation(fine[0][0], choice.hz)
    return choice


def parallel_decimation(cond, hz: float) -> int:
    """Decimation after an automatic parallel filter at ``hz`` [Hz]: new Nyquist about
    ``hz``, so that a residual white before the filter stays about white on the kept rows
    (closer rows would be correlated and least squares' std too small)."""
    fs = 1.0 / float(np.median(np.diff(cond.t)))
    return decimation_factor(fs, hz, nyquist_margin=1.0)


def covariance_log_volume(A, y) -> float:
    """log det(s^2 (A^T A)^-1) / p for the rows A (M, n, p), y (M, n): the log of the
    geometric mean of the least-squares estimate's variances (the covariance's volume per
    parameter) [-]; NaN when rank-deficient or with at most 3 p rows."""
    p = A.shape[-1]
    a, b = A.reshape(-1, p), y.reshape(-1)
    if len(b) <= 3 * p:
        return np.nan
    d = np.sqrt(np.sum(a * a, axis=0))
    if np.any(d == 0):
        return np.nan
    x, *_ = np.linalg.lstsq(a / d, b, rcond=None)
    r = b - (a / d) @ x
    s2 = float(r @ r) / (len(b) - p)
    sign, logdet = np.linalg.slogdet((a / d).T @ (a / d))
    if sign <= 0 or s2 <= 0:
        return np.nan
    return float(np.log(s2) - (logdet + 2.0 * np.sum(np.log(d))) / p)


def _join(conds):
    if len(conds) == 1:
        return replace(conds[0], notes=[n for n in conds[0].notes if not n.startswith("cut-off")])
    ts, start = [], 0.0
    for c in conds:
        ts.append(c.t - c.t[0] + start)
        start = ts[-1][-1] + float(np.median(np.diff(c.t)))
    notes = [n for n in conds[0].notes if not n.startswith("cut-off")]
    notes.append(f"{len(conds)} runs conditioned separately, rows stacked")
    dropped = {k: sum(c.dropped.get(k, 0) for c in conds) for k in conds[0].dropped}
    raw = None
    if all(c.tau_raw is not None for c in conds):
        raw = np.concatenate([c.tau_raw for c in conds])
    jm = None
    if all(c.joint_mask is not None for c in conds):
        jm = np.concatenate([c.joint_mask for c in conds])
    return replace(
        conds[0],
        t=np.concatenate(ts),
        **{f: np.concatenate([getattr(c, f) for c in conds])
           for f in ("q", "qd", "qdd", "tau", "mask", "stiction")},
        tau_raw=raw, dropped=dropped, notes=notes, joint_mask=jm, momentum=None,
    )  # fmt: skip


def rows_summary(cond) -> str:
    """'rows: M of N conditioned samples used; dropped: ...' for the report, then the
    parallel filter's notes (how it was chosen, the decimation after it), one a line."""
    n, used = len(cond.mask), int(cond.mask.sum())
    why = ", ".join(f"{v} {k}" for k, v in cond.dropped.items() if v)
    dec = f" (after decimation by {cond.decimation})" if cond.decimation > 1 else ""
    parallel = [note for note in cond.notes if note.startswith("parallel filter")]
    jm = getattr(cond, "joint_mask", None)
    if jm is not None:  # the momentum form: a joint's rows are cut on their own
        zeroed = int((~jm[cond.mask]).sum())
        return (f"rows: {used} of {n} conditioned samples{dec} used, {zeroed} joint rows of "
                f"them zeroed (that joint's equation cut)"
                + (f"; joint rows cut: {why}" if why else ""))  # fmt: skip
    return (
        f"rows: {used} of {n} conditioned samples{dec} used"
        + (f"; dropped {why}" if why else "")
        + "".join("\n" + note for note in parallel)
    )


def _doubts(conds, choice) -> list[str]:
    """Warnings about the conditioning: most rows dropped, effort power beyond the cut-off,
    a cross-validation minimum at the edge of the candidates."""
    out = []
    n = sum(len(c.mask) for c in conds)
    used = sum(int(c.mask.sum()) for c in conds)
    if n and used < MOST_ROWS_DROPPED * n:
        out.append(
            f"only {used} of {n} conditioned samples usable ({100 * used / n:.0f} %): the fit "
            "rests on a small part of the data (see the dropped rows above)"
        )
    if all(c.tau_raw is not None for c in conds):
        raw = np.concatenate([c.tau_raw - c.tau_raw.mean(0) for c in conds])
        cut = np.concatenate([c.tau_raw - c.tau for c in conds])
        total = float(np.sum(raw**2))
        frac = float(np.sum(cut**2)) / total if total > 0 else 0.0
        if frac > POWER_BEYOND_CUTOFF:
            out.append(
                f"{100 * frac:.0f} % of the effort's power lies beyond the {conds[0].cutoff_hz:g} "
                "Hz cut-off (noise, or motion the model does not see): check the cut-off"
            )
    if choice is not None and len(choice.candidates) > 1:
        if choice.cutoff_hz in (choice.candidates[0], choice.candidates[-1]):
            out.append(
                f"the cut-off {choice.cutoff_hz:g} Hz is at the edge of the candidates "
                f"({choice.candidates[0]:g}-{choice.candidates[-1]:g} Hz): the best may lie beyond"
            )
    return out
