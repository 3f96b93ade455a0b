"""The identification pipeline: log -> conditioning -> base regressor -> estimators.

Inputs are a guardid log (or arrays in its shape) and the robot description; outputs are
the base parameters per method with their uncertainty, the torque fit, and the motors'
electrical parameters. Time comes from the tick column; lost ticks are gaps, which the
conditioning stage bridges by resampling.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from guardid.conditioning import condition
from guardid.dynamics import build_model
from guardid.errors import GuardidError
from guardid.estimators import (
    RLS,
    Gradient,
    Hopfield,
    LeastSquares,
    WeightedLeastSquares,
    d_tau,
)
from guardid.identify.electrical import MotorEstimate, identify_motor

METHODS = ("ls", "wls", "rls", "hopfield", "gradient")
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


def identification_rows(
    t_s,
    q_rad,
    current_a,
    description,
    cutoff_hz=None,
    in_current_units=False,
    effort_is_torque: bool = False,
    **kwargs,
):
    """Conditioned signals and the stacked base regressor of the usable rows.

    Returns (conditioned, A (M, n, b), y (M, n)) where y is the joint torque [N m] minus the
    model's known torque (or the current [A] when ``in_current_units``).
    ``effort_is_torque``: ``current_a`` is measured joint torque [N m] sampled at the time
    stamps (foreign logs): gain 1, no period-mean alignment.
    """
    model = build_model(description)
    gain = None if in_current_units else _drive_gain(description)
    if effort_is_torque:
        gain = 1.0
        kwargs.setdefault("align_period_mean", False)
    cond = condition(t_s, q_rad, current_a, cutoff_hz=cutoff_hz, gain=gain, **kwargs)
    m = cond.mask
    if m.sum() <= len(model.base.names):
        raise GuardidError(
            f"only {int(m.sum())} usable rows after conditioning (need more than "
            f"{len(model.base.names)}): the run is too short or the joints hardly move"
        )
    q, qd, qdd = cond.q[m], cond.qd[m], cond.qdd[m]
    A = model.base_regressor(q, qd, qdd)
    y = cond.tau[m] - model.known_torque(q, qd, qdd)
    return cond, A, y


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
) -> Identification:
    """Identify the base parameters of ``description`` from one run.

    t_s (N,) [s]; q_rad (N, n); current_a (N, n) motor current [A] (period means, guard
    firmware) or joint torque with drive-less joints; voltage_v and ticks (optional) add the
    motors' R and Ke. ``methods`` is any subset of :data:`METHODS`. ``effort_is_torque``:
    current_a is measured joint torque [N m] (see :func:`identification_rows`).
    """
    unknown = [m for m in methods if m not in METHODS]
    if unknown:
        raise GuardidError(f"--method: unknown {', '.join(unknown)} (known: {', '.join(METHODS)})")
    model = build_model(description)
    cond, A, y = identification_rows(
        t_s, q_rad, current_a, description, cutoff_hz, in_current_units, effort_is_torque
    )
    nominal = model.base.values(model.params)
    dt = float(np.median(np.diff(cond.t)))
    results: dict[str, MethodResult] = {}
    ls = LeastSquares().fit(A, y)
    for method in methods:
        if method == "ls":
            est = ls
        elif method == "wls":
            est = WeightedLeastSquares().fit(A, y)
        elif method == "rls":
            est = RLS(lam=lam, p0=1e6).fit(A, y)
        elif method == "hopfield":
            half = _hopfield_half_widths(nominal)
            est = Hopfield(theta_n=nominal, half_widths=half, beta=beta, dt=dt).fit(A, y)
        else:
            est = Gradient(eta=gradient_eta, dt=dt, theta0=nominal).fit(A, y)
        results[method] = _result(method, est, A, y, cond.t[cond.mask])
    warnings = [
        f"{name}: relative standard deviation {r:.0f} % (poorly identifiable; "
        "a richer excitation or a longer run would help)"
        for name, r in zip(model.base.names, ls.rel_std_, strict=True)
        if r > POOR_REL_STD_PCT
    ]
    motors = []
    if voltage_v is not None and ticks is not None and not (in_current_units or effort_is_torque):
        motors = _motors(description, ticks, q_rad, voltage_v, current_a)
    return Identification(
        names=tuple(model.base.names),
        formulas=tuple(model.base.formulas),
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
        hist_t = t_rows[np.clip(idx - 1, 0, len(t_rows) - 1)]
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
