"""The telemetry's whole-mA current put back on the ADC's levels (issue 27): the second
rounding's error follows the motion and biased long captures' tilt friction."""

from __future__ import annotations

import math

import numpy as np
import pytest

from guardid.conditioning.units import current_on_adc_levels
from guardid.identify.prepare import prepared_runs
from guardid.identify.runs import load_run
from guardid.robot import load_robot

RANGE_A, BITS, UNIT_A = 2.0, 10, 1e-3  # the guard's current sensor; TELEMETRY.current in mA
STEP_A = 2 * RANGE_A / 2**BITS  # 3.90625 mA, worked out by hand


def telemetry_ma(levels_a):
    """Whole mA, rounded half up, as the firmware's telemetry sends them (written here from
    the protocol's definition, not from guardid's emulator)."""
    return np.array([math.floor(x * 1000 + 0.5) / 1000 for x in levels_a])


def test_levels_recovered_exactly_from_the_rounded_telemetry():
    rng = np.random.default_rng(4)
    codes = rng.integers(-512, 512, 5000)
    codes[:4] = [16, -16, 0, 511]  # 62.5 mA and -62.5 mA: a rounding tie each
    levels = codes * STEP_A
    got = current_on_adc_levels(telemetry_ma(levels), RANGE_A, BITS, UNIT_A)
    assert got is not None and np.array_equal(got, levels)
    # a second pass leaves exact levels as they are
    assert np.array_equal(current_on_adc_levels(got, RANGE_A, BITS, UNIT_A), levels)


def _rounded(codes, bits=BITS):
    return telemetry_ma(np.asarray(codes) * (2 * RANGE_A / 2**bits))


CODES = np.arange(-20, 20)  # 40 distinct levels: enough to be recognised


@pytest.mark.parametrize(
    ("values", "bits", "why"),
    [
        (np.r_[_rounded(CODES), 0.0031], 10, "3.1 mA: 0.8 mA from the 3.906 mA level"),
        ((_rounded(CODES) + _rounded(CODES + 1)) / 2, 10, "means of two readings"),
        (_rounded(CODES, 12), 12, "a 12-bit ADC: 0.98 mA steps, finer than twice the unit"),
        (_rounded(CODES, 11), 11, "an 11-bit ADC: 1.95 mA steps, not more than twice the unit"),
        (_rounded(np.arange(19)), 10, "19 distinct levels: too few to tell from chance"),
    ],
)
def test_values_that_are_not_rounded_levels_are_left_alone(values, bits, why):
    assert current_on_adc_levels(np.array(values), RANGE_A, bits, UNIT_A) is None, why


def test_twenty_levels_and_a_nan():
    """20 distinct levels are recognised; a NaN stays a NaN and does not stop the rest."""
    values = np.r_[_rounded(np.arange(20)), np.nan]
    got = current_on_adc_levels(values, RANGE_A, BITS, UNIT_A)
    assert got is not None and np.isnan(got[-1])
    assert np.array_equal(got[:-1], np.arange(20) * STEP_A)


def test_cross_validation_scores_the_held_out_run_on_the_levels(gap_guard_captures, monkeypatch):
    """--cv fits on the levels (identify) and scores the held-out run on them too."""
    import guardid.identify.crossval as crossval
    from guardid.identify.pipeline import IdentifyOptions

    seen = []
    run_tuple = crossval._run_tuple

    def spy(part):
        seen.append(np.array(part.current))
        return run_tuple(part)

    monkeypatch.setattr(crossval, "_run_tuple", spy)
    runs = [load_run(gap_guard_captures[s]) for s in (1, 2)]
    crossval.fold_scores(runs, load_robot("guard"), IdentifyOptions(methods=("ls",)))
    assert len(seen) >= 2
    for current in seen:
        codes = current / STEP_A
        assert np.array_equal(codes, np.round(codes))


def test_a_guardid_log_reaches_the_fit_on_the_adc_levels(gap_guard_captures):
    """A simulated capture's currents: every one within half a mA of the level identify
    uses, and every level a whole number of ADC steps (numpy on the log); identify's
    preparation works on a copy."""
    description = load_robot("guard")
    run = load_run(gap_guard_captures[1])
    logged = np.array(run.current)
    (prepared,), _ = prepared_runs([run], description)
    levels = prepared.current
    assert np.array_equal(run.current, logged)  # the caller's run is left as it was
    assert np.all(np.abs(levels - logged) <= 0.5e-3 + 1e-12)
    codes = levels / STEP_A
    assert np.array_equal(codes, np.round(codes))
    assert np.mean(levels != logged) > 0.5  # most readings were moved off whole mA


def test_a_log_in_other_units_keeps_its_current(gap_guard_captures):
    """Currents that are not the telemetry's rounding (here shifted by 0.3 mA on one joint)
    reach the fit as they were logged on that joint."""
    description = load_robot("guard")
    run = load_run(gap_guard_captures[2])
    run.current = np.array(run.current)
    run.current[:, 1] += 0.0003
    kept = run.current[:, 1].copy()
    (prepared,), _ = prepared_runs([run], description)
    assert np.array_equal(prepared.current[:, 1], kept)
    codes = prepared.current[:, 0] / STEP_A
    assert np.array_equal(codes, np.round(codes))
