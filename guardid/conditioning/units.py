"""Unit conversions: encoder counts -> joint radians, motor current -> joint torque."""

from __future__ import annotations

import math

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
    telemetry carries it rounded (half up) to whole ``unit_a`` [A] (1 mA;
    ``TELEMETRY.current``'s scale). That second rounding's error depends on the level (it
    repeats every 125 mA on the guard), so it follows the motion and persists through a
    run: on 20-minute captures it biased the tilt's friction by 0.7 std
    (docs/std_residuals.md). Two cases are undone:

    - **step > unit** (the guard; an 11-bit ADC over +-2 A): each level's rounding lies
      within half a unit of it and of no other level, so the level is recovered exactly,
      round(i / step) x step, when every finite value lies within half a unit of a level
      and the joint shows at least :func:`distinct_levels_needed` distinct levels (a value
      off the grid falls that near a level by chance with probability unit / step).
    - **unit / 2 < step <= unit** (a 12-bit ADC over +-2 A: 0.977 mA steps): every whole
      unit is some level's rounding, and one in about unit / (unit - step) is two levels'
      (every 42 mA on that ADC). Whole-unit values are thus no evidence by themselves; the
      histogram is: a value that two levels round to is read about twice as often as its
      neighbours. When every finite value is a whole number of units and that evidence
      (:func:`_two_level_evidence`) beats chance by ln(1 / :data:`CHANCE`), each value is
      replaced by the mean of the levels that round to it: exact where one level does,
      half a step off where two do (against a rounding error that follows the level).

    None (the values kept as they are) otherwise: a finer ADC, another firmware's
    conversion, an averaged reading such as the AVR port's mean of its oversampled
    conversions, a foreign log. Values that are not finite are left where they are."""
    step = 2.0 * float(full_range_a) / (1 << int(adc_bits))
    unit = float(unit_a)
    if not (step > 0.5 * unit and unit > 0.0):
        return None
    current = np.asarray(current_a, dtype=float)
    finite = np.isfinite(current)
    if step > unit:
        levels = np.where(finite, np.round(current / step) * step, current)
        near = np.abs(current - levels)[finite] <= 0.5 * unit * (1.0 + 1e-6)
        needed = distinct_levels_needed(step, unit)
        if not np.all(near) or np.unique(levels[finite]).size < needed:
            return None
        return levels
    whole = np.round(current[finite] / unit)
    if whole.size == 0 or not np.all(np.abs(current[finite] / unit - whole) <= 1e-6):
        return None
    first, count = _preimage(whole, step / unit, int(adc_bits))
    if np.any(count < 1) or _two_level_evidence(whole, step / unit, int(adc_bits)) < -math.log(
        CHANCE
    ):
        return None
    out = current.copy()
    out[finite] = (first + 0.5 * (count - 1)) * step
    return out


CHANCE = 1e-11
"""Chance [-] the level recovery may take values that are not rounded ADC levels for
levels: the fewest distinct levels (step > unit) and the histogram's evidence
(unit / 2 < step <= unit) are set so that values off the grid pass with at most this
probability."""

MIN_DISTINCT_LEVELS = 20
"""Fewest distinct levels [-] a joint's current must show before it is put on the ADC's
levels, whatever the step: 20 values off the grid all within half a unit of a level by
chance has probability (unit / step)^20, below :data:`CHANCE` on the guard (1 mA against
3.906 mA steps)."""


def distinct_levels_needed(step_a: float, unit_a: float) -> int:
    """Fewest distinct levels [-] for step > unit: values off the grid each land within half
    a unit of a level with probability unit / step, so n of them all do with (unit /
    step)^n; n is the least with that below :data:`CHANCE`, and at least
    :data:`MIN_DISTINCT_LEVELS` (20 on the guard; 38 for 1.953 mA steps)."""
    share = unit_a / step_a
    return max(MIN_DISTINCT_LEVELS, math.ceil(math.log(CHANCE) / math.log(share)))


def _preimage(whole, ratio: float, adc_bits: int):
    """First ADC code (N,) and number of codes (N,) whose level rounds (half up) to each
    whole-unit value; ``whole`` in units, ``ratio`` = step / unit <= 1. Codes outside the
    ADC's range are not counted."""
    half = 1 << (adc_bits - 1)
    eps = 1e-9
    first = np.maximum(np.ceil((whole - 0.5) / ratio - eps), -half)
    last = np.minimum(np.ceil((whole + 0.5) / ratio - eps) - 1.0, half - 1)
    return first, last - first + 1.0


def _two_level_evidence(whole, ratio: float, adc_bits: int) -> float:
    """Log-likelihood ratio [-] of "rounded ADC levels" against "whole-unit readings of a
    smooth current", from the histogram of ``whole`` (values in units, step / unit =
    ``ratio`` <= 1). At each value whose number of levels differs from both neighbours'
    (the values two levels round to, or, below 2/3 unit, the values only one does), the
    three counts are binomial: shares in proportion to their numbers of levels under the
    first, a third each under the second (the density taken as flat over three units).
    Triples do not overlap. Positive favours the levels."""
    values, counts = np.unique(whole, return_counts=True)
    lo, hi = values[0] - 1.0, values[-1] + 1.0
    grid = np.arange(lo, hi + 1.0)
    hist = np.zeros(grid.size)
    hist[(values - lo).astype(int)] = counts
    _, n = _preimage(grid, ratio, adc_bits)
    odd = np.flatnonzero((n[1:-1] != n[:-2]) & (n[1:-1] != n[2:])) + 1
    total, last = 0.0, -3
    for c in odd:
        if c - last < 3:
            continue
        last = c
        k = hist[c - 1 : c + 2]
        if k.sum() == 0:
            continue
        share = n[c - 1 : c + 2] / n[c - 1 : c + 2].sum()
        total += float(np.sum(k * np.log(3.0 * share)))
    return total
