"""The identification pipeline, stage by stage (docs/CONTRACTS.md):

runs (:class:`~guardid.identify.runs.Run`) -> prepared runs and segments
(:mod:`guardid.identify.prepare`) -> conditioned signals and equation rows
(:func:`~guardid.identify.rows.stacked_rows`) -> the estimators named in the options
(:mod:`guardid.identify.methods`, registered by name) -> result (:class:`Identification`:
estimates with their uncertainty, checks, the motors' electrical parameters).

Time comes from the tick column; lost ticks are gaps: a run is split at a long one
(:mod:`guardid.identify.segments`, said in the warnings), shorter ones are bridged (the
acceleration form) or cut (the momentum form) by the conditioning stage. Everything
:func:`identify` is told besides the data is one :class:`IdentifyOptions`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace

import numpy as np

from guardid.conditioning.bandwidth import HARMONIC_FACTOR
from guardid.conditioning.momentum import ticks_needed
from guardid.conditioning.options import ConditioningOptions
from guardid.dynamics import build_model
from guardid.errors import GuardidError
from guardid.estimators import LeastSquares, d_tau
from guardid.identify.current_zero import MODES as ZERO_MODES
from guardid.identify.current_zero import ZeroOutcome, zero_stage
from guardid.identify.electrical import MotorEstimate, identify_motor_runs, motor_doubts
from guardid.identify.equation import free_columns
from guardid.identify.methods import FitRows, MethodFit, methods_for
from guardid.identify.prepare import effort_is_torque, prepared_runs, run_signals
from guardid.identify.rows import rows_summary, stacked_rows
from guardid.identify.trust import (
    MAX_MASS_SAMPLES,
    impossible_values,
    mark_not_converged,
    stacked_error,
)
from guardid.identify.untrusted import indefinite_mass_matrix, reference_method, trust_problems

POOR_REL_STD_PCT = 10.0  #: warn when a parameter's relative standard deviation exceeds this


@dataclass(frozen=True)
class HopfieldSettings:
    """The Hopfield network's: gain ``beta`` [unit of y^2 times s]; ``passes`` over the rows,
    each starting where the previous ended; ``nominal`` (b',) [SI] the start and centre of
    its box (+-100 %; None: the description's base values); ``settle``: also report the
    network's equilibrium on the whole log as ``hopfield-eq`` (the least-squares estimate
    inside the box, never the network's own)."""

    beta: float = 0.01
    passes: int = 1
    nominal: tuple[float, ...] | None = None
    settle: bool = False

    def __post_init__(self):
        if self.nominal is not None:  # a tuple: options stay immutable
            object.__setattr__(self, "nominal", tuple(float(x) for x in self.nominal))


@dataclass(frozen=True)
class IdentifyOptions:
    """How :func:`identify` runs, everything but the data.

    ``methods``: names of registered estimators (:func:`guardid.identify.methods.method_names`;
    a string is read as a comma-separated list), fitted and reported in this order;
    ``conditioning``: :class:`ConditioningOptions` (None: all automatic); ``hopfield``:
    :class:`HopfieldSettings`; ``rls_lambda``: RLS forgetting factor in (0, 1];
    ``gradient_eta``: the gradient estimator's gain; ``in_current_units``: no
    current-to-torque gain (estimates in the effort's unit); ``current_zero``: what to do
    with the current sensors' zero a log's footer gives (``subtract``: take it off the
    currents, every std counting its error; ``ignore``; :mod:`guardid.identify.current_zero`).
    Whether the effort is measured torque comes with the data
    (:attr:`~guardid.identify.runs.Run.torque`).
    """

    methods: tuple[str, ...] = ("ls", "wls", "rls", "hopfield")
    conditioning: ConditioningOptions | None = None
    hopfield: HopfieldSettings = field(default_factory=HopfieldSettings)
    rls_lambda: float = 1.0
    gradient_eta: float = 1e-3
    in_current_units: bool = False
    current_zero: str = "subtract"

    def __post_init__(self):
        if self.current_zero not in ZERO_MODES:
            raise ValueError(f"current_zero: {self.current_zero!r} is not one of "
                             f"{', '.join(ZERO_MODES)}")  # fmt: skip
        m = self.methods
        m = [x.strip() for x in m.split(",") if x.strip()] if isinstance(m, str) else m
        object.__setattr__(self, "methods", tuple(m))


@dataclass
class MethodResult:
    """One estimator's outcome: estimate (b,), std (b,) or None, history (K, b) or None;
    ``cov`` (b, b) its covariance when the estimator gives one; ``notes``: its warnings."""

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
    cov: np.ndarray | None = None
    notes: list[str] = field(default_factory=list)
    output_spread: np.ndarray | None = None  # MLP: its output's spread over the rows, not a std
    fitted_on: object = None  # the Rows it was fitted on when not the other methods' (iv/didim)


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
    current_zero: ZeroOutcome | None = None  # the current sensors' zero stage (None: not made)


HARMONIC_CUTOFF_FACTOR = HARMONIC_FACTOR  # kept for callers; see conditioning.bandwidth


def identified_names(description) -> tuple[str, ...]:
    """Names of the base parameters that identification estimates (all but the friction
    offsets a description declares absent with ``offset: null``)."""
    model = build_model(description)
    return tuple(model.base.names[i] for i in free_columns(model, description))


def identify(runs, description, options: IdentifyOptions | None = None) -> Identification:
    """Identify the base parameters of ``description`` from ``runs`` (a list of
    :class:`~guardid.identify.runs.Run`).

    A run is split at its long gaps (:mod:`guardid.identify.segments`, named in the
    warnings) unless the caller split it. Each run is conditioned on its own and the
    equation rows are stacked (one fit, :func:`stacked_rows`; the equation form and the
    cut-off, when not given in ``options.conditioning``: the momentum form at 2 x the first
    run's ``highest_harmonic_hz`` for motor-current logs on a tick grid, else the
    acceleration form, its cut-off chosen by cross-validation); measured velocities
    (``Run.qd``) replace the differentiated positions when every run has them.
    Then every method of ``options.methods`` (:mod:`guardid.identify.methods`) is fitted on
    the rows, and the motors' R and Ke are estimated from every run's voltage and ticks
    together (a motor-equation row never spans two runs) when all runs have both and the
    effort is motor current in amperes. The options used, cut-off resolved, are in the result.
    """
    options = options or IdentifyOptions()
    runs, split, zeros = prepared_runs(runs, description, options)
    torque = effort_is_torque(runs)
    methods = methods_for(options.methods)  # unknown names refused before any work
    for check in dict.fromkeys(m.check for m in methods if m.check is not None):
        check(options.methods, runs, description)
    conditioning = options.conditioning
    forms = {m.equation for m in methods}
    if (
        len(forms) == 1
        and None not in forms
        and (conditioning or ConditioningOptions()).equation is None
    ):
        # every method fits one form (iv, didim: acceleration): the rows are made in it
        conditioning = replace(conditioning or ConditioningOptions(), equation=forms.pop())
    # segments -> conditioned signals -> equation rows, every run on its own, rows stacked
    rows = stacked_rows(
        [run_signals(r, runs) for r in runs], description, conditioning,
        in_current_units=options.in_current_units, effort_is_torque=torque,
        highest_harmonic_hz=runs[0].highest_harmonic_hz,
        periods_s=[r.excitation_period_s for r in runs],
    )  # fmt: skip
    return_freed_memory()  # the conditioning's per-tick temporaries, before the fit
    fit_rows = _fit_rows(rows, runs, description, options, torque)
    results = _fit_all(methods, fit_rows)  # the estimators, in the order asked
    zero = zero_stage(fit_rows, results, zeros.taken, description, options.current_zero,
                      zeros.lines)  # fmt: skip
    result = _result_of(fit_rows, results, options, torque)  # checks, warnings, motors
    result.current_zero = zero
    result.notes += zero.lines
    result.warnings[:0] = zeros.warnings
    if split is not None:
        result.warnings[:0] = split.lines(result.cutoff_hz)
    return result


def return_freed_memory() -> None:
    """Give the free pages inside the heap back to the system (glibc's ``malloc_trim``; a
    no-op elsewhere): arrays below glibc's mmap threshold are freed into the heap, whose
    pages stay resident unless trimmed (4 h log: about 12 MiB less through the fit)."""
    try:
        import ctypes

        trim = ctypes.CDLL(None).malloc_trim
    except (OSError, AttributeError, TypeError):
        return
    trim(0)


def _fit_rows(rows, runs, description, options, torque) -> FitRows:
    model = build_model(description)
    cond, A, y = rows
    free = free_columns(model, description)
    spacing = max(int(cond.decimation), 1)
    need = ticks_needed(len(free), rows.lag_ticks)
    if rows.row_ticks is not None and spacing * len(A) < need:
        raise GuardidError(
            f"rows every {spacing} ticks: {spacing * len(A)} usable ticks are too few for "
            f"their std (the fit's {len(free)} parameters over a window of "
            f"{rows.lag_ticks + 1} ticks need {need}): "
            "capture longer or leave the rows' spacing to identify"
        )
    return FitRows(
        A=A, y=y, rows=rows, names=tuple(model.base.names[i] for i in free),
        nominal=model.base.values(model.params)[free],
        dt=float(np.median(np.diff(cond.t[cond.mask]))),
        ls=LeastSquares(**rows.error_model()).fit(A, y),
        runs=runs, description=description, model=model, free=free, options=options,
        effort_is_torque=torque,
    )  # fmt: skip


def _fit_all(methods, rows: FitRows) -> dict[str, MethodResult]:
    """Every method's :class:`MethodResult` (and its extra results right after it), its
    in-sample figures on the rows it was fitted on (:attr:`MethodFit.rows`)."""
    results: dict[str, MethodResult] = {}
    for method in methods:
        fit = method.fit(rows)
        own = fit.rows if fit.rows is not None else rows.rows
        t_rows = own.cond.t[own.cond.mask]
        results[method.name] = _result(method.name, fit, own.A, own.y, t_rows)
        results[method.name].fitted_on = fit.rows
        for name, extra in fit.extra.items():
            results[name] = _result(name, extra, own.A, own.y, t_rows)
    return results


def _not_converged(results, ls) -> list[str]:
    """:func:`mark_not_converged`; a method fitted on rows of its own (IV and DIDIM in the
    acceleration form beside momentum-form rows) is judged against LS on those rows."""
    own = {m: r for m, r in results.items() if r.fitted_on is None}
    out = mark_not_converged(own, ls)
    for m, r in results.items():
        if r.fitted_on is not None:
            A, y = r.fitted_on.A, r.fitted_on.y
            ref = LeastSquares().fit(A, y)
            t = r.fitted_on.cond.t[r.fitted_on.cond.mask]
            out += mark_not_converged({"ls": _result("ls", MethodFit.of(ref), A, y, t), m: r}, ref)
    return out


REPEATING_SHARE = 0.5
"""A parameter whose variance is at least this share an error that repeats every excitation
period is told that a longer run of the same excitation helps little [-]."""


def poorly_identifiable(names, rel_std_pct, repeating_share=None) -> list[str]:
    """One warning per parameter whose relative std exceeds :data:`POOR_REL_STD_PCT` [%],
    with what would help: a richer excitation or a longer run; only another excitation when
    at least :data:`REPEATING_SHARE` of its variance repeats every period (``repeating_share``
    (b,), :class:`~guardid.estimators.LeastSquares`' ``repeating_share_``), which more
    periods of the same excitation do not average out (twice the run: that part stays)."""
    share = np.zeros(len(names)) if repeating_share is None else np.asarray(repeating_share)
    out = []
    for name, r, s in zip(names, rel_std_pct, share, strict=True):
        if not r > POOR_REL_STD_PCT:
            continue
        if s >= REPEATING_SHARE:
            why = (f"{100 * s:.0f} % of its variance is an error that repeats every "
                   "excitation period, which a longer run of the same excitation does not "
                   "average out; another excitation would help")  # fmt: skip
        else:
            why = "a richer excitation or a longer run would help"
        out.append(f"{name}: relative standard deviation {r:.0f} % (poorly identifiable; {why})")
    return out


def _result_of(rows: FitRows, results, options, torque) -> Identification:
    """The result stage: warnings, trust checks and the motors beside the estimates."""
    cond, ls, names, runs = rows.rows.cond, rows.ls, rows.names, rows.runs
    ref = reference_method(results)
    rel_std = results[ref].rel_std_pct if ref is not None else ls.rel_std_
    repeating = results[ref].settings.get("repeating_residual", {}) if ref is not None else {}
    warnings = poorly_identifiable(names, rel_std, repeating.get("variance_share"))
    notes = [n for r in results.values() for n in r.notes]
    warnings += rows.rows.warnings + _moving_with_cutoff(rows.rows.choice, names, ls) + notes
    warnings += _not_converged(results, ls)
    warnings += impossible_values(rows.model, rows.free, names, ls, cond, options.in_current_units)
    motors = []
    electrical = all(r.voltage is not None and r.ticks is not None for r in runs)
    if electrical and not (options.in_current_units or torque):
        motors = _motors(rows.description, runs)
    return Identification(
        names=names,
        formulas=tuple(rows.model.base.formulas[i] for i in rows.free),
        nominal=rows.nominal,
        results=results,
        cond=float(ls.cond_),
        rows=int(rows.A.shape[0]),
        cutoff_hz=float(cond.cutoff_hz),
        torque_unit=cond.torque_unit,
        notes=list(cond.notes),
        motors=motors,
        warnings=warnings,
        conditioning=rows.rows.options,
        cutoff_reason=cond.notes[0] if cond.notes else "",
        rows_summary=rows_summary(cond),
        untrusted=trust_problems(ls, names, results, motors)
        + _mass_problems(rows, results, ls, options)
        + motor_doubts(rows.description, motors),
    )


def _mass_problems(rows: FitRows, results, ls, options) -> list[str]:
    """:func:`indefinite_mass_matrix` of the verdict's method (its estimate and covariance;
    LS's when it has none) at up to ``MAX_MASS_SAMPLES`` of the run's rows (none in current
    units, whose scale is unknown)."""
    cond = rows.rows.cond
    if options.in_current_units or not len(cond.q):
        return []
    ref = reference_method(results)
    r = results.get(ref) if ref is not None else None
    theta, cov = (r.theta, r.cov) if r is not None and r.cov is not None else (ls.theta_, ls.cov_)
    q = np.asarray(cond.q)[:: max(1, len(cond.q) // MAX_MASS_SAMPLES)]
    return indefinite_mass_matrix(rows.model, rows.free, theta, cov, q)


MOVING_PCT = 10.0
"""Warn when a well-identified parameter moves more than this [%] between the chosen cut-off
and a neighbouring candidate."""


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


def _result(method, fit: MethodFit, A, y, t_rows) -> MethodResult:
    """A :class:`MethodResult`: the fit, its error on the rows, its history's times [s]."""
    theta = np.asarray(fit.theta, dtype=float)
    hist, hist_t = fit.history, None
    if hist is not None and len(hist):
        samples = fit.history_samples
        idx = np.asarray(np.arange(len(hist)) if samples is None else samples, dtype=int)
        n = len(t_rows)
        span = float(t_rows[-1] - t_rows[0]) + (float(t_rows[1] - t_rows[0]) if n > 1 else 0.0)
        hist_t = t_rows[np.clip(idx - 1, 0, None) % n] + np.clip(idx - 1, 0, None) // n * span
    return MethodResult(
        method=method,
        theta=theta,
        std=None if fit.std is None else np.asarray(fit.std),
        rel_std_pct=None if fit.rel_std_pct is None else np.asarray(fit.rel_std_pct),
        history=None if hist is None else np.asarray(hist),
        history_t=hist_t,
        d_tau=float(d_tau(A, y, theta)),
        d_tau_per_joint=np.asarray(d_tau(A, y, theta, per_joint=True)),
        settings=dict(fit.settings),
        converged=bool(fit.converged),
        d_stacked=stacked_error(A, y, theta),
        cov=fit.cov,
        notes=list(fit.notes),
        output_spread=None if fit.output_spread is None else np.asarray(fit.output_spread),
    )


def _motors(description, runs) -> list[MotorEstimate]:
    """Each driven, encoded joint's R and Ke from every run's ticks, q, voltage and current
    (no pair of ticks spans two runs; the rows are formed by chunks, not stacked)."""
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
        count = 2 * math.pi / joint.counts_per_joint_rev
        out.append(
            identify_motor_runs(
                joint.name,
                [
                    (
                        r.ticks,
                        np.asarray(r.q)[:, j],
                        np.asarray(r.voltage)[:, j],
                        np.asarray(r.current)[:, j],
                    )
                    for r in runs
                ],  # fmt: skip
                joint.drive.gear_ratio,
                period,
                current_noise_a=noise,
                count_rad=count,
            )  # fmt: skip
        )
    return out
