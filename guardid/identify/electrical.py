"""Motor electrical identification: V = R i + Ke N qd (+ L di/dt), linear in R, Ke, L.

The telemetry reports, per tick k, the voltage and current means over the period ending at
k and the encoder counts at k. Averaging the motor equation over that period is exact:

    mean V = R mean i + Ke N (q_k - q_{k-1}) / T + L (i(kT) - i((k-1)T)) / T

so the back-EMF regressor needs no differentiation filter at all. The end-point currents
are unknown; their difference is approximated by the difference of successive period
means (the L column), which is why L is only an option (L/R of a small gear motor is far
below one period and L is then poorly identifiable).

**The std** is the larger of the homoscedastic one, sigma^2 (A^T A)^-1 (A^T A bias-
compensated, below), and the sandwich (White) one, (A^T A)^-1 (sum_k r_k^2 a_k a_k^T)
(A^T A)^-1. A few rows far off the equation pull R and Ke by many homoscedastic std, and
the sandwich widens the std to their pull: rows cut out of a variant log with the ticks
renumbered, the step at the cut 0.82 of the jump threshold (so not split,
:mod:`guardid.identify.jumps`), put the pan's Ke 11 std off (0.02479 +- 1.9e-5 against
0.025); with the sandwich 1.05 std (+- 2.0e-4). On 690 intact logs of five robots Ke's std
is 1.035 times the homoscedastic one at the median, 1.48 at most; R's 1.015 and 1.72
(2026-11-29).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from guardid.errors import GuardidError


@dataclass(frozen=True)
class MotorEstimate:
    """One motor: R [ohm], Ke [V s/rad, motor side], L [H] or None, their std, and rows used."""

    joint: str
    resistance: float
    ke: float
    inductance: float | None
    resistance_std: float
    ke_std: float
    rows: int
    residual_rms_v: float

    def drive_gain(self, gear_ratio: float, efficiency: float) -> float:
        """Joint torque per amp, N eta Kt [N m/A], assuming Kt = Ke (SI motor constants)."""
        return gear_ratio * efficiency * self.ke


MOTOR_CHUNK = 65536
"""Motor-equation rows formed at a time (peak memory of long logs) [rows]."""


def identify_motor(
    joint: str,
    ticks: np.ndarray,
    q_rad: np.ndarray,
    voltage_v: np.ndarray,
    current_a: np.ndarray,
    gear_ratio: float,
    period_s: float,
    **options,
) -> MotorEstimate:
    """Least squares on the period-averaged motor equation of one joint.

    ticks: tick numbers (gaps allowed: only consecutive pairs are used); q_rad: joint angle
    at each tick [rad]; voltage_v, current_a: period means [V, A]; gear_ratio N;
    period_s: sample period T [s]. ``options``: with_inductance (bool), min_current_a,
    current_noise_a, count_rad (:func:`identify_motor_runs`). Rows with |i| <
    min_current_a are dropped.
    :func:`identify_motor_runs` for several runs (no pair of ticks spans two).

    The regressors are measured too: the current with the ADC's noise and the angle
    difference with the encoder's quantisation. Both bias plain least squares towards zero
    (errors in variables: a few % on R for a lightly loaded joint). Given the current
    noise std ``current_noise_a`` [A] (sensor noise and quantisation) and one encoder step
    ``count_rad`` [rad], their known variances are subtracted from the normal equations
    (bias-compensated least squares).
    """
    return identify_motor_runs(
        joint, [(ticks, q_rad, voltage_v, current_a)], gear_ratio, period_s, **options
    )


def _motor_rows(runs, gear_ratio, period_s, with_inductance, min_current_a):
    """The motor equation's rows (A (K, 2 | 3), y (K,)) of every run (ticks, q_rad,
    voltage_v, current_a), :data:`MOTOR_CHUNK` ticks at a time: tick k with tick k - 1
    (and k - 2 with the inductance) the one before it."""
    for ticks, q_rad, voltage_v, current_a in runs:
        ticks = np.asarray(ticks)
        i = np.asarray(current_a, dtype=float)
        v = np.asarray(voltage_v, dtype=float)
        for a in range(1, len(ticks), MOTOR_CHUNK):
            k = np.arange(a, min(a + MOTOR_CHUNK, len(ticks)))
            ok = ticks[k] - ticks[k - 1] == 1
            if with_inductance:
                ok &= (k >= 2) & (ticks[k - 1] - ticks[np.maximum(k - 2, 0)] == 1)
            k = k[ok]
            k = k[np.abs(i[k]) >= min_current_a]
            cols = [i[k], gear_ratio * (q_rad[k] - q_rad[k - 1]) / period_s]
            if with_inductance:
                cols.append((i[k] - i[k - 1]) / period_s)
            yield np.column_stack(cols), v[k]


def identify_motor_runs(
    joint: str,
    runs,
    gear_ratio: float,
    period_s: float,
    with_inductance: bool = False,
    min_current_a: float = 0.0,
    current_noise_a: float = 0.0,
    count_rad: float = 0.0,
) -> MotorEstimate:
    """:func:`identify_motor` on the rows of every run (ticks, q_rad, voltage_v, current_a)
    together, the normal equations summed over chunks of :data:`MOTOR_CHUNK` ticks (memory
    of one chunk)."""
    p = 3 if with_inductance else 2
    normal, aty, rows = np.zeros((p, p)), np.zeros(p), 0
    for A, y in _motor_rows(runs, gear_ratio, period_s, with_inductance, min_current_a):
        normal += A.T @ A
        aty += A.T @ y
        rows += len(y)
    if rows <= p:
        raise GuardidError(f"joint {joint}: too few consecutive rows ({rows}) for the motor fit")
    noise = np.zeros(p)
    noise[0] = current_noise_a**2
    # the difference of two independently quantised angles: variance 2 * step^2 / 12
    noise[1] = (gear_ratio / period_s) ** 2 * count_rad**2 / 6.0
    if with_inductance:
        noise[2] = 2.0 * current_noise_a**2 / period_s**2
    normal -= rows * np.diag(noise)
    try:
        theta = np.linalg.solve(normal, aty)
        cov_unit = np.linalg.inv(normal)
    except np.linalg.LinAlgError:  # a motor that never turns: R and Ke not determined
        theta, cov_unit = np.full(p, np.nan), np.full((p, p), np.nan)
    rss, meat = 0.0, np.zeros((p, p))
    for A, y in _motor_rows(runs, gear_ratio, period_s, with_inductance, min_current_a):
        r = y - A @ theta
        rss += float(r @ r)
        weighted = A * r[:, None]
        meat += weighted.T @ weighted
    sigma2 = rss / (rows - p)
    # the larger of the homoscedastic and the sandwich (White) variance: a few rows far off
    # the equation (a splice's one-row step, a glitch) widen it to the shift they cause
    var = np.maximum(np.diag(sigma2 * cov_unit), np.diag(cov_unit @ meat @ cov_unit))
    std = np.sqrt(np.where(var >= 0.0, var, np.nan))  # negative: not determined (nan)
    return MotorEstimate(
        joint=joint,
        resistance=float(theta[0]),
        ke=float(theta[1]),
        inductance=float(theta[2]) if with_inductance else None,
        resistance_std=float(std[0]),
        ke_std=float(std[1]),
        rows=rows,
        residual_rms_v=float(np.sqrt(rss / rows)),
    )


KE_TOLERANCE = 0.25
"""Relative difference [-] between an identified Ke and the description's beyond which
:func:`motor_doubts` warns: a datasheet's motor constant holds to about +-10 %, and the
rigid-body parameters rest on the description's Kt (joint torque = N eta Kt i), so an
identified Ke a quarter off means the effort's scale, or the columns, are not the robot's."""
R_FACTOR = 2.0
"""Factor [-] between an identified R and the description's beyond which
:func:`motor_doubts` warns: copper's resistance rises 0.39 %/K, so even a motor 100 K warmer
than the datasheet's 20 degC stays within 1.4x; a factor of 2 is no temperature change."""
DOUBT_STD = 5.0
"""...and only when the difference is also beyond this many of the estimate's std [-]."""


def motor_doubts(description, motors) -> list[str]:
    """Problems (identify refuses the result, exit 4; ``--force`` writes it with them as
    warnings) for identified motors whose Ke or R disagree with the robot description's
    (:data:`KE_TOLERANCE`, :data:`R_FACTOR`, :data:`DOUBT_STD`): the voltage, current or
    angle columns of that joint may not belong together (swapped, another robot's log), or
    the description's motor or current sensor is not the one fitted. Either way the
    rigid-body estimates are not to be trusted, as they rest on the description's Kt and
    on the current's scale, and the momentum form's stencil corrections on its R (the
    back-EMF's damping N Ke / R and the current's lag L / R). A current read k times as large
    as it flows gives R / k with Ke unchanged and scales every inertial and friction estimate
    by k, hundreds of their std off; it is caught only beyond k = :data:`R_FACTOR` (the guard,
    60 s, both currents times 2.5: R 3.2 against 8 ohm, MX2R 1.93 +- 0.002 against 0.77;
    times 1.98 passes with every estimate 1.98 times too large: the current's scale cannot
    be told from a warm motor's R below that). Until 2026-11-29 this was a warning with exit
    0."""
    drives = {j.name: j.drive for j in description.joints if j.drive is not None}
    out = []
    for m in motors:
        d = drives.get(m.joint)
        if d is None or not (np.isfinite(m.ke) and np.isfinite(m.resistance)):
            continue
        ke_off = abs(m.ke - d.ke) > max(KE_TOLERANCE * d.ke, DOUBT_STD * m.ke_std)
        ratio = m.resistance / d.resistance if d.resistance > 0 else np.inf
        r_off = (ratio > R_FACTOR or ratio < 1.0 / R_FACTOR) and abs(
            m.resistance - d.resistance
        ) > DOUBT_STD * m.resistance_std
        if ke_off or r_off:
            out.append(
                f"motor {m.joint}: identified R {m.resistance:.3g} ohm, Ke {m.ke:.3g} V s/rad "
                f"against the description's {d.resistance:.3g} ohm, {d.ke:.3g} V s/rad: this "
                "joint's voltage, current and angle columns may not belong together (swapped "
                "columns, another robot's log?) or its motor or current sensor is not the "
                "description's; the rigid-body parameters rest on the description's Kt and on "
                "the current's scale"
            )
    return out
