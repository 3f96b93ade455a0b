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

from guardid.conditioning.bandwidth import HARMONIC_FACTOR
from guardid.conditioning.options import ConditioningOptions
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
from guardid.identify.rows import (  # noqa: F401  (re-exported)
    STICTION_GUARD_PERIODS,
    Rows,
    free_columns,
    identification_rows,
    rows_summary,
    stacked_rows,
)
from guardid.identify.trust import (
    BoundedLeastSquares,
    impossible_values,
    lower_bounds,
    mark_not_converged,
    stacked_error,
)
from guardid.identify.untrusted import trust_problems

METHODS = ("ls", "wls", "bls", "rls", "hopfield", "gradient", "mlp", "iv", "didim")
POOR_REL_STD_PCT = 10.0  #: warn when a parameter's relative standard deviation exceeds this
REFERENCE_METHODS = ("wls", "ls")
"""The method whose estimate and std a report's verdict uses: the first of these that ran.
WLS, because its std matches the spread of its estimates over seeds on the guard robot's
closed loop (``bench/bench_std_check.py``, 100 seeds: spread / std 0.84-1.11 on the
default and the tracking excitation, truth within 3 std in >= 99.7 % of pairs), where LS's
pooled noise level makes the pan parameters' std up to 1.35x too large and the tilt's up to
1.35x too small (its two joints' residuals differ by a factor of several). IV and DIDIM
are not in the list: they need a guardid log with setpoints and the robot's controller;
IV meets the same bars there (its biases up to 0.2 std smaller on the tracking
excitation), DIDIM's std is up to 1.4x too small on it."""


def reference_method(results) -> str | None:
    """Name of the method the verdict uses (:data:`REFERENCE_METHODS`, then any with std)."""
    for m in REFERENCE_METHODS:
        if m in results and results[m].std is not None:
            return m
    return next((m for m, r in results.items() if r.std is not None), None)


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
    converged: bool = True  # False: in-sample fit much worse than LS's (not an equal)
    d_stacked: float = math.nan  # in-sample rms(y - A theta) / rms(y), joints stacked [-]


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
    conditioning: ConditioningOptions = field(default_factory=ConditioningOptions)
    cutoff_reason: str = ""
    rows_summary: str = ""
    untrusted: list[str] = field(default_factory=list)  # guardid.identify.untrusted; [] = trusted


HARMONIC_CUTOFF_FACTOR = HARMONIC_FACTOR  # kept for callers; see conditioning.bandwidth


def identified_names(description) -> tuple[str, ...]:
    """Names of the base parameters that identification estimates (all but the friction
    offsets a description declares absent with ``offset: null``)."""
    model = build_model(description)
    return tuple(model.base.names[i] for i in free_columns(model, description))


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


def identify(
    t_s,
    q_rad,
    current_a,
    description,
    methods=("ls", "wls", "rls", "hopfield"),
    conditioning: ConditioningOptions | None = None,
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
    qd=None,
    setpoints=None,
) -> Identification:
    """Identify the base parameters of ``description`` from one run (or several).

    t_s (N,) [s]; q_rad (N, n); current_a (N, n) motor current [A] (period means, guard
    firmware) or joint torque with drive-less joints; voltage_v and ticks (optional) add the
    motors' R and Ke. ``methods`` is any subset of :data:`METHODS`. ``effort_is_torque``:
    current_a is measured joint torque [N m] (see :func:`identification_rows`).
    ``highest_harmonic_hz`` [Hz] (the excitation's, e.g. from the log header,
    :func:`trajectory_highest_harmonic`) informs the automatic cut-off; ``conditioning``
    (:class:`ConditioningOptions`, default all automatic) says how the logs are conditioned
    (:func:`stacked_rows`); the options used, cut-off resolved, are in the result.
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
    never spans two runs). ``qd`` (N, n) [rad/s | m/s] (a list for several runs): measured
    joint velocities, used instead of the differentiated positions. ``bls`` is least squares
    with friction and rotor inertia kept >= 0 (:mod:`guardid.identify.trust`).
    ``iv`` and ``didim`` (:mod:`guardid.closedloop`) simulate the closed loop: they need
    ``setpoints`` (N, n) [rad] (a list for several runs), ``ticks`` and ``voltage_v``.
    """
    unknown = [m for m in methods if m not in METHODS]
    if unknown:
        raise GuardidError(f"--method: unknown {', '.join(unknown)} (known: {', '.join(METHODS)})")
    if "iv" in methods or "didim" in methods:
        from guardid.closedloop import check_inputs

        check_inputs(methods, description, setpoints, ticks)
    model = build_model(description)
    several = isinstance(t_s, (list, tuple))
    runs = list(zip(t_s, q_rad, current_a, strict=True)) if several else [(t_s, q_rad, current_a)]
    loop_inputs = (
        runs,
        *[
            list(x) if several and x is not None else [x] * len(runs)
            for x in (ticks, setpoints, voltage_v)
        ],
    )  # per run (closedloop)
    if qd is not None:
        runs = [(*r, v) for r, v in zip(runs, qd if several else [qd], strict=True)]
    rows = stacked_rows(
        runs, description, conditioning, in_current_units=in_current_units,
        effort_is_torque=effort_is_torque, highest_harmonic_hz=highest_harmonic_hz,
    )  # fmt: skip
    cond, A, y = rows
    if several:  # motors (R, Ke) from all runs, stacked
        q_rad = np.concatenate([np.asarray(r[1], dtype=float) for r in runs])
        current_a = np.concatenate([np.asarray(r[2], dtype=float) for r in runs])
        voltage_v = (
            np.concatenate([np.asarray(v, dtype=float) for v in voltage_v]) if voltage_v else None
        )
        ticks = _separated_ticks(ticks) if ticks else None
    free = free_columns(model, description)
    names = tuple(model.base.names[i] for i in free)
    nominal = model.base.values(model.params)[free]
    dt = float(np.median(np.diff(cond.t[cond.mask])))
    results: dict[str, MethodResult] = {}
    closed_loop_notes: list[str] = []
    ls = LeastSquares().fit(A, y)
    loop_rows = None  # iv / didim: the acceleration form's rows
    for method in methods:
        if method == "ls":
            est = ls
        elif method == "wls":
            est = WeightedLeastSquares().fit(A, y)
        elif method == "bls":
            est = BoundedLeastSquares(lower_bounds(names)).fit(A, y)
        elif method == "rls":
            est = RLS(lam=lam, p0=_rls_p0(A)).fit(A, y)
        elif method == "hopfield":
            start = nominal if hopfield_nominal is None else np.asarray(hopfield_nominal, float)
            est = run_hopfield(A, y, start, beta, dt, hopfield_passes)
            online_end = np.array(est.theta_)
            if hopfield_settle:
                eq = copy.deepcopy(est).settle(A, y)
        elif method in ("iv", "didim"):  # closed-loop consistent (guardid.closedloop)
            from guardid.closedloop import fit_closed_loop

            if loop_rows is None:
                loop_rows = closed_loop_rows(rows, runs, description, conditioning,
                                             in_current_units, effort_is_torque,
                                             highest_harmonic_hz, closed_loop_notes)  # fmt: skip
            est, note = fit_closed_loop(method, loop_rows.A, loop_rows.y, loop_rows, loop_inputs,
                                        description, model, free,
                                        (in_current_units, effort_is_torque))  # fmt: skip
            closed_loop_notes += note
            lc = loop_rows.cond
            results[method] = _result(method, est, loop_rows.A, loop_rows.y, lc.t[lc.mask])
            results[method].converged = bool(est.converged)  # report's "(not converged)"
            continue
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
    ref = reference_method(results)
    rel_std = results[ref].rel_std_pct if ref is not None else ls.rel_std_
    warnings = [
        f"{name}: relative standard deviation {r:.0f} % (poorly identifiable; "
        "a richer excitation or a longer run would help)"
        for name, r in zip(names, rel_std, strict=True)
        if r > POOR_REL_STD_PCT
    ]
    warnings += rows.warnings + _moving_with_cutoff(rows.choice, names, ls) + closed_loop_notes
    warnings += _not_converged(results, ls, rows, loop_rows)
    warnings += impossible_values(model, free, names, ls, cond, in_current_units)
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
        conditioning=rows.options,
        cutoff_reason=cond.notes[0] if cond.notes else "",
        rows_summary=rows_summary(cond),
        untrusted=trust_problems(ls, names, results, motors),
    )


MOVING_PCT = 10.0
"""Warn when a well-identified parameter moves more than this [%] between the chosen cut-off
and a neighbouring candidate."""


def _not_converged(results, ls, rows, loop_rows) -> list[str]:
    """:func:`mark_not_converged`, IV and DIDIM against LS on their own rows when those are
    not the other methods' (another equation form: other rows, another in-sample error)."""
    loop = [m for m in results if m in ("iv", "didim")]
    if loop_rows is None or loop_rows is rows or not loop or "ls" not in results:
        return mark_not_converged(results, ls)
    lc = loop_rows.cond
    ref = _result("ls", LeastSquares().fit(loop_rows.A, loop_rows.y), loop_rows.A, loop_rows.y,
                  lc.t[lc.mask])  # fmt: skip
    out = mark_not_converged({m: r for m, r in results.items() if m not in loop}, ls)
    return out + mark_not_converged({"ls": ref, **{m: results[m] for m in loop}}, ls)


def closed_loop_rows(rows, runs, description, options, in_current_units, effort_is_torque,
                     highest_harmonic_hz, notes):  # fmt: skip
    """The rows IV and DIDIM fit: they condition their simulated closed loop like the
    measured run, row for row, in the acceleration form (the momentum form's per-joint cuts
    follow the measured run's stops: ``rows.momentum_rows_of`` would line a simulated run up
    with them, not wired yet). ``rows`` when already in that form; else the runs conditioned
    again in it (a note in ``notes``)."""
    if rows.options.equation == "acceleration":
        return rows
    notes.append(
        "iv/didim: acceleration form (their simulated closed loop is conditioned like the "
        "measured run in that form); the other methods: momentum form"
    )
    options = replace(options or ConditioningOptions(), equation="acceleration", order=None)
    return stacked_rows(runs, description, options, in_current_units=in_current_units,
                        effort_is_torque=effort_is_torque,
                        highest_harmonic_hz=highest_harmonic_hz)  # fmt: skip


def _moving_with_cutoff(choice, names, ls) -> list[str]:
    """Warnings for estimates that move a lot with the cut-off (neighbouring candidates)."""
    if choice is None or len(choice.candidates) < 2:
        return []
    i = choice.candidates.index(choice.cutoff_hz)
    base = choice.thetas[i]
    if base is None:
        return []
    out = []
    for j in (i - 1, i + 1):
        other = choice.thetas[j] if 0 <= j < len(choice.thetas) else None
        if other is None:
            continue
        change = 100 * np.abs(other - base) / np.maximum(np.abs(base), 1e-300)
        well = ls.rel_std_ < POOR_REL_STD_PCT
        moved = [f"{n} {c:.0f} %" for n, c, w in zip(names, change, well, strict=True)
                 if w and c > MOVING_PCT]  # fmt: skip
        if moved:
            out.append(
                f"estimates move a lot with the cut-off: at {choice.candidates[j]:g} Hz instead "
                f"of {choice.cutoff_hz:g} Hz " + ", ".join(moved) + " change"
            )
    return out


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
        d_stacked=stacked_error(A, y, theta),
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
