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
      (:func:`_two_level_evidence`) beats chance by ln(1 / :data:`CHANCE`), gathered at
      :data:`MIN_TRIPLES` or more values (not from one held current), each value is
      replaced by the mean of the levels that round to it: exact where one level does,
      half a step off where two do (against a rounding error that follows the level).

    None (the values kept as they are) otherwise: a finer ADC, another firmware's
    conversion, an averaged reading such as the AVR port's mean of its oversampled
    conversions, a foreign log. Values that are not finite are left where they are."""
    bits = int(adc_bits)
    unit = float(unit_a)
    if not (1 <= bits <= 32 and unit > 0.0):
        return None
    step = 2.0 * float(full_range_a) / (1 << bits)
    if not step > 0.5 * unit:
        return None
    current = np.asarray(current_a, dtype=float)
    finite = np.isfinite(current)
    values = current[finite]
    if values.size == 0:
        return None
    levels = readings_on_levels(values, full_range_a, bits, unit)  # every value a level's
    if levels is None:
        return None
    if step > unit:
        if np.unique(levels).size < distinct_levels_needed(step, unit):
            return None
    else:
        needed = -math.log(CHANCE) * (1.0 - 1e-9)  # MIN_TRIPLES capped triples reach it
        if _two_level_evidence(np.round(values / unit), step, unit, bits) < needed:
            return None
    out = current.copy()
    out[finite] = levels
    return out


def readings_on_levels(values_a, full_range_a: float, adc_bits: int, unit_a: float):
    """Readings [A] (N,) mapped onto the ADC's levels value by value: the level itself
    (step > unit), the mean of the levels that round to the value (unit / 2 < step <=
    unit); None when a value is no level's rounding (or the step neither case). The
    mapping of :func:`current_on_adc_levels`, which first decides from a joint's whole log
    that its values are such roundings; the readings of a joint it put on the levels go
    the same way."""
    unit = float(unit_a)
    step = 2.0 * float(full_range_a) / (1 << int(adc_bits))
    values = np.asarray(values_a, dtype=float)
    if step > unit:
        levels = np.round(values / step) * step
        return levels if np.all(np.abs(values - levels) <= 0.5 * unit * (1.0 + 1e-6)) else None
    if not step > 0.5 * unit:
        return None
    whole = np.round(values / unit)
    if not np.all(np.abs(values / unit - whole) <= 1e-6):
        return None
    mean, count = _preimage(whole, step, unit, int(adc_bits))
    return mean if np.all(count >= 1) else None


CHANCE = 1e-11
"""Chance [-] the level recovery may take values that are not rounded ADC levels for
levels: the fewest distinct levels (step > unit: values spread over the range) and the
histogram's evidence (unit / 2 < step <= unit: whole-unit readings of a current whose
density is smooth over three units) are set so that such values pass with at most this
probability. A current held still at :data:`MIN_TRIPLES` values that two levels each round
to is not covered by that figure."""

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


MIN_TRIPLES = 5
"""Fewest places [-] the histogram must show two levels rounding to one value: each
triple's evidence counts up to ln(1 / :data:`CHANCE`) / 5, so that a current held still
at one value (a holding torque, a square wave's two values) cannot pass however long it
is held."""


def _telemetry_units(levels_a, unit_a: float) -> np.ndarray:
    """Levels [A] as the firmware's telemetry rounds them, in units: floor(level x scale +
    0.5), with scale = 1 / unit as the firmware writes it (1000.0 for mA), so that ties
    fall as its floats make them fall."""
    scale = 1.0 / unit_a
    if abs(scale - round(scale)) <= 1e-9 * scale:
        scale = float(round(scale))
    return np.floor(levels_a * scale + 0.5)


def _preimage(whole, step_a: float, unit_a: float, adc_bits: int):
    """Mean level [A] (N,) and number of ADC codes (N,) whose level (code x step) the
    telemetry rounds to each whole-unit value ``whole`` (N,), unit / 2 < step <= unit;
    codes outside the ADC's range are not counted (count 0, mean NaN)."""
    half = 1 << (adc_bits - 1)
    near = np.round(np.asarray(whole, dtype=float) * (unit_a / step_a))
    codes = near[:, None] + np.arange(-2.0, 3.0)  # a unit holds at most 2 codes, within +-1
    levels = codes * step_a
    hit = (_telemetry_units(levels, unit_a) == whole[:, None]) & (codes >= -half)
    hit &= codes <= half - 1
    count = hit.sum(axis=1)
    with np.errstate(invalid="ignore", divide="ignore"):
        mean = np.where(hit, levels, 0.0).sum(axis=1) / count
    return mean, count


def _two_level_evidence(whole, step_a: float, unit_a: float, adc_bits: int) -> float:
    """Log-likelihood ratio [-] of "rounded ADC levels" against "whole-unit readings of a
    smooth current", from the histogram of ``whole`` (values in units, unit / 2 < step <=
    unit). At each value whose number of levels differs from both neighbours' (the values
    two levels round to, or, below 2/3 unit, the values only one does), the three counts
    are binomial: shares in proportion to their numbers of levels under the first, a third
    each under the second (the density taken as flat over three units). Triples do not
    overlap; each counts up to ln(1 / :data:`CHANCE`) / :data:`MIN_TRIPLES` (a peak where a
    current is held still favours the first without being evidence of levels). Positive
    favours the levels."""
    values, counts = np.unique(whole, return_counts=True)
    lo, hi = values[0] - 1.0, values[-1] + 1.0
    grid = np.arange(lo, hi + 1.0)
    hist = np.zeros(grid.size)
    hist[(values - lo).astype(int)] = counts
    _, n = _preimage(grid, step_a, unit_a, adc_bits)
    cap = -math.log(CHANCE) / MIN_TRIPLES
    odd = np.flatnonzero((n[1:-1] != n[:-2]) & (n[1:-1] != n[2:])) + 1
    total, last = 0.0, -3
    for c in odd:
        if c - last < 3:
            continue
        last = c
        k = hist[c - 1 : c + 2]
        if k.sum() == 0 or n[c - 1 : c + 2].min() < 1:
            continue
        share = n[c - 1 : c + 2] / n[c - 1 : c + 2].sum()
        total += min(cap, float(np.sum(k * np.log(3.0 * share))))
    return total
