"""The telemetry's whole-mA current put back on the ADC's levels (issue 27): the second
rounding's error follows the motion and biased long captures' tilt friction."""

from __future__ import annotations

import math

import numpy as np
import pytest

from guardid.conditioning.units import current_on_adc_levels
from guardid.identify.pipeline import IdentifyOptions
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
        (_rounded(np.arange(19)), 10, "19 distinct levels: too few to tell from chance"),
        (_rounded(np.arange(37), 11), 11, "11-bit: 37 levels of 1.953 mA, too few (38 needed)"),
        (_rounded(np.arange(-200, 200), 13), 13, "a 13-bit ADC: 0.49 mA steps, below half a unit"),
    ],
)
def test_values_that_are_not_rounded_levels_are_left_alone(values, bits, why):
    assert current_on_adc_levels(np.array(values), RANGE_A, bits, UNIT_A) is None, why


def test_an_11_bit_adc_is_recovered_exactly_from_38_levels():
    """1.953 mA steps: each level's whole-mA rounding lies within half a mA of it and of no
    other level; a whole mA falls on some level's rounding with chance 1 / 1.953 = 0.512,
    so 38 values are needed for below 1e-11 (0.512^37 = 1.7e-11, 0.512^38 = 8.9e-12, by
    hand)."""
    step = 2 * RANGE_A / 2**11
    codes = np.arange(-19, 19)
    got = current_on_adc_levels(_rounded(codes, 11), RANGE_A, 11, UNIT_A)
    assert got is not None and np.array_equal(got, codes * step)


STEP12_A = 2 * RANGE_A / 2**12  # 0.9765625 mA: two levels round to one whole mA every 42 mA


def _smooth_codes(n, rng, bits=12):
    """n ADC codes of a smooth current (a slow sine, an offset and 5 mA noise)."""
    current = 0.3 * np.sin(np.linspace(0.0, 60.0, n)) + 0.05 + rng.normal(0.0, 0.005, n)
    return np.floor(current / (2 * RANGE_A / 2**bits) + 0.5)


def test_a_12_bit_adc_goes_to_the_mean_of_the_levels_that_round_to_each_value():
    """Every whole mA is some 12-bit level's rounding and one in about 42 is two levels':
    with enough readings the doubled values show in the histogram, and each value becomes
    the mean of the levels that round to it, here found by brute force over all 4096
    codes."""
    rng = np.random.default_rng(12)
    codes = _smooth_codes(20000, rng)
    logged = _rounded(codes, 12)
    got = current_on_adc_levels(logged, RANGE_A, 12, UNIT_A)
    assert got is not None
    all_levels = np.arange(-2048, 2048) * STEP12_A
    rounded = telemetry_ma(all_levels)
    expected = np.array([all_levels[rounded == v].mean() for v in logged])
    np.testing.assert_allclose(got, expected, rtol=0, atol=1e-12)
    single = np.array([np.sum(rounded == v) == 1 for v in logged])
    assert 0.9 < single.mean() < 1.0  # most values come back exactly, some as a mean of two
    np.testing.assert_allclose(got[single], codes[single] * STEP12_A, rtol=0, atol=1e-12)


CASES12 = ["500 readings", "means of two", "0.3 mA off", "whole mA", "beyond the range", "13 bits"]


@pytest.mark.parametrize("case", CASES12)
def test_12_bit_values_without_the_evidence_are_left_alone(case):
    """Whole mA from a 12-bit ADC carry no sign of the levels but the histogram's: too few
    readings to show it, values that are not whole mA, whole mA of a current that was
    never on 0.977 mA levels (rounded straight from the continuous value), or a value no
    level rounds to (2.1 A: beyond the +-2 A range). A 13-bit ADC's 0.488 mA steps, below
    half a unit, are left alone however many readings show them."""
    rng = np.random.default_rng(13)
    bits = 12
    if case == "500 readings":
        values = _rounded(_smooth_codes(500, rng), 12)
    elif case == "means of two":
        codes = _smooth_codes(20000, rng)
        values = (_rounded(codes, 12) + _rounded(codes + 1, 12)) / 2
    elif case == "0.3 mA off":
        values = _rounded(_smooth_codes(20000, rng), 12) + 0.0003
    elif case == "whole mA":
        current = 0.3 * np.sin(np.linspace(0.0, 60.0, 20000)) + rng.normal(0.0, 0.005, 20000)
        values = telemetry_ma(current)
    elif case == "beyond the range":
        values = np.r_[_rounded(_smooth_codes(20000, rng), 12), 2.1]
    else:
        bits = 13
        values = _rounded(_smooth_codes(40000, rng, 13), 13)
    assert current_on_adc_levels(values, RANGE_A, bits, UNIT_A) is None, case


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
    # the read zero left in: what is scored is then the levels themselves
    options = IdentifyOptions(methods=("ls",), current_zero="ignore")
    crossval.fold_scores(runs, load_robot("guard"), options)
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
    # the footer's zero left in: the levels themselves reach the fit
    (prepared,), _, _ = prepared_runs([run], description, IdentifyOptions(current_zero="ignore"))
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
    (prepared,), _, _ = prepared_runs([run], description, IdentifyOptions(current_zero="ignore"))
    assert np.array_equal(prepared.current[:, 1], kept)
    codes = prepared.current[:, 0] / STEP_A
    assert np.array_equal(codes, np.round(codes))


def _brute_force(full_range_a, bits):
    """Whole mA -> (number of levels, their mean [A]) over every code, each level rounded as
    the firmware's telemetry writes it: floor(level x 1000.0 + 0.5)."""
    step = 2 * full_range_a / 2**bits
    codes = np.arange(-(2 ** (bits - 1)), 2 ** (bits - 1))
    rounded = np.floor(codes * step * 1000.0 + 0.5)
    table = {}
    for v in np.unique(rounded):
        levels = codes[rounded == v] * step
        table[v] = (levels.size, levels.mean())
    return table


@pytest.mark.parametrize(("full_range_a", "bits"), [(2.0, 12), (1.6, 12), (0.6, 11)])
def test_the_levels_behind_each_value_as_the_firmware_rounds_them(full_range_a, bits):
    """Every whole mA in range against a brute force over all codes, on ranges whose steps
    are not powers of two too (1.6 A: 0.78125 mA; 0.6 A / 11 bits: 0.5859 mA), where the
    firmware's floats break some ties downwards."""
    from guardid.conditioning.units import _preimage

    table = _brute_force(full_range_a, bits)
    whole = np.array(sorted(table))
    mean, count = _preimage(whole, 2 * full_range_a / 2**bits, UNIT_A, bits)
    np.testing.assert_array_equal(count, [table[v][0] for v in whole])
    np.testing.assert_allclose(mean, [table[v][1] for v in whole], rtol=0, atol=1e-15)
    beyond = np.array([whole.min() - 1.0, whole.max() + 1.0])  # no code's level rounds there
    np.testing.assert_array_equal(_preimage(beyond, 2 * full_range_a / 2**bits, UNIT_A, bits)[1], 0)


def _doubled_values_ma(n):
    """The first n positive whole mA that two 12-bit levels (2 A) round to."""
    table = _brute_force(RANGE_A, 12)
    return [v for v in sorted(table) if v > 0 and table[v][0] == 2][:n]


def test_the_evidence_worked_by_hand():
    """One triple about a doubled value d: counts (10, 20, 10) at d - 1, d, d + 1 give
    10 ln(3/4) + 20 ln(3/2) + 10 ln(3/4) = 20 ln(9/8) = 2.3557; (100, 200, 100) would give
    23.56 but counts at most ln(1e11) / 5 = 5.0657: one held value is not the evidence."""
    from guardid.conditioning.units import _two_level_evidence

    (d,) = _doubled_values_ma(1)
    for k, want in ((10, 20 * math.log(9 / 8)), (100, math.log(1e11) / 5)):
        whole = np.repeat([d - 1.0, d, d + 1.0], [k, 2 * k, k])
        got = _two_level_evidence(whole, STEP12_A, UNIT_A, 12)
        assert got == pytest.approx(want, rel=1e-9)


@pytest.mark.parametrize("places", [4, 5])
def test_the_evidence_must_come_from_five_places(places):
    """Strong triples (100, 200, 100) about 4 doubled values reach 4 x 5.07 = 20.3 < 25.3:
    left alone; about 5 they reach ln(1e11): put on the levels."""
    whole = np.concatenate(
        [np.repeat([d - 1.0, d, d + 1.0], [100, 200, 100]) for d in _doubled_values_ma(places)]
    )
    got = current_on_adc_levels(whole / 1000, RANGE_A, 12, UNIT_A)
    assert (got is not None) == (places == 5)


@pytest.mark.parametrize("case", ["held at 21 mA", "square wave", "held half the log"])
def test_a_current_held_still_is_not_taken_for_levels(case):
    """Whole mA of currents never on the levels that sit still at values two levels round
    to (a holding torque; a square wave between two such values; half a log held, half a
    smooth motion): each hold is one place however long it lasts."""
    rng = np.random.default_rng(21)
    d1, d2 = _doubled_values_ma(2)  # 21 and 63 mA
    if case == "held at 21 mA":
        current = d1 / 1000 + rng.normal(0.0, 0.0003, 60000)
    elif case == "square wave":
        current = np.where(np.arange(60000) % 200 < 100, d1, -d1) / 1000
        current = current + rng.normal(0.0, 0.0003, 60000)
    else:
        moving = 0.3 * np.sin(np.linspace(0.0, 60.0, 30000)) + rng.normal(0.0, 0.005, 30000)
        current = np.r_[d2 / 1000 + rng.normal(0.0, 0.0003, 30000), moving]
    assert current_on_adc_levels(telemetry_ma(current), RANGE_A, 12, UNIT_A) is None
