"""Sensor and actuator quantisation: PWM duty, ADC, shaft encoder (all SI units)."""

from __future__ import annotations

import math

TWO_PI = 2.0 * math.pi


def pwm_quantise(volts: float, supply: float, bits: int) -> float:
    """Voltage [V] actually applied by a sign-magnitude PWM of ``bits`` bits.

    The duty takes ``2**bits`` levels 0 .. 2**bits - 1 (of ``supply`` [V]); the magnitude is
    clipped to the supply and rounded to the nearest level, the sign is kept (symmetric).
    """
    levels = (1 << bits) - 1
    mag = min(abs(volts), supply)
    duty = math.floor(mag / supply * levels + 0.5)
    out = duty * supply / levels
    return -out if volts < 0.0 else out


def adc_quantise(value: float, full_range: float, bits: int) -> float:
    """Reading of a ``bits``-bit ADC spanning +-``full_range`` (same unit as ``value``).

    Step (LSB) = 2 * full_range / 2**bits; the code is round(value / LSB) clipped to
    [-2**(bits-1), 2**(bits-1) - 1]; the result is code * LSB.
    """
    lsb = 2.0 * full_range / (1 << bits)
    half = 1 << (bits - 1)
    code = math.floor(value / lsb + 0.5)
    if code >= half:
        code = half - 1
    elif code < -half:
        code = -half
    return code * lsb


def adc_step(full_range: float, bits: int) -> float:
    """ADC step (LSB) [unit of the range]."""
    return 2.0 * full_range / (1 << bits)


def encoder_counts(q: float, counts_per_rad: float) -> int:
    """Quadrature counts for joint angle ``q`` [rad]: floor(q * N * counts_per_rev / 2 pi).

    ``counts_per_rad`` = N * counts_per_rev / (2 pi) (counts per joint radian).
    """
    return math.floor(q * counts_per_rad)
