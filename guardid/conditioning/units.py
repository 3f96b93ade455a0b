"""Unit conversions: encoder counts -> joint radians, motor current -> joint torque."""

from __future__ import annotations

import numpy as np


def counts_per_joint_rev(description) -> np.ndarray:
    """Encoder counts per joint revolution (n,) = encoder counts_per_rev * gear ratio.

    ``description`` is a ChainDescription; every joint needs an encoder (counts per *motor*
    revolution after decoding); a joint without a drive has gear ratio 1.
    """
    out = []
    for joint in description.joints:
        if joint.encoder is None:
            raise ValueError(f"joint {joint.name!r} has no encoder in the description")
        out.append(joint.counts_per_joint_rev)
    return np.asarray(out, dtype=float)


def counts_to_rad(counts, counts_per_rev) -> np.ndarray:
    """Joint angles [rad] from encoder counts (N, n).

    Parameters
    ----------
    counts : array_like (N, n) or (n,)
        Encoder counts (the motor-shaft encoder, decoded).
    counts_per_rev : array_like (n,) or scalar, or a ChainDescription
        Counts per *joint* revolution; a description is converted with
        :func:`counts_per_joint_rev`.
    """
    if hasattr(counts_per_rev, "joints"):
        counts_per_rev = counts_per_joint_rev(counts_per_rev)
    return np.asarray(counts, dtype=float) * (2.0 * np.pi / np.asarray(counts_per_rev, float))


def drive_gain(description) -> np.ndarray:
    """Current-to-torque gain (n,) [N m/A]: N * eta * kt per joint (DESIGN.md section 3).

    Raises ValueError if a joint has no drive (its effort is not a motor current).
    """
    out = []
    for joint in description.joints:
        if joint.drive is None:
            raise ValueError(f"joint {joint.name!r} has no drive: no current-to-torque gain")
        d = joint.drive
        out.append(d.gear_ratio * d.efficiency * d.kt)
    return np.asarray(out, dtype=float)


def current_to_torque(current, gain) -> np.ndarray:
    """Joint torque [N m] = gain [N m/A] * current [A], gain scalar, (n,) or a description."""
    if hasattr(gain, "joints"):
        gain = drive_gain(gain)
    return np.asarray(current, dtype=float) * np.asarray(gain, dtype=float)


def current_on_adc_levels(current_a, full_range_a: float, adc_bits: int, unit_a: float):
    """A joint's logged current [A] (N,) put back on its sensor's ADC levels, or None.

    The firmware reads the current through an ADC of ``adc_bits`` bits over
    +-``full_range_a`` [A] (step 2 x range / 2^bits: 3.906 mA on the guard) and the
    telemetry carries it rounded to whole ``unit_a`` [A] (1 mA; ``TELEMETRY.current``'s
    scale). That second rounding's error depends on the level (it repeats every 125 mA on
    the guard), so it follows the motion and persists through a run: on 20-minute captures
    it biased the tilt's friction by 0.7 std (docs/std_residuals.md). When the step is more
    than twice the unit, each level's rounding is within half a unit of it and of no other
    level, so the level is recovered exactly: round(i / step) x step. None (the values kept
    as they are) when the step is not that coarse, when any value is more than half a unit
    from every level (another firmware's conversion, an averaged reading such as the AVR
    port's mean of its oversampled conversions, a foreign log), or when the joint shows
    fewer than :data:`MIN_DISTINCT_LEVELS` distinct levels (a value off the grid falls
    within half a unit of a level by chance with probability unit / step: a few could pass
    together). Values that are not finite are left where they are."""
    step = 2.0 * float(full_range_a) / (1 << int(adc_bits))
    if not step > 2.0 * unit_a:
        return None
    current = np.asarray(current_a, dtype=float)
    finite = np.isfinite(current)
    levels = np.where(finite, np.round(current / step) * step, current)
    near = np.abs(current - levels)[finite] <= 0.5 * unit_a * (1.0 + 1e-6)
    if not np.all(near) or np.unique(levels[finite]).size < MIN_DISTINCT_LEVELS:
        return None
    return levels


MIN_DISTINCT_LEVELS = 20
"""Fewest distinct levels [-] a joint's current must show before it is put on the ADC's
levels: 20 values off the grid all within half a unit of a level by chance has probability
(unit / step)^20, below 1e-11 on the guard (1 mA against 3.906 mA steps)."""
