"""Fixed-point PID step, as a microcontroller without an FPU runs it.

Positions are encoder counts (int), the output is millivolts (int). Gains arrive in
micro-units (SET_PID: kp [uV/rad], ki [uV/(rad s)], kd [uV s/rad]) and are turned once
into Q16 factors per count, so the per-tick step is integer multiply, add and shift:

    u_mV = (KP*e + I + KD*(e - e_prev) + (FF << 16)) >> 16,   I += KI*e   (I in Q16 mV)

with ``e = setpoint - position`` in counts and ``FF`` the host's feedforward [mV]
(SETPOINT_FF; 0 otherwise), added before the output limit. The integral is clamped to the
output range and frozen while the output saturates in the direction of the error (anti-windup).
"""

from __future__ import annotations

import math

Q = 16  #: fractional bits of the gains and of the integral


def _round_div(num: int, den: int) -> int:
    """Integer division rounded half away from zero (den > 0)."""
    return (num + den // 2) // den if num >= 0 else -((-num + den // 2) // den)


def pid_gains_q16(
    kp_uv: int, ki_uv: int, kd_uv: int, counts_per_rev: int, tick_us: int
) -> tuple[int, int, int]:
    """Q16 gains in mV per count (per tick for KI, times ticks for KD).

    kp_uv [uV/rad], ki_uv [uV/(rad s)], kd_uv [uV s/rad]; counts_per_rev: encoder counts
    per joint revolution; tick_us: sample period [us]. Integers only, 2*pi entering as
    the integer 2*pi*1e9, so that the C core computes the very same factors.
    """
    two_pi_e9 = 6283185307  # 2*pi * 1e9
    # kp [mV/count] = kp_uv * 1e-3 * 2pi / cpr  -> Q16
    den = counts_per_rev * 1_000_000_000 * 1000
    kp = _round_div(kp_uv * two_pi_e9 << Q, den)
    ki = _round_div(ki_uv * two_pi_e9 * tick_us << Q, den * 1_000_000)
    kd = _round_div(kd_uv * two_pi_e9 * 1_000_000 << Q, den * tick_us)
    return kp, ki, kd


class FixedPid:
    """One joint's PID in integer arithmetic (see the module docstring)."""

    def __init__(self, limit_mv: int) -> None:
        self.limit_mv = limit_mv  #: output saturation [mV], the supply voltage
        self.kp = self.ki = self.kd = 0  # Q16 gains
        self.integral = 0  # Q16 mV
        self.prev_error = 0  # counts
        self.saturated = False

    def set_gains(self, gains_q16: tuple[int, int, int]) -> None:
        """Install Q16 gains from :func:`pid_gains_q16`."""
        self.kp, self.ki, self.kd = gains_q16

    def reset(self) -> None:
        """Forget the integral and the previous error (on entering closed-loop mode)."""
        self.integral = 0
        self.prev_error = 0
        self.saturated = False

    def step(self, setpoint: int, position: int, feedforward_mv: int = 0) -> int:
        """One tick: the output voltage [mV] (PID plus ``feedforward_mv``), clamped to
        +-limit_mv."""
        error = setpoint - position
        limit = self.limit_mv
        lim_q = limit << Q
        integral = self.integral + self.ki * error
        if integral > lim_q:  # clamped to +-lim_q
            integral = lim_q
        elif integral < -lim_q:
            integral = -lim_q
        raw = (
            self.kp * error + integral + self.kd * (error - self.prev_error) + (feedforward_mv << Q)
        )
        out = raw >> Q if raw >= 0 else -((-raw) >> Q)
        # saturated: |out| > limit, then clamped; anti-windup: integrate only while not
        # pushing further into saturation
        if out > limit or out < -limit:
            self.saturated = True
            out = limit if out > 0 else -limit
            if (error > 0) != (out > 0):
                self.integral = integral
        else:
            self.saturated = False
            self.integral = integral
        self.prev_error = error
        return out


def counts_per_joint_rev(counts_per_motor_rev: int, gear_ratio: float) -> int:
    """Encoder counts per joint revolution (gear ratio must give a whole number)."""
    value = counts_per_motor_rev * gear_ratio
    if abs(value - round(value)) > 1e-9:
        raise ValueError(f"counts per joint revolution {value} is not a whole number")
    return int(round(value))


def mv_from_volts(volts: float) -> int:
    """Volts to integer millivolts, rounded."""
    return int(math.floor(volts * 1000.0 + 0.5))
