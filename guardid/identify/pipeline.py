"""The identification pipeline: log -> conditioning -> base regressor -> estimators.

Inputs are a guardid log (or arrays in its shape) and the robot description; outputs are
the base parameters per method with their uncertainty, the torque fit, and the motors'
electrical parameters. Time comes from the tick column; lost ticks are gaps, which the
conditioning stage bridges by resampling.
"""

from __future__ import annotations

import copy
import math
from dataclasses import dataclass, field, replace

import numpy as np

from guardid.conditioning import choose_cutoff, condition
from guardid.conditioning.bandwidth import clip_cutoff
from guardid.conditioning.parallel import parallel_filter
from guardid.dynamics import build_model
from guardid.errors import GuardidError
from guardid.estimators import (
    MLP,
    RLS,
    Gradient,
    Hopfield,
    LeastSquares,
    WeightedLeastSquares,
    d_tau,
)
from guardid.identify.electrical import MotorEstimate, identify_motor

METHODS = ("ls", "wls", "rls", "hopfield", "gradient", "mlp")
POOR_REL_STD_PCT = 10.0  #: warn when a parameter's relative standard deviation exceeds this


@dataclass
class MethodResult:
    """One estimator's outcome: estimate (b,), std (b,) or None, history (K, b) or None."""

    method: str
    theta: np.ndarray
    std: np.ndarray | None = None
    rel_std_pct: np.ndarray | None = None
    history: np.ndarray | None = None
    history_t: np.ndarray | None = None
    d_tau: float = math.nan
    d_tau_per_joint: np.ndarray | None = None
    settings: dict = field(default_factory=dict)


@dataclass
class Identification:
    """Everything ``guardid identify`` reports."""

    names: tuple[str, ...]
    formulas: tuple[str, ...]
    nominal: np.ndarray  # base values from the robot description [SI]
    results: dict[str, MethodResult]
    cond: float
    rows: int
    cutoff_hz: float
    torque_unit: str
    notes: list[str]
    motors: list[MotorEstimate] = field(default_factory=list)
    warnings: list[str] = field(default_factory=list)


HARMONIC_CUTOFF_FACTOR = 8.0
"""Default cut-off = this x the excitation's highest harmonic when the log says it [-].

Measured on 60 s guard captures (13 runs, 2 optimised trajectories, highest harmonic 0.5 Hz):
5 x (2.5 Hz) leaves the stick/slip transients of the PID-tracked motion under-resolved, 8 x
(4 Hz) gave the smallest errors; the encoder-quantisation noise on qdd is still negligible.
"""
STICTION_GUARD_PERIODS = 0.6
"""Rows within this many cut-off periods of a stuck / reversing sample are dropped [-]."""


def identified_names(description) -> tuple[str, ...]:
    """Names of the base parameters that identification estimates (all but the friction
    offsets a description declares absent with ``offset: null``)."""
    model = build_model(description)
    return tuple(model.base.names[i] for i in _free_columns(model, description))


def _free_columns(model, description) -> list[int]:
    fixed = {
        f"Fo{j + 1}"
        for j, joint in enumerate(description.joints)
        if joint.friction is not None and not getattr(joint.friction, "offset_modelled", True)
    }
    return [i for i, name in enumerate(model.base.names) if name not in fixed]


def trajectory_highest_harmonic(trajectory: dict | None) -> float | None:
    """Highest frequency [Hz] of a trajectory mapping (a log header's ``trajectory``).

    Fourier series: base_freq x harmonics; sums of sines / multisines: the largest
    ``frequencies`` entry. None when unknown (then the cut-off comes from the spectrum).
    """
    if not isinstance(trajectory, dict):
        return None
    try:
        if trajectory.get("kind") == "fourier":
            return float(trajectory["base_freq"]) * int(trajectory["harmonics"])
        freqs = trajectory.get("frequencies")
        if freqs is not None:
            return float(np.max(np.abs(np.asarray(freqs, dtype=float))))
    except (KeyError, TypeError, ValueError):
        return None
    return None


def identification_rows(
    t_s,
    q_rad,
    current_a,
    description,
    cutoff_hz=None,
    in_current_units=False,
    effort_is_torque=False,
    *,
    highest_harmonic_hz: float | None = None,
    parallel_filter_hz: float | None = None,
    **kwargs,
):
    """Conditioned signals and the stacked base regressor of the usable rows.

    Returns (conditioned, A (M, n, b'), y (M, n)) where y is the joint torque [N m] minus the
    model's known torque (or the current [A] when ``in_current_units``) and b' counts the
    :func:`identified_names` columns. ``effort_is_torque``: ``current_a`` is measured joint
    torque [N m] (instantaneous samples: gain 1, no period-mean alignment). Defaults (each
    overridable through ``kwargs`` of :func:`guardid.conditioning.condition`):

    * cut-off: ``cutoff_hz`` [Hz], else :data:`HARMONIC_CUTOFF_FACTOR` x
      ``highest_harmonic_hz`` [Hz] (clipped to [0.5 Hz, 0.4 Nyquist]), else the spectrum rule;
    * stiction: a sample is flagged when a joint is below the velocity threshold or its
      encoder did not count in the period (stuck or reversing), and every row within
      :data:`STICTION_GUARD_PERIODS` / cut-off of a flagged sample is dropped;
    * decimation to a Nyquist frequency of about the cut-off, so that the rows' filtered
      noise is roughly independent and the LS standard deviations are honest.

    ``parallel_filter_hz`` [Hz] (default None = off): Gautier's parallel filter
    (:mod:`guardid.conditioning.parallel`): the regressor is computed on every conditioned
    sample (no decimation there), then its columns and y are low-passed with one filter at
    this cut-off and decimated to a Nyquist frequency of about 2x it; the usable-row mask
    is decimated with them and rows within 1 / ``parallel_filter_hz`` of either end are
    dropped. Use a cut-off near the excitation band's upper edge, below ``cutoff_hz``.
    """
    model = build_model(description)
    gain = None if in_current_units else _drive_gain(description)
    if effort_is_torque:
        gain = None if in_current_units else np.ones(len(description.joints))
        kwargs.setdefault("align_period_mean", False)
    t = np.asarray(t_s, dtype=float)
    fs = 1.0 / float(np.median(np.diff(t)))
    if cutoff_hz is None and highest_harmonic_hz:
        cutoff_hz = clip_cutoff(HARMONIC_CUTOFF_FACTOR * float(highest_harmonic_hz), fs)
    if cutoff_hz is None:
        cutoff_hz = choose_cutoff(t, np.asarray(q_rad, dtype=float).reshape(len(t), -1))
    if parallel_filter_hz:
        kwargs["decimate"] = 1  # decimation happens after the parallel filter
    auto_guard = "stiction_guard_s" not in kwargs and not effort_is_torque
    auto_dec = "decimate" not in kwargs and not effort_is_torque
    if not effort_is_torque:  # guardid logs (period-mean motor current); foreign: as before
        kwargs.setdefault("stiction_guard_s", STICTION_GUARD_PERIODS / cutoff_hz)
        kwargs.setdefault("flat_is_stuck", True)
        kwargs.setdefault("decimate", max(1, int(fs / (2.0 * cutoff_hz))))
    cond = condition(t, q_rad, current_a, cutoff_hz=cutoff_hz, gain=gain, **kwargs)
    n_free = len(_free_columns(model, description))
    if cond.mask.sum() <= 3 * n_free and auto_guard:
        # a short or slow run: the stiction guard would leave too few rows; fall back to
        # masking the flagged samples only (less accurate friction, said in the notes)
        kwargs.update(stiction_guard_s=0.0, flat_is_stuck=False)
        if auto_dec:
            kwargs.pop("decimate")
        cond = condition(t, q_rad, current_a, cutoff_hz=cutoff_hz, gain=gain, **kwargs)
        cond.notes.append("too few rows with the stiction guard: guard disabled")
    free = _free_columns(model, description)
    if parallel_filter_hz:
        return _parallel_rows(model, description, cond, free, in_current_units, parallel_filter_hz)
    m = cond.mask
    if m.sum() <= len(free):
        raise GuardidError(
            f"only {int(m.sum())} usable rows after conditioning (need more than "
            f"{len(free)}): the run is too short or the joints hardly move"
        )
    q, qd, qdd = cond.q[m], cond.qd[m], cond.qdd[m]
    A_all = model.base_regressor(q, qd, qdd)
    values = model.base.values(model.params)
    fixed = [i for i in range(A_all.shape[2]) if i not in free]
    y = cond.tau[m] - model.known_torque(q, qd, qdd)
    if fixed and not in_current_units:
        y = y - A_all[:, :, fixed] @ values[fixed]
    return cond, A_all[:, :, free], y


def _parallel_rows(model, description, cond, free, in_current_units, hz):
    """:func:`identification_rows` with the parallel filter at ``hz`` [Hz] (see there)."""
    fs = 1.0 / float(np.median(np.diff(cond.t)))
    if not 0.0 < hz < 0.5 * fs:
        raise GuardidError(f"--parallel-filter: {hz:g} Hz must be in (0, {0.5 * fs:g}) Hz")
    A_all = model.base_regressor(cond.q, cond.qd, cond.qdd)
    y = cond.tau - model.known_torque(cond.q, cond.qd, cond.qdd)
    fixed = [i for i in range(A_all.shape[2]) if i not in free]
    if fixed and not in_current_units:
        y = y - A_all[:, :, fixed] @ model.base.values(model.params)[fixed]
    sig = (cond.q, cond.qd, cond.qdd, cond.stiction)
    k, (A_all, y, tau, mask, q, qd, qdd, stuck) = parallel_filter(
        fs, hz, A_all, y, cond.tau, cond.mask, *sig
    )
    t = cond.t[::k]
    mask = mask & (t >= t[0] + 1.0 / hz) & (t <= t[-1] - 1.0 / hz)
    note = f"parallel filter {hz:.3g} Hz on the regressor and the torque, then decimation by {k}"
    cond = replace(
        cond, t=t, q=q, qd=qd, qdd=qdd, tau=tau, mask=mask, stiction=stuck,
        decimation=cond.decimation * k, notes=[*cond.notes, note],
    )  # fmt: skip
    if mask.sum() <= len(free):
        raise GuardidError(
            f"only {int(mask.sum())} usable rows after the parallel filter (need more than "
            f"{len(free)}): the run is too short or the joints hardly move"
        )
    return cond, A_all[mask][:, :, free], y[mask]


def stacked_rows(
    runs,
    description,
    cutoff_hz=None,
    in_current_units=False,
    effort_is_torque=False,
    *,
    highest_harmonic_hz: float | None = None,
    parallel_filter_hz: float | None = None,
):
    """Rows of several runs, each conditioned on its own, stacked.

    ``runs``: a sequence of (t [s] (N,), q [rad] (N, n), effort (N, n)). The cut-off
    [Hz] (``cutoff_hz``, else :func:`identification_rows`' rule on the first run) is the
    same for every run. Returns (conditioned, A (M, n, b'), y (M, n)) where
    ``conditioned`` joins the runs' conditioned signals, times shifted so that they keep
    increasing (run k starts one sample after run k-1 ends).
    """
    conds, As, ys = [], [], []
    for t, q, effort in runs:
        cond, A, y = identification_rows(
            t, q, effort, description, cutoff_hz, in_current_units, effort_is_torque,
            highest_harmonic_hz=highest_harmonic_hz, parallel_filter_hz=parallel_filter_hz,
        )  # fmt: skip
        cutoff_hz = cond.cutoff_hz
        conds.append(cond)
        As.append(A)
        ys.append(y)
    if len(conds) == 1:
        return conds[0], As[0], ys[0]
    ts, start = [], 0.0
    for c in conds:
        ts.append(c.t - c.t[0] + start)
        start = ts[-1][-1] + float(np.median(np.diff(c.t)))
    notes = list(conds[0].notes) + [f"{len(conds)} runs conditioned separately, rows stacked"]
    joined = replace(
        conds[0],
        t=np.concatenate(ts),
        **{f: np.concatenate([getattr(c, f) for c in conds])
           for f in ("q", "qd", "qdd", "tau", "mask", "stiction")},
        notes=notes,
    )  # fmt: skip
    return joined, np.concatenate(As), np.concatenate(ys)


def _drive_gain(description) -> np.ndarray:
    gains = []
    for j in description.joints:
        if j.drive is None:
            gains.append(1.0)  # ideal torque source: the effort column is torque already
        else:
            gains.append(j.drive.gear_ratio * j.drive.efficiency * j.drive.kt)
    return np.array(gains)


def identify(
    t_s,
    q_rad,
    current_a,
    description,
    methods=("ls", "wls", "rls", "hopfield"),
    cutoff_hz: float | None = None,
    beta: float = 0.01,
    lam: float = 1.0,
    gradient_eta: float = 1e-3,
    voltage_v=None,
    ticks=None,
    in_current_units: bool = False,
    effort_is_torque: bool = False,
    highest_harmonic_hz: float | None = None,
    hopfield_passes: int = 1,
    hopfield_nominal=None,
    hopfield_settle: bool = False,
    parallel_filter_hz: float | None = None,
) -> Identification:
    """Identify the base parameters of ``description`` from one run (or several).

    t_s (N,) [s]; q_rad (N, n); current_a (N, n) motor current [A] (period means, guard
    firmware) or joint torque with drive-less joints; voltage_v and ticks (optional) add the
    motors' R and Ke. ``methods`` is any subset of :data:`METHODS`. ``effort_is_torque``:
    current_a is measured joint torque [N m] (see :func:`identification_rows`).
    ``highest_harmonic_hz`` [Hz] (the excitation's, e.g. from the log header,
    :func:`trajectory_highest_harmonic`) sets the default cut-off (:func:`identification_rows`).
    Hopfield starts from ``hopfield_nominal`` (b',) (default: the description's base values)
    in a box of +-100 % of it and runs ``hopfield_passes`` times over the rows, each pass
    starting where the previous one ended (same box). ``results['hopfield']`` is the
    network's own estimate: its state at the end of the online passes (also in
    ``settings['online_end']``), with its history for the plots. With ``hopfield_settle``
    the network also settles with the whole log's weights (:meth:`Hopfield.settle`); that
    equilibrium is the least-squares estimate inside the box (it equals LS to many digits
    when LS lies inside), so it is reported separately as ``results['hopfield-eq']``,
    never as the Hopfield estimate.

    Several runs: t_s, q_rad and current_a are lists (one array per run), conditioned
    separately and their rows stacked (:func:`stacked_rows`); voltage_v and ticks are then
    lists too and the motors are estimated from all runs together (a motor-equation row
    never spans two runs). ``parallel_filter_hz`` [Hz]:
    Gautier's parallel filter on the regressor and the torque (:func:`identification_rows`).
    """
    unknown = [m for m in methods if m not in METHODS]
    if unknown:
        raise GuardidError(f"--method: unknown {', '.join(unknown)} (known: {', '.join(METHODS)})")
    model = build_model(description)
    several = isinstance(t_s, (list, tuple))
    runs = list(zip(t_s, q_rad, current_a, strict=True)) if several else [(t_s, q_rad, current_a)]
    cond, A, y = stacked_rows(
        runs, description, cutoff_hz, in_current_units, effort_is_torque,
        highest_harmonic_hz=highest_harmonic_hz, parallel_filter_hz=parallel_filter_hz,
    )  # fmt: skip
    if several:  # motors (R, Ke) from all runs, stacked
        q_rad = np.concatenate([np.asarray(r[1], dtype=float) for r in runs])
        current_a = np.concatenate([np.asarray(r[2], dtype=float) for r in runs])
        voltage_v = (
            np.concatenate([np.asarray(v, dtype=float) for v in voltage_v]) if voltage_v else None
        )
        ticks = _separated_ticks(ticks) if ticks else None
    free = _free_columns(model, description)
    names = tuple(model.base.names[i] for i in free)
    nominal = model.base.values(model.params)[free]
    dt = float(np.median(np.diff(cond.t[cond.mask])))
    results: dict[str, MethodResult] = {}
    ls = LeastSquares().fit(A, y)
    for method in methods:
        if method == "ls":
            est = ls
        elif method == "wls":
            est = WeightedLeastSquares().fit(A, y)
        elif method == "rls":
            est = RLS(lam=lam, p0=_rls_p0(A)).fit(A, y)
        elif method == "hopfield":
            start = nominal if hopfield_nominal is None else np.asarray(hopfield_nominal, float)
            est = run_hopfield(A, y, start, beta, dt, hopfield_passes)
            online_end = np.array(est.theta_)
            if hopfield_settle:
                eq = copy.deepcopy(est).settle(A, y)
        elif method == "mlp":  # seed 001's network; inputs (q, q', q'') of the usable rows
            m = cond.mask
            est = MLP().fit(A, y, X=np.hstack([cond.q[m], cond.qd[m], cond.qdd[m]]))
        else:
            est = Gradient(eta=gradient_eta, dt=dt, theta0=nominal).fit(A, y)
        results[method] = _result(method, est, A, y, cond.t[cond.mask])
        if method == "hopfield":
            results[method].settings = {
                "beta": beta,
                "passes": hopfield_passes,
                "online_end": online_end,
                "settled": hopfield_settle,
            }
            if hopfield_settle:  # labelled as what it is: the equilibrium, not the network's
                results["hopfield-eq"] = _result("hopfield-eq", eq, A, y, cond.t[cond.mask])
                results["hopfield-eq"].settings = {"equilibrium_of": "hopfield", "beta": beta}
    warnings = [
        f"{name}: relative standard deviation {r:.0f} % (poorly identifiable; "
        "a richer excitation or a longer run would help)"
        for name, r in zip(names, ls.rel_std_, strict=True)
        if r > POOR_REL_STD_PCT
    ]
    motors = []
    if voltage_v is not None and ticks is not None and not (in_current_units or effort_is_torque):
        motors = _motors(description, ticks, q_rad, voltage_v, current_a)
    return Identification(
        names=names,
        formulas=tuple(model.base.formulas[i] for i in free),
        nominal=nominal,
        results=results,
        cond=float(ls.cond_),
        rows=int(A.shape[0]),
        cutoff_hz=float(cond.cutoff_hz),
        torque_unit=cond.torque_unit,
        notes=list(cond.notes),
        motors=motors,
        warnings=warnings,
    )


def run_hopfield(A, y, nominal, beta: float, dt: float, passes: int = 1) -> Hopfield:
    """Hopfield estimator from ``nominal`` (b,) in the box nominal +- :func:`_hopfield_half_widths`.

    ``passes`` > 1 runs the log again from where the previous pass ended (same box, same
    beta [unit of y^2 times s] and sample period dt [s]); ``history_`` then spans all
    passes (sample counts continue across passes).
    """
    nominal = np.asarray(nominal, dtype=float)
    half = _hopfield_half_widths(nominal)
    bounds = (nominal - half, nominal + half)
    est = Hopfield(theta_n=nominal, bounds=bounds, beta=beta, dt=dt).fit(A, y)
    hist, counts = [est.history_], [est.history_samples_]
    for k in range(1, max(int(passes), 1)):
        est = Hopfield(theta_n=est.theta_, bounds=bounds, beta=beta, dt=dt).fit(A, y)
        hist.append(est.history_)
        counts.append(est.history_samples_ + k * A.shape[0])
    est.history_ = np.concatenate(hist)
    est.history_samples_ = np.concatenate(counts)
    return est


def _rls_p0(A) -> float:
    """RLS initial covariance [(unit of theta / unit of y)^2]: 1e6 / mean(A^2), so that the
    prior's weight is ~1e-10 of one row's whatever the regressor's scale (RLS(lambda=1)
    then ends within ~1e-8 relative of LS)."""
    scale = float(np.mean(np.square(A)))
    return 1e10 / scale if scale > 0 else 1e10


def _hopfield_half_widths(nominal: np.ndarray) -> np.ndarray:
    """The prior box of each base parameter: +-100 % of its nominal value, with a floor."""
    floor = 0.1 * float(np.median(np.abs(nominal[nominal != 0]))) if np.any(nominal) else 1.0
    return np.maximum(np.abs(nominal), floor)


def _result(method, est, A, y, t_rows) -> MethodResult:
    theta = np.asarray(est.theta_, dtype=float)
    std = getattr(est, "std_", None)
    rel = getattr(est, "rel_std_", None)
    hist = getattr(est, "history_", None)
    hist_t = None
    if hist is not None and len(hist):
        idx = np.asarray(getattr(est, "history_samples_", np.arange(len(hist))), dtype=int)
        n = len(t_rows)
        span = float(t_rows[-1] - t_rows[0]) + (float(t_rows[1] - t_rows[0]) if n > 1 else 0.0)
        hist_t = t_rows[np.clip(idx - 1, 0, None) % n] + np.clip(idx - 1, 0, None) // n * span
    return MethodResult(
        method=method,
        theta=theta,
        std=None if std is None else np.asarray(std),
        rel_std_pct=None if rel is None else np.asarray(rel),
        history=None if hist is None else np.asarray(hist),
        history_t=hist_t,
        d_tau=float(d_tau(A, y, theta)),
        d_tau_per_joint=np.asarray(d_tau(A, y, theta, per_joint=True)),
    )


def _separated_ticks(ticks_per_run) -> np.ndarray:
    """One tick axis for stacked runs: each run's ticks shifted to start 2 after the previous
    run's last, so that no pair of consecutive ticks spans two runs."""
    out, start = [], 0
    for ticks in ticks_per_run:
        ticks = np.asarray(ticks, dtype=np.int64)
        out.append(ticks - ticks[0] + start)
        start = int(out[-1][-1]) + 2
    return np.concatenate(out)


def _motors(description, ticks, q_rad, voltage_v, current_a) -> list[MotorEstimate]:
    out = []
    period = description.sample_period
    for j, joint in enumerate(description.joints):
        if joint.drive is None or joint.encoder is None:
            continue
        noise = 0.0
        if joint.current_sensor is not None:
            cs = joint.current_sensor
            step = 2.0 * cs.range / 2**cs.adc_bits
            noise = math.sqrt(cs.noise**2 + step**2 / 12.0)
        count = 2 * math.pi / (joint.encoder.counts_per_rev * joint.drive.gear_ratio)
        out.append(
            identify_motor(
                joint.name,
                np.asarray(ticks),
                np.asarray(q_rad)[:, j],
                np.asarray(voltage_v)[:, j],
                np.asarray(current_a)[:, j],
                joint.drive.gear_ratio,
                period,
                current_noise_a=noise,
                count_rad=count,
            )  # fmt: skip
        )
    return out
