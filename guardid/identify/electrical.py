"""Motor electrical identification: V = R i + Ke N qd (+ L di/dt), linear in R, Ke, L.

The telemetry reports, per tick k, the voltage and current means over the period ending at
k and the encoder counts at k. Averaging the motor equation over that period is exact:

    mean V = R mean i + Ke N (q_k - q_{k-1}) / T + L (i(kT) - i((k-1)T)) / T

so the back-EMF regressor needs no differentiation filter at all. The end-point currents
are unknown; their difference is approximated by the difference of successive period
means (the L column), which is why L is only an option (L/R of a small gear motor is far
below one period and L is then poorly identifiable).
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


def identify_motor(
    joint: str,
    ticks: np.ndarray,
    q_rad: np.ndarray,
    voltage_v: np.ndarray,
    current_a: np.ndarray,
    gear_ratio: float,
    period_s: float,
    with_inductance: bool = False,
    min_current_a: float = 0.0,
    current_noise_a: float = 0.0,
    count_rad: float = 0.0,
) -> MotorEstimate:
    """Least squares on the period-averaged motor equation of one joint.

    ticks: tick numbers (gaps allowed: only consecutive pairs are used); q_rad: joint angle
    at each tick [rad]; voltage_v, current_a: period means [V, A]; gear_ratio N;
    period_s: sample period T [s]. Rows with |i| < min_current_a are dropped.

    The regressors are measured too: the current with the ADC's noise and the angle
    difference with the encoder's quantisation. Both bias plain least squares towards zero
    (errors in variables: a few % on R for a lightly loaded joint). Given the current
    noise std ``current_noise_a`` [A] (sensor noise and quantisation) and one encoder step
    ``count_rad`` [rad], their known variances are subtracted from the normal equations
    (bias-compensated least squares).
    """
    ticks = np.asarray(ticks)
    consecutive = np.diff(ticks) == 1
    if with_inductance:
        consecutive[1:] &= consecutive[:-1]
        consecutive[0] = False
    k = np.nonzero(consecutive)[0] + 1
    i = np.asarray(current_a, dtype=float)
    keep = np.abs(i[k]) >= min_current_a
    k = k[keep]
    cols = [i[k], gear_ratio * (q_rad[k] - q_rad[k - 1]) / period_s]
    if with_inductance:
        cols.append((i[k] - i[k - 1]) / period_s)
    A = np.column_stack(cols)
    y = np.asarray(voltage_v, dtype=float)[k]
    if len(k) <= A.shape[1]:
        raise GuardidError(f"joint {joint}: too few consecutive rows ({len(k)}) for the motor fit")
    normal = A.T @ A
    noise = np.zeros(A.shape[1])
    noise[0] = current_noise_a**2
    # the difference of two independently quantised angles: variance 2 * step^2 / 12
    noise[1] = (gear_ratio / period_s) ** 2 * count_rad**2 / 6.0
    if with_inductance:
        noise[2] = 2.0 * current_noise_a**2 / period_s**2
    normal -= len(y) * np.diag(noise)
    try:
        theta = np.linalg.solve(normal, A.T @ y)
        cov_unit = np.linalg.inv(normal)
    except np.linalg.LinAlgError:  # a motor that never turns: R and Ke not determined
        theta, cov_unit = np.full(A.shape[1], np.nan), np.full((A.shape[1],) * 2, np.nan)
    r = y - A @ theta
    sigma2 = r @ r / (len(y) - A.shape[1])
    var = np.diag(sigma2 * cov_unit)
    std = np.sqrt(np.where(var >= 0.0, var, np.nan))  # negative: not determined (nan)
    return MotorEstimate(
        joint=joint,
        resistance=float(theta[0]),
        ke=float(theta[1]),
        inductance=float(theta[2]) if with_inductance else None,
        resistance_std=float(std[0]),
        ke_std=float(std[1]),
        rows=len(k),
        residual_rms_v=float(np.sqrt(np.mean(r**2))),
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
    """Warnings for identified motors whose Ke or R disagree with the robot description's
    (:data:`KE_TOLERANCE`, :data:`R_FACTOR`, :data:`DOUBT_STD`): the voltage, current or
    angle columns of that joint may not belong together (swapped, another robot's log), or
    the description's motor is not the one fitted."""
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
                "columns, another robot's log?) or its motor is not the description's; the "
                "rigid-body parameters rest on the description's Kt"
            )
    return out
