"""The current sensors' zero: a capture reads it at rest after the run, identify subtracts
it and widens the std for its error, and says how well the zero must be known for the std
to hold.

Truth: readings scripted by hand (which rows count, their mean); the simulator's own
sensor offset (``sim://guard?wiring=current_offset:J=A``, added in the sensor, the motion
untouched: the PID does not read the current), so that two captures of one seed differ
only by the offset; the robot YAML's base parameters (the simulator runs the YAML).
"""

from __future__ import annotations

import dataclasses
import math
import re
import shutil

import numpy as np
import pytest
import yaml
from badinput_tools import invoke

from guardid.capture.run import _current_zero
from guardid.capture.zero import STILL_TICKS, default_rest_s, measure_current_zero
from guardid.errors import LinkError, LogFormatError
from guardid.identify import IdentifyOptions, identify
from guardid.identify.current_zero import (
    ZERO_SIGNIFICANCE,
    footer_zero,
    sensor_zeros,
    subtract_zeros,
)
from guardid.identify.prepare import current_on_adc_levels
from guardid.identify.runs import Run, load_run
from guardid.robot import load_robot

STEP_A = 4.0 / 1024  # guard.yaml's current ADC step: +-2 A over 10 bits [A]
PAN_OFFSET, TILT_OFFSET = -2 * STEP_A, 5 * STEP_A  # on the ADC's levels: identify's snap holds


@pytest.fixture(scope="module")
def guard():
    return load_robot("guard")


# --- the capture's side: which rows count -------------------------------------------------


class _Telemetry:
    def __init__(self, counts, current_ma, tick=0):
        self.counts, self.current_ma, self.tick = counts, current_ma, tick


class _Session:
    """Scripted telemetry: ``rows`` (counts, current_ma) in order; ``fail_at``: the read
    that raises LinkError."""

    def __init__(self, rows, fail_at=None):
        self.rows, self.read, self.modes, self.fail_at = list(rows), 0, [], fail_at
        self.volts = []

    def set_mode(self, mode):
        self.modes.append(mode)

    def send_voltage(self, volts):
        self.volts.append(list(volts))

    def next_telemetry(self):
        if self.read == self.fail_at:
            raise LinkError("port x: telemetry stopped")
        t = _Telemetry(*self.rows[self.read], tick=self.read)
        self.read += 1
        return t


def test_the_zero_is_the_mean_of_the_rows_after_the_joints_stood_still(guard):
    # 20 rows moving (the tilt falls, a braking current flows), then still rows: the first
    # STILL_TICKS still rows are waited out, the next ones are the zero
    moving = [((0, -k), (0, -150)) for k in range(20)]
    still = [((0, -20), (3 + (k % 3), -7 + 2 * (k % 2))) for k in range(200)]
    session = _Session(moving + still)
    rest_s = 10 * guard.sample_period  # ten rows
    zero = measure_current_zero(session, guard, rest_s)
    assert session.modes == ["voltage"]  # 0 V before every read: the motors held at rest
    assert session.volts == [[0.0, 0.0]] * session.read
    # still[0] is where the joint arrived (its counts differ from the last move's row);
    # still[k] then has k unchanged rows behind it: still[STILL_TICKS] is the first read
    first = STILL_TICKS
    counted = [still[k][1] for k in range(first, first + 10)]
    pan = [c[0] * 1e-3 for c in counted]
    tilt = [c[1] * 1e-3 for c in counted]
    assert zero["pan"]["rows"] == zero["tilt"]["rows"] == 10
    assert zero["pan"]["mean_a"] == pytest.approx(np.mean(pan), abs=1e-15)
    assert zero["tilt"]["mean_a"] == pytest.approx(np.mean(tilt), abs=1e-15)
    assert zero["tilt"]["std_a"] == pytest.approx(np.std(tilt, ddof=1), rel=1e-12)
    assert session.read == 20 + first + 10  # read no further than needed


def test_a_joint_that_moves_again_restarts_the_wait(guard):
    # still for 15 rows, one move, then still: rows before the move count, the wait restarts
    rows = [((0, 0), (1, 1))] * 16 + [((1, 0), (500, 500))] + [((1, 0), (2, 2))] * 40
    zero = measure_current_zero(_Session(rows), guard, 12 * guard.sample_period)
    # before the move: rows 10..15 (10..15 unchanged rows behind them): 6 rows of 1 mA;
    # after it the 10th unchanged row onwards, 6 rows of 2 mA; the move's row (500 mA) never
    assert zero["pan"]["rows"] == 12
    assert zero["pan"]["mean_a"] == pytest.approx(1.5e-3, abs=1e-15)


def test_joints_never_at_rest_are_said_not_measured(guard):
    rows = [((k, 0), (0, 0)) for k in range(100000)]
    session = _Session(rows)
    zero = measure_current_zero(session, guard, 1.0)
    assert set(zero) == {"not_measured"} and "not at rest" in zero["not_measured"]
    assert session.read == math.ceil(1.0 / 0.015) + math.ceil(15.0 / 0.015)  # then gave up


def test_a_lost_link_at_rest_keeps_the_run_and_says_so(guard):
    session = _Session([((0, 0), (0, 0))] * 50, fail_at=30)
    zero = _current_zero(session, guard, 1.0, 60.0)
    assert "link error" in zero["not_measured"]
    assert _current_zero(_Session([]), guard, 0.0, 60.0) is None  # not asked: no entry


def test_the_default_rest_is_a_share_of_the_run_within_its_bounds():
    assert default_rest_s(60.0) == 6.0
    assert default_rest_s(10.0) == 2.0
    assert default_rest_s(3600.0) == 120.0


# --- the log's side: the footer, the zero's std error ----------------------------------------


@pytest.mark.parametrize(
    "entry, field",
    [
        ("not a mapping", "expected a mapping"),
        ({"tilt": 3}, "tilt: expected mean_a"),
        ({"tilt": {"mean_a": "x", "std_a": 0.1, "rows": 5}}, "tilt: mean_a"),
        ({"tilt": {"mean_a": 0.0, "std_a": True, "rows": 5}}, "tilt: std_a"),
        ({"tilt": {"mean_a": 0.0, "std_a": -0.1, "rows": 5}}, "tilt: std_a"),
        ({"tilt": {"mean_a": float("nan"), "std_a": 0.1, "rows": 5}}, "tilt: mean_a"),
        ({"tilt": {"mean_a": 0.0, "std_a": 0.1, "rows": 1}}, "tilt: rows"),
        ({"tilt": {"mean_a": 0.0, "std_a": 0.1}}, "tilt: rows"),
        ({"tilt": {"mean_a": 0.0, "std_a": 0.1, "rows": 2.5}}, "tilt: rows"),
        (
            {"tilt": {"mean_a": 0.0, "std_a": 0.1, "rows": 3, "readings_ma": [[0, 2]]}},
            "tilt: readings",
        ),
        (
            {"tilt": {"mean_a": 0.0, "std_a": 0.1, "rows": 3, "readings_ma": [[0.5, 3]]}},
            "tilt: readings",
        ),
        ({"tilt": {"mean_a": 0.0, "std_a": 0.1, "rows": 3, "readings_ma": [3]}}, "tilt: readings"),
        (
            {"tilt": {"mean_a": 0.0, "std_a": 0.1, "rows": 3, "readings_ma": {0: 3}}},
            "tilt: readings",
        ),
        ({"tilt": {"mean_a": 0.0, "std_a": 0.1, "rows": 3, "t_s": "soon"}}, "tilt: t_s"),
        ({"tilt": {"mean_a": 0.0, "std_a": 0.1, "rows": 3, "t_s": True}}, "tilt: t_s"),
        ({"tilt": {"mean_a": 0.0, "std_a": 0.1, "rows": 3, "t_s": float("inf")}}, "tilt: t_s"),
    ],
)
def test_a_malformed_footer_zero_is_one_line_naming_the_field(entry, field):
    with pytest.raises(LogFormatError, match=f"^log.csv: footer: current_zero: {field}"):
        footer_zero("log.csv", {"current_zero": entry})
    key = "current_zero_before"  # the zero read before the run: the same checks, its name
    with pytest.raises(LogFormatError, match=f"^log.csv: footer: {key}: {field}"):
        footer_zero("log.csv", {key: entry}, key)


def test_no_zero_reads_as_none_and_one_not_measured_says_why():
    assert footer_zero("x", None) is None
    assert footer_zero("x", {"ended": "complete"}) is None
    assert footer_zero("x", {"current_zero": {"not_measured": "why"}}) == {"not_measured": "why"}


def _run(zero, n=200, source=None):
    t = np.arange(n) * 0.015
    current = np.column_stack([np.full(n, 0.1), np.full(n, -0.2)])
    return Run("a.csv", "guard", np.arange(n), t, np.zeros((n, 2)), current, None,
               current_zero=zero, source=source)  # fmt: skip


def test_the_zeros_std_error_worked_out_by_hand(guard):
    noisy = {"mean_a": 0.004, "std_a": 0.008, "rows": 64, "on_levels": True}  # dithered
    quiet = {"mean_a": 0.0, "std_a": 0.0, "rows": 400, "on_levels": True}  # all alike
    pan, tilt = sensor_zeros(_run({"pan": noisy, "tilt": quiet}), guard)
    assert pan.std_error_a == pytest.approx(0.008 / 8, rel=1e-12)
    assert pan.significance == pytest.approx(4.0, rel=1e-12)
    # all alike: the YAML's noise (8 mA) over sqrt(400) and the step's rounding stays
    assert tilt.std_error_a == pytest.approx(math.hypot(0.008 / 20, STEP_A / math.sqrt(12)))
    # two readings that happened to agree do not make a 1 mA std: the YAML's 8 mA at least
    few = {"mean_a": 0.0, "std_a": 0.0025, "rows": 4, "on_levels": True}
    assert sensor_zeros(_run({"pan": few}), guard)[0].std_error_a == pytest.approx(0.004)
    # readings not put back on the ADC's levels keep the telemetry's 1 mA rounding
    raw = {**noisy, "on_levels": False}
    assert sensor_zeros(_run({"pan": raw}), guard)[0].std_error_a == pytest.approx(
        math.sqrt(0.001**2 + 1e-6 / 12), rel=1e-12
    )
    assert sensor_zeros(_run({"tilt": quiet}), guard)[0] is None  # the pan not read


def test_the_zeros_readings_go_on_the_adcs_levels_as_the_logs_currents_do(guard):
    """The capture's whole-mA readings of the rest, by hand: 4 mA is the level 3.90625 mA
    (one step of 4 / 1024 A), -8 mA two steps down; the footer's own mean_a is not used."""
    zero = {"tilt": {"mean_a": 0.5, "std_a": 9.0, "rows": 4, "readings_ma": [[-8, 1], [4, 3]]}}
    logged = np.round((np.arange(200) - 100) * STEP_A * 1e3) * 1e-3  # levels in whole mA
    run = dataclasses.replace(_run(zero), current=np.column_stack([logged, logged]),
                              current_zero_before=zero)  # fmt: skip
    on = current_on_adc_levels(run, guard)
    levels = np.array([-2, 1, 1, 1]) * STEP_A
    for entry in (on.current_zero["tilt"], on.current_zero_before["tilt"]):  # both rests
        assert entry["on_levels"] is True
        assert entry["mean_a"] == pytest.approx(levels.mean(), abs=1e-15)
        assert entry["std_a"] == pytest.approx(levels.std(ddof=1), rel=1e-12)
    assert footer_zero("x", {"current_zero": {"tilt": {**zero["tilt"], "on_levels": True}}}) == {
        "tilt": zero["tilt"]
    }  # a file cannot say it is on levels


def test_every_read_zero_is_subtracted_once_per_log_and_one_off_is_a_warning(guard):
    big = {"mean_a": 0.02, "std_a": 0.008, "rows": 100, "on_levels": True}  # 25 std errors
    small = {"mean_a": 0.003, "std_a": 0.008, "rows": 100, "on_levels": True}  # 3.75
    zero = {"pan": big, "tilt": small}
    segments = [_run(zero, source="a.csv"), _run(zero, source="a.csv")]
    runs, read = subtract_zeros(segments, guard, "subtract")
    for r in runs:
        np.testing.assert_allclose(r.current[:, 0], 0.1 - 0.02, rtol=0, atol=1e-15)
        np.testing.assert_allclose(r.current[:, 1], -0.2 - 0.003, rtol=0, atol=1e-15)
    assert [(t.source, t.joint) for t in read.taken] == [("a.csv", 0), ("a.csv", 1)]  # once
    line = ("a.csv: current sensors' zero read at rest: pan +20.00 +- 0.80 mA, tilt +3.00 "
            "+- 0.80 mA: subtracted, every std counting its error")  # fmt: skip
    assert read.lines == (line,)
    assert len(read.warnings) == 1 and "the pan current sensor reads +20.00" in read.warnings[0]
    assert ZERO_SIGNIFICANCE == 4.0  # 3.75 std errors: no warning, 25: one

    runs, read = subtract_zeros(segments, guard, "ignore")
    assert not read.taken and runs[0].current is segments[0].current
    assert read.lines[0].endswith("left in (--current-zero ignore)")
    assert len(read.warnings) == 1  # an off sensor is said whatever is done with it
    assert "left in: the estimates carry it" in read.warnings[0]
    torque = Run("t.csv", "guard", None, np.arange(5.0), np.zeros((5, 2)), np.ones((5, 2)),
                 None, torque=True, current_zero=zero)  # fmt: skip
    assert subtract_zeros([torque], guard, "subtract")[0][0] is torque
    with pytest.raises(ValueError, match="auto"):
        subtract_zeros(segments, guard, "auto")
    # a joint the robot does not have (a renamed column): said, not used
    _, read = subtract_zeros([_run({**zero, "Tilt": small})], guard, "subtract")
    assert any("current_zero: Tilt: no such joint in the robot" in w for w in read.warnings)


# --- end to end on the simulator's own sensor offset -------------------------------------------


@pytest.fixture(scope="module")
def offset_captures(tmp_path_factory, excitation):
    """One seed captured four times (60 s): healthy, the pan's sensor PAN_OFFSET off, the
    tilt's TILT_OFFSET off, and both (``both``); ``--zero-rest`` its default, the zero read
    before the run too (``--zero-before``)."""
    d = tmp_path_factory.mktemp("current_zero")
    traj = excitation("--no-optimise")
    out = {}
    for name, wiring in (("healthy", ""), ("pan", f"current_offset:pan={PAN_OFFSET!r}"),
                         ("tilt", f"current_offset:tilt={TILT_OFFSET!r}"),
                         ("both", f"current_offset:pan={PAN_OFFSET!r},"
                                  f"current_offset:tilt={TILT_OFFSET!r}")):  # fmt: skip
        port = "sim://guard?seed=4&phase=1" + (f"&wiring={wiring}" if wiring else "")
        log = d / f"{name}.csv"
        res = invoke("capture", "--port", port, "--trajectory", traj, "--duration", 60,
                     "--quiet", "--zero-before", "-o", log)  # fmt: skip
        assert res.exit_code == 0, res.output
        out[name] = log
    return out


def _tilt_reads_its_offset(output) -> bool:
    """The warning that the tilt's sensor is off, by about TILT_OFFSET."""
    found = re.search(r"the tilt current sensor reads \+([\d.]+) \+- ", output)
    return found is not None and abs(float(found.group(1)) - 1e3 * TILT_OFFSET) < 1.5


def _fit(log, mode, guard):
    return identify([load_run(log)], guard, IdentifyOptions(methods=("wls",), current_zero=mode))


def test_the_capture_reads_the_simulated_sensors_zero(offset_captures):
    footer = _footer(offset_captures["both"])["current_zero"]
    assert footer["pan"]["rows"] == footer["tilt"]["rows"] == math.ceil(6.0 / 0.015)  # 10 %
    for joint, truth in (("pan", PAN_OFFSET), ("tilt", TILT_OFFSET)):
        e = footer[joint]
        err = e["std_a"] / math.sqrt(e["rows"])
        assert abs(e["mean_a"] - truth) < 4 * err + 1e-3  # the telemetry's whole mA
    healthy = _footer(offset_captures["healthy"])["current_zero"]
    for e in healthy.values():
        assert abs(e["mean_a"]) < 4 * e["std_a"] / math.sqrt(e["rows"])


def _footer(log) -> dict:
    """The log's footer, parsed here: the commented lines from '# footer:' on."""
    lines = log.read_text().splitlines()
    start = lines.index("# footer:")
    return yaml.safe_load("\n".join(ln[2:] for ln in lines[start:]))["footer"]


def _with_zero(log, zeros):
    """``log``'s run with its footer's zeros replaced by ``zeros`` {joint: A} (read once),
    known to 1e-8 A (noisy readings on the ADC's levels, 1e12 of them)."""
    exact = {j: {"mean_a": z, "std_a": 0.01, "rows": 10**12, "on_levels": True}
             for j, z in zeros.items()}  # fmt: skip
    return dataclasses.replace(load_run(log), current_zero=exact, current_zero_before=None)


def test_subtracting_the_simulated_offset_gives_the_healthy_estimate(offset_captures, guard):
    """The simulator adds the offset in its sensor; the motion is the same (the PID reads no
    current). Subtracting that offset as the footer's zero gives the healthy log's
    estimate: the zero enters the rows as the constant it is, nothing else."""
    healthy = _fit(offset_captures["healthy"], "ignore", guard).results["wls"]
    for name, zeros in (("pan", {"pan": PAN_OFFSET}), ("tilt", {"tilt": TILT_OFFSET}),
                        ("both", {"pan": PAN_OFFSET, "tilt": TILT_OFFSET})):  # fmt: skip
        run = _with_zero(offset_captures[name], zeros)
        taken = identify([run], guard, IdentifyOptions(methods=("wls",), current_zero="subtract"))
        np.testing.assert_allclose(taken.results["wls"].theta, healthy.theta, rtol=0,
                                   atol=1e-6 * healthy.std.min())  # fmt: skip
        left = _fit(offset_captures[name], "ignore", guard).results["wls"].theta
        assert np.max(np.abs(left - healthy.theta) / healthy.std) > 10  # it mattered


def test_the_sensitivity_is_how_the_estimate_moves_with_a_small_zero(offset_captures, guard):
    """The reported change per ampere against the whole pipeline run again with 0.1 mA
    subtracted from one joint (small: WLS's weights, which a zero moves too, stay put; a
    2-step offset on this log moves the pan's weight by 4 times)."""
    healthy = _fit(offset_captures["healthy"], "ignore", guard)
    G, w = healthy.current_zero.sensitivity, healthy.results["wls"]
    for j, name in enumerate(("pan", "tilt")):
        run = _with_zero(offset_captures["healthy"], {name: 1e-4})
        moved = identify([run], guard, IdentifyOptions(methods=("wls",), current_zero="subtract"))
        per_amp = (moved.results["wls"].theta - w.theta) / -1e-4
        assert np.max(np.abs(G[:, j]) / w.std) > 1000  # a parameter moves 1 std per mA or more
        # WLS's weights, held in G, move with the zero too: a few % of the column's largest
        scale = np.max(np.abs(G[:, j]) / w.std)
        np.testing.assert_allclose(per_amp / w.std, G[:, j] / w.std, rtol=0, atol=0.05 * scale)


def test_identify_subtracts_the_read_zero_and_the_truth_is_within_3_std(offset_captures):
    log = offset_captures["both"]
    res = invoke("identify", log, "--method", "wls", "-o", log.with_suffix(".yaml"))
    assert res.exit_code == 0, res.output
    assert "current sensors' zero read at rest: pan -7." in res.output
    assert (
        "subtracted as a straight line from before the run to after it, every std "
        "counting its error" in res.output
    )
    assert "warning: " in res.output and _tilt_reads_its_offset(res.output)
    assert "zero moved by" not in res.output  # an offset, no drift: the two zeros agree
    params = yaml.safe_load(log.with_suffix(".yaml").read_text())
    truth = np.array([p["yaml_value"] for p in params["base_parameters"]])
    wls = params["methods"]["wls"]
    z = (np.array(wls["values"]) - truth) / np.array(wls["std"])
    assert np.all(np.abs(z) < 3), z
    taken = params["current_zero"]["subtracted"]
    assert [(t["joint"], t["read"]) for t in taken] == [
        ("pan", "before"),
        ("pan", "after"),
        ("tilt", "before"),
        ("tilt", "after"),
    ]
    # left in, the same log is confidently wrong: the tilt's offset becomes gravity (MX2R)
    res = invoke("identify", log, "--method", "wls", "--current-zero", "ignore",
                 "-o", log.with_suffix(".ignored.yaml"))  # fmt: skip
    assert res.exit_code == 0, res.output
    ignored = yaml.safe_load(log.with_suffix(".ignored.yaml").read_text())["methods"]["wls"]
    names = [p["name"] for p in params["base_parameters"]]
    k = names.index("MX2R")
    assert abs(ignored["values"][k] - truth[k]) > 10 * ignored["std"][k]


def test_the_tolerance_is_the_zero_error_that_moves_a_parameter_by_one_std(offset_captures, guard):
    healthy = _fit(offset_captures["healthy"], "subtract", guard)
    assert not any("current sensor reads" in w for w in healthy.warnings)  # within noise
    assert any("tilt +0." in n or "tilt -0." in n for n in healthy.notes)
    tol = healthy.current_zero.tolerance_a
    G, std = healthy.current_zero.sensitivity, healthy.results["wls"].std
    for j in range(2):
        assert np.max(np.abs(G[:, j]) * tol[j] / std) == pytest.approx(1.0, rel=1e-9)
        assert 1e-5 < tol[j] < 1e-2  # a fraction of the 3.9 mA step, on a minute's log


def test_subtracting_widens_the_std_by_the_zeros_own_error(offset_captures, guard):
    """The healthy log's zero is noise, taken off all the same: each std is the one
    of the same zero known exactly, plus the change per ampere times the zero's std error
    (worked out here from the readings put on the ADC's levels), in quadrature."""
    log = offset_captures["healthy"]
    prepared = current_on_adc_levels(load_run(log), guard).current_zero  # on the levels
    read = {j: prepared[j]["mean_a"] for j in ("pan", "tilt")}
    exact = identify([_with_zero(log, read)], guard,
                     IdentifyOptions(methods=("wls",), current_zero="subtract"))  # fmt: skip
    once = dataclasses.replace(load_run(log), current_zero_before=None)  # read after the run
    taken = identify([once], guard, IdentifyOptions(methods=("wls",), current_zero="subtract"))
    # the readings' std, at least guard.yaml's 8 mA sensor noise, over sqrt(rows)
    err = [
        max(prepared[j]["std_a"], 0.008) / math.sqrt(prepared[j]["rows"]) for j in ("pan", "tilt")
    ]
    G = exact.current_zero.sensitivity
    extra = (G[:, 0] * err[0]) ** 2 + (G[:, 1] * err[1]) ** 2
    np.testing.assert_allclose(taken.results["wls"].theta, exact.results["wls"].theta,
                               rtol=1e-12)  # fmt: skip
    np.testing.assert_allclose(taken.results["wls"].std ** 2,
                               exact.results["wls"].std ** 2 + extra, rtol=1e-6)  # fmt: skip
    assert np.max(extra / exact.results["wls"].std ** 2) > 0.1  # a widening worth testing
    assert len(taken.current_zero.subtracted) == 2


def test_a_log_without_the_footers_zero_is_identified_as_before(offset_captures, tmp_path, guard):
    """The footer's zeros removed by hand (a log of an older capture): the sensitivity is
    still said; nothing is subtracted."""
    log = tmp_path / "old.csv"
    shutil.copy(offset_captures["healthy"], log)
    for key in ("current_zero", "current_zero_before"):
        lines = log.read_text().splitlines(keepends=True)
        start = next(i for i, ln in enumerate(lines) if ln.startswith(f"#   {key}:"))
        end = start + 1
        while end < len(lines) and lines[end].startswith("#     "):
            end += 1
        log.write_text("".join(lines[:start] + lines[end:]))
    run = load_run(log)
    assert run.current_zero is None and run.current_zero_before is None
    res = invoke("identify", log, "--method", "wls")
    assert res.exit_code == 0, res.output
    assert "read at rest" not in res.output
    assert "std hold while each sensor's zero is known to well within pan 0." in res.output
    ignored = _fit(offset_captures["healthy"], "ignore", guard)
    assert np.array_equal(_fit(log, "subtract", guard).results["wls"].theta,
                          ignored.results["wls"].theta)  # fmt: skip


def test_validate_and_cv_subtract_the_read_zero_too(offset_captures, tmp_path):
    """A model fitted on the healthy log scores the offset log as well as the healthy one
    once the offset log's read zero is taken off (validate), and leave-one-run-out over
    the two logs scores each held-out run near the fit's own error, not the offset's."""
    params = tmp_path / "healthy.yaml"
    res = invoke("identify", offset_captures["healthy"], "--method", "wls", "-o", params)
    assert res.exit_code == 0, res.output
    scores = {}
    for name in ("healthy", "both"):
        res = invoke("validate", offset_captures[name], "--params", params)
        assert res.exit_code == 0, res.output
        scores[name] = float(re.search(r":WLS\s+([\d.]+)%", res.output).group(1))
    assert _tilt_reads_its_offset(res.output)  # the offset log's warning
    assert scores["both"] < 1.2 * scores["healthy"]
    cv = {}
    for mode in ("subtract", "ignore"):
        res = invoke("identify", "--cv", offset_captures["both"], offset_captures["healthy"],
                     "--method", "wls", "--current-zero", mode)  # fmt: skip
        assert res.exit_code == 0, res.output
        cv[mode] = float(re.search(r"^mean\s+([\d.]+)%", res.output, re.M).group(1))
    assert cv["subtract"] < 0.5 * cv["ignore"]


class _StopAfter:
    """A session whose telemetry reads raise KeyboardInterrupt (Ctrl-C) once ``after`` of
    them were made after the capture said it is reading the zero (``notify``) ``when``
    ('before' or 'after' the trajectory)."""

    def __init__(self, session, after, when="after"):
        self.session, self.after, self.left, self.when = session, after, None, when

    def __getattr__(self, name):
        return getattr(self.session, name)

    def notify(self, message):
        said = "before the trajectory" if self.when == "before" else "trajectory done"
        if "zero at rest" in message and message.startswith(said):
            self.left = self.after

    def next_telemetry(self):
        if self.left is not None:
            if self.left == 0:
                raise KeyboardInterrupt
            self.left -= 1
        return self.session.next_telemetry()


@pytest.mark.parametrize(
    "when, after, kept",
    [("after", 300, True), ("after", 5, False), ("before", 300, True), ("before", 5, False)],
)
def test_a_stop_during_the_rest_keeps_the_zero_read_so_far(tmp_path, guard, when, after, kept):
    """Ctrl-C at rest: every row of the finished trajectory stays, the zero read until then
    goes to the footer (rows: the reads after the 10 still ticks); with fewer than two
    readings the footer says it was not read, and identify warns. Before the trajectory:
    no row, nothing moved but the arm settling at 0 V, the zero read so far kept."""
    from guardid.capture import capture
    from guardid.excitation.sines import SumOfSines
    from guardid.link import Session, open_port

    port = open_port("sim://guard?seed=7")
    session = _StopAfter(Session(port), after, when)
    session.handshake()
    log = tmp_path / "run.csv"
    traj = SumOfSines([[0.3], [0.1]], [[0.2], [0.3]], [[0.0], [0.0]], [0.0, 0.2])
    result = capture(session, guard, traj, 10.0, log, {"robot": "guard"}, notify=session.notify,
                     zero_rest_s=10.0, zero_before=True)  # fmt: skip
    port.close()
    footer = _footer(log)
    if when == "before":
        assert result.ended == "interrupted" and result.rows == 0
        assert "current_zero" not in footer  # never reached
        zero = footer["current_zero_before"]
        if kept:
            assert 2 <= zero["tilt"]["rows"] <= 300 - STILL_TICKS
        else:
            assert "not_measured" in zero and "SIGINT" in zero["not_measured"]
        return
    assert result.ended == "interrupted" and result.rows == 667
    zero = footer["current_zero"]
    assert footer["current_zero_before"]["pan"]["rows"] == math.ceil(10.0 / 0.015)
    if kept:
        # the joints come to rest first, then the still ticks: of the 300 reads, fewer
        # than the 10 s asked for are readings, and some are
        assert 2 <= zero["tilt"]["rows"] <= 300 - STILL_TICKS < math.ceil(10.0 / 0.015)
        assert zero["tilt"]["rows"] == zero["pan"]["rows"]
    else:
        assert "not_measured" in zero and "SIGINT" in zero["not_measured"]
        res = invoke("identify", log, "--robot", "guard", "--method", "wls")
        assert "the current sensors' zero was not read after the run (stopped (SIGINT)" in (
            res.output
        )
        assert "the one read before it is taken off as a constant" in res.output


def test_the_widening_holds_in_the_acceleration_form_and_in_current_units(offset_captures):
    """The read zero's error widens the std in either equation form and in current units,
    by the same share in current units as in torque (current units scale each joint's
    equation by its gain; WLS's weights take the scale out); a robot whose joints have no
    friction model (no offset column in the momentum form) says its error is not counted.
    The healthy log: its zero is noise, so ignoring it changes nothing but the std."""
    log = offset_captures["healthy"]
    widening = {}
    for extra in ([], ["--equation", "acceleration"], ["--current-units"]):
        std = {}
        for mode in ("subtract", "ignore"):
            out = log.parent / f"w{len(extra)}{mode}.yaml"
            res = invoke("identify", log, "--method", "wls", "--current-zero", mode, *extra,
                         "-o", out, "--force")  # fmt: skip
            assert res.exit_code == 0, res.output
            std[mode] = np.array(yaml.safe_load(out.read_text())["methods"]["wls"]["std"])
        widening[tuple(extra)] = std["subtract"] / std["ignore"]
        assert widening[tuple(extra)].max() > 1.1, extra  # MX2R's, Fc1's
    np.testing.assert_allclose(widening[("--current-units",)], widening[()], rtol=0.05)
    robot = log.parent / "frictionless.yaml"
    text = open(load_robot("guard").source, encoding="utf-8").read()
    robot.write_text(re.sub(r"friction: \{[^}]*\}", "friction: null", text))
    res = invoke("identify", log, "--robot", robot, "--method", "wls", "--force")
    assert "its error NOT counted in the std" in res.output


# --- a zero that drifts: read before and after the run, taken off as a line -------------------

DRIFT_A_PER_S = {"pan": 1e-4, "tilt": -1e-4}  # 0.1 mA/s: about 7 mA over a 60 s capture's time


@pytest.fixture(scope="module")
def drift_capture(tmp_path_factory, excitation):
    """One 60 s capture of the optimised excitation on a seed whose sensors' zeros drift
    (``current_drift``, from the robot's power-up, before the sensor's ADC: the currents stay
    on its levels), ``--zero-rest`` its default and ``--zero-before`` (6 s before the run,
    6 s after)."""
    log = tmp_path_factory.mktemp("drift") / "drift.csv"
    wiring = ",".join(f"current_drift:{j}={r!r}" for j, r in DRIFT_A_PER_S.items())
    res = invoke("capture", "--port", f"sim://guard?seed=5&phase=1&wiring={wiring}",
                 "--trajectory", excitation(), "--duration", 60, "--quiet", "--zero-before",
                 "-o", log)  # fmt: skip
    assert res.exit_code == 0, res.output
    assert "current sensors' zero before the run at rest: pan " in res.output
    assert "; after it at rest: pan " in res.output
    return log


def test_the_capture_reads_the_zero_before_and_after_the_run_with_their_times(drift_capture):
    """Both rests in the footer, each joint's with its mean time on the log's clock: the
    one before the run ends before its first row, the one after starts after its last;
    the two zeros differ by the simulated drift times the time between them."""
    footer = _footer(drift_capture)
    before, after = footer["current_zero_before"], footer["current_zero"]
    # the tilt sank onto its stop at 0 V: an approach brought it back before the first row
    assert footer["start_approach_ticks"] > math.ceil(0.5 / 0.015)  # the quintic and the hold
    lowest = load_robot("guard").joints[1].limits.position[0]
    assert load_run(drift_capture).q[0, 1] - lowest > 0.05  # off its stop [rad]
    rows = math.ceil(6.0 / 0.015)
    for joint, rate in DRIFT_A_PER_S.items():
        b, a = before[joint], after[joint]
        assert b["rows"] == a["rows"] == rows
        # the readings' mean time: half the rest from its end (before) or start (after)
        assert b["t_s"] <= -0.5 * rows * 0.015 + 1e-9
        assert a["t_s"] >= 60.0 + 0.5 * (rows - 1) * 0.015 - 1e-9
        err = math.hypot(b["std_a"], a["std_a"]) / math.sqrt(rows)
        moved = a["mean_a"] - b["mean_a"]
        assert abs(moved - rate * (a["t_s"] - b["t_s"])) < 4 * err + 1e-3  # whole mA


def test_a_drifting_zero_is_taken_off_as_a_line_and_the_truth_is_within_3_std(drift_capture):
    """The line through the two zeros: every parameter within 3 std of the YAML's, the
    drift said. The same log with only the zero after the run (a constant: an older
    capture's footer) is confidently wrong on the gravity term."""
    out = drift_capture.with_suffix(".yaml")
    res = invoke("identify", drift_capture, "--method", "wls", "-o", out, "--force")
    assert res.exit_code == 0, res.output
    assert "subtracted as a straight line from before the run to after it" in res.output
    for joint in DRIFT_A_PER_S:
        assert f"the {joint} current sensor's zero moved by " in res.output
    params = yaml.safe_load(out.read_text())
    truth = np.array([p["yaml_value"] for p in params["base_parameters"]])
    wls = params["methods"]["wls"]
    z = (np.array(wls["values"]) - truth) / np.array(wls["std"])
    assert np.all(np.abs(z) < 3), z
    once = dataclasses.replace(load_run(drift_capture), current_zero_before=None)
    const = identify([once], load_robot("guard"), IdentifyOptions(methods=("wls",))).results
    z_const = (const["wls"].theta - truth) / const["wls"].std
    assert np.max(np.abs(z_const)) > 4, z_const  # MX2R: the tilt's drift taken for gravity


def _with_line(log, shift_a=None):
    """``log``'s run with both its footer's zeros (their times kept) known to 1e-8 A, one of
    them moved: ``shift_a`` (joint, 'before' | 'after', A)."""
    run = current_on_adc_levels(load_run(log), load_robot("guard"))
    zeros = {}
    for key, when in (("current_zero_before", "before"), ("current_zero", "after")):
        zeros[key] = {}
        for j, e in getattr(run, key).items():
            moved = shift_a[2] if shift_a and shift_a[:2] == (j, when) else 0.0
            zeros[key][j] = {"mean_a": e["mean_a"] + moved, "std_a": 0.01, "rows": 10**12,
                             "on_levels": True, "t_s": e["t_s"]}  # fmt: skip
    return dataclasses.replace(run, **zeros)


def test_each_end_of_the_line_widens_the_std_by_its_own_effect(drift_capture, guard):
    """The two ends' errors, each through its own share of the line: the std of the read
    line is that of the same line known exactly plus, in quadrature, each end's change of
    the estimate per ampere (the whole pipeline run again with that end moved 0.1 mA)
    times its std error (worked out here: the readings' std on the ADC's levels, at least
    guard.yaml's 8 mA sensor noise, over sqrt(rows))."""
    options = IdentifyOptions(methods=("wls",))
    exact = identify([_with_line(drift_capture)], guard, options).results["wls"]
    read = identify([load_run(drift_capture)], guard, options)
    taken = read.results["wls"]
    np.testing.assert_allclose(taken.theta, exact.theta, rtol=1e-9)  # the same line
    effects = {(guard.joints[s.joint].name, s.when): g
               for s, g in zip(read.current_zero.subtracted, read.current_zero.effects,
                               strict=True)}  # fmt: skip
    run = current_on_adc_levels(load_run(drift_capture), guard)
    extra = np.zeros_like(exact.std)
    for key, when in (("current_zero_before", "before"), ("current_zero", "after")):
        for j, e in getattr(run, key).items():
            moved = identify([_with_line(drift_capture, (j, when, 1e-4))], guard, options)
            per_amp = (moved.results["wls"].theta - exact.theta) / -1e-4
            # each end's reported effect: WLS's weights held, a few % of the largest
            scale = np.max(np.abs(per_amp) / exact.std)
            np.testing.assert_allclose(effects[j, when] / exact.std, per_amp / exact.std,
                                       rtol=0, atol=0.05 * scale)  # fmt: skip
            assert e.get("on_levels")  # an analog drift: the readings stay on the levels
            var = max(e["std_a"], 0.008) ** 2 / e["rows"]
            extra += per_amp**2 * var
    assert np.max(extra / exact.std**2) > 0.1  # a widening worth testing
    # WLS's weights, held in the reported effects, move with the zero too: a few %
    # (each variance within 15 % of its widening, or 1 % of itself)
    gap = np.abs(taken.std**2 - (exact.std**2 + extra))
    assert np.all(gap <= 0.15 * extra + 0.01 * exact.std**2), gap / extra


def test_an_approach_brings_the_robot_from_where_it_rests_to_the_first_setpoint(guard):
    """After the rest before the run the arm may have sunk onto its stop: the first leg is
    an approach from there (a quintic within half the joints' velocity and acceleration
    limits, then a hold at the first setpoint), then the run's rows as they were (the
    first row's feedforward during the approach); no approach when the robot rests
    there."""
    from guardid.capture.checks import counts_per_rad
    from guardid.capture.resume import HOLD_S, LIMIT_SHARE, start_rows
    from guardid.link.session import LazyRows

    rows = LazyRows(50, lambda a, b: np.array([[k, 2 * k, 7, 8] for k in range(a, b)]))
    same, lead = start_rows(rows, guard, (0, 0), (0, 0), (7, 8))
    assert same is rows and lead == 0
    now = (0, -1334)  # the tilt on its -10 deg stop
    moved, lead = start_rows(rows, guard, now, (0, 0), (7, 8))
    got = np.array([moved[k] for k in range(len(moved))])
    assert len(moved) == lead + 50
    assert got[0, :2].tolist() == list(now) and np.all(got[:lead, 2:] == [7, 8])
    hold = math.ceil(HOLD_S / guard.sample_period)
    assert np.all(got[lead - hold : lead, :2] == 0)  # held at the first setpoint
    np.testing.assert_array_equal(got[lead:], [[k, 2 * k, 7, 8] for k in range(50)])
    q = got[:lead, :2] / counts_per_rad(guard)
    v = np.diff(q, axis=0) / guard.sample_period
    a = np.diff(v, axis=0) / guard.sample_period
    vmax = np.array([j.limits.velocity for j in guard.joints])
    amax = np.array([j.limits.acceleration for j in guard.joints])
    assert np.all(np.abs(v).max(axis=0) <= LIMIT_SHARE * vmax * 1.05)  # rounding to counts
    assert np.all(np.abs(a).max(axis=0) <= LIMIT_SHARE * amax * 1.5)


def test_validate_follows_the_params_files_current_zero_unless_told(offset_captures, tmp_path):
    """validate takes the logs' zeros off as the first params file's identify did (its
    ``current_zero.mode``); --current-zero overrides it. Scored on the offset log, the
    model of the healthy one: the offset left in costs several times the error."""
    log = offset_captures["both"]
    score = {}
    for mode in ("subtract", "ignore"):
        params = tmp_path / f"{mode}.yaml"
        res = invoke("identify", offset_captures["healthy"], "--method", "wls",
                     "--current-zero", mode, "-o", params)  # fmt: skip
        assert res.exit_code == 0, res.output
        for told in (None, "subtract", "ignore"):
            extra = () if told is None else ("--current-zero", told)
            res = invoke("validate", log, "--params", params, *extra)
            assert res.exit_code == 0, res.output
            score[mode, told] = float(re.search(r":WLS\s+([\d.]+)%", res.output).group(1))
            assert ("left in (--current-zero ignore)" in res.output) == ((told or mode) == "ignore")
    for mode in ("subtract", "ignore"):  # each params file: its own mode unless told
        assert score[mode, None] == score[mode, mode]
        assert score[mode, "ignore"] > 3 * score[mode, "subtract"]


def test_a_link_lost_during_the_run_keeps_the_zero_read_before_it(tmp_path, guard):
    """The port vanishes mid-run (no --reconnect): the rows so far and the zero read before
    the run stay in the log's footer."""
    from guardid.capture import capture
    from guardid.excitation.sines import SumOfSines
    from guardid.link import Session, open_port

    port = open_port("sim://guard?seed=2&disconnect_s=8&reconnect_s=3")
    session = Session(port)
    session.handshake()
    log = tmp_path / "run.csv"
    traj = SumOfSines([[0.3], [0.1]], [[0.2], [0.3]], [[0.0], [0.0]], [0.0, 0.2])
    with pytest.raises(LinkError, match="rows kept in"):
        capture(session, guard, traj, 10.0, log, {"robot": "guard"}, zero_rest_s=1.0,
                zero_before=True)  # fmt: skip
    port.close()
    footer = _footer(log)
    assert footer["ended"].startswith("link error")
    assert 0 < load_run(log).t.size < 10.0 / 0.015
    assert footer["current_zero_before"]["pan"]["rows"] == math.ceil(1.0 / 0.015)
    assert footer["current_zero_before"]["pan"]["t_s"] < 0
    assert "current_zero" not in footer


def test_the_line_between_two_zeros_worked_out_by_hand(guard):
    """Zeros read before (t = -3 s) and after (t = 63 s): at each row the current loses the
    straight line through them (at t = 0: z_b + (z_a - z_b) x 3 / 66); one joint read only
    after is a constant; one read only before is too."""
    t = np.arange(0, 4000) * 0.015
    current = np.column_stack([np.full(t.size, 0.1), np.full(t.size, -0.2)])
    before = {
        "pan": {"mean_a": 0.004, "std_a": 0.008, "rows": 400, "t_s": -3.0},
        "tilt": {"mean_a": -0.002, "std_a": 0.008, "rows": 400, "t_s": -3.0},
    }
    after = {"pan": {"mean_a": 0.010, "std_a": 0.008, "rows": 400, "t_s": 63.0}}
    run = Run("a.csv", "guard", np.arange(t.size), t, np.zeros((t.size, 2)), current, None,
              current_zero=after, current_zero_before=before)  # fmt: skip
    (out,), read = subtract_zeros([run], guard, "subtract")
    line = 0.004 + (0.010 - 0.004) * (t + 3.0) / 66.0
    np.testing.assert_allclose(out.current[:, 0], 0.1 - line, rtol=0, atol=1e-15)
    np.testing.assert_allclose(out.current[:, 1], -0.2 + 0.002, rtol=0, atol=1e-15)
    assert [(s.joint, s.when, s.share is not None) for s in read.taken] == [
        (0, "before", True),
        (0, "after", True),
        (1, "before", False),
    ]
    # (0.49 mA: 8 mA / sqrt(400) and the whole mA's rounding, sqrt(0.4^2 + 1 / 12))
    assert "pan +4.00 +- 0.49 mA before, +10.00 +- 0.49 mA after; tilt -2.00" in read.lines[0]
    assert any("the pan current sensor's zero moved by +6.00 mA" in w for w in read.warnings)


def test_a_link_lost_during_the_rest_before_is_taken_up_by_a_reconnect(tmp_path, excitation):
    """The port vanishes during the rest before the run (the robot's 5th second of a 6 s
    rest) and comes back 3 s later: with --reconnect the run goes on from the trajectory's
    start and completes; the zero before is said not read, the zero after is read."""
    log = tmp_path / "rc.csv"
    res = invoke("capture", "--port", "sim://guard?seed=15&start=50&disconnect_s=5&reconnect_s=3",
                 "--trajectory", excitation("--no-optimise"), "--duration", 10,
                 "--reconnect", 5, "--zero-before", "--zero-rest", 6, "--quiet",
                 "-o", log)  # fmt: skip
    assert res.exit_code == 0, res.output
    footer = _footer(log)
    assert footer["ended"] == "complete" and footer["reconnects"] == 1
    assert load_run(log).t.size == math.ceil(10 / 0.015)
    assert footer["current_zero_before"]["not_measured"].startswith("link error")
    assert footer["current_zero"]["pan"]["rows"] == math.ceil(6 / 0.015)


@pytest.mark.parametrize(
    "before_t, after_t, field",
    [
        (-3.0, None, "current_zero: pan: t_s: missing"),
        (None, 63.0, "current_zero_before: pan: t_s: missing"),
        (1.0, 63.0, "current_zero_before: pan: t_s: 1.0 is not before the run's first row"),
        (-3.0, 30.0, "current_zero: pan: t_s: 30.0 is not after the run's last row"),
        (-3.0, -5.0, "current_zero: pan: t_s: -5.0 is not after the run's last row"),
    ],
)
def test_two_zeros_whose_times_cannot_be_theirs_are_one_line_naming_the_field(
    guard, before_t, after_t, field
):
    """A 60 s run's rows span 0 .. 59.985 s: the zero before must be read at or before the
    first row, the one after at or after the last, both with a time or neither."""
    t = np.arange(0, 4000) * 0.015

    def entry(t_s):
        e = {"mean_a": 0.001, "std_a": 0.008, "rows": 400}
        return e if t_s is None else {**e, "t_s": t_s}

    run = Run("a.csv", "guard", np.arange(t.size), t, np.zeros((t.size, 2)),
              np.zeros((t.size, 2)), None, current_zero={"pan": entry(after_t)},
              current_zero_before={"pan": entry(before_t)})  # fmt: skip
    with pytest.raises(LogFormatError, match=f"^a.csv: footer: {re.escape(field)}"):
        subtract_zeros([run], guard, "subtract")


def test_a_drift_alone_is_not_a_sensor_whose_zero_is_off(guard):
    """Zero at 0 before the run, 6 mA after: the drift is warned of, not an off zero (of
    two ends the one nearer 0 decides); 16 mA before and 6 mA after: both ends off, the
    sensor's zero is off."""
    t = np.arange(0, 4000) * 0.015
    for before, off in ((0.0, False), (0.016, True)):
        run = Run("a.csv", "guard", np.arange(t.size), t, np.zeros((t.size, 2)),
                  np.zeros((t.size, 2)), None,
                  current_zero={"pan": {"mean_a": 0.006, "std_a": 0.008, "rows": 400,
                                        "t_s": 63.0}},
                  current_zero_before={"pan": {"mean_a": before, "std_a": 0.008, "rows": 400,
                                               "t_s": -3.0}})  # fmt: skip
        _, read = subtract_zeros([run], guard, "subtract")
        assert any("the pan current sensor's zero moved by" in w for w in read.warnings)
        assert any("its zero is off" in w for w in read.warnings) == off


@pytest.mark.parametrize(
    "stored, field",
    [("weird", "current_zero: expected a mapping"), ({"mode": "maybe"}, "current_zero: mode")],
)
def test_validate_names_a_params_files_malformed_current_zero(offset_captures, tmp_path,
                                                              stored, field):  # fmt: skip
    from badinput_tools import ERROR_PREFIX

    params = tmp_path / "p.yaml"
    res = invoke("identify", offset_captures["healthy"], "--method", "wls", "-o", params)
    assert res.exit_code == 0, res.output
    data = yaml.safe_load(params.read_text())
    data["current_zero"] = stored
    params.write_text(yaml.safe_dump(data))
    res = invoke("validate", offset_captures["healthy"], "--params", params)
    lines = res.stderr.strip().splitlines()
    assert res.exit_code == 2 and len(lines) == 1 and lines[0].startswith(ERROR_PREFIX), res.stderr
    assert f"p.yaml: {field}" in lines[0]
    res = invoke(
        "validate", offset_captures["healthy"], "--params", params, "--current-zero", "ignore"
    )  # told: the file's mode is not needed
    assert res.exit_code == 0, res.output


def test_zero_before_without_a_rest_is_refused_before_anything_moves(tmp_path, excitation):
    log = tmp_path / "x.csv"
    res = invoke("capture", "--trajectory", excitation("--no-optimise"), "--duration", 5,
                 "--zero-before", "--zero-rest", 0, "-o", log)  # fmt: skip
    assert res.exit_code == 2 and "--zero-rest 0" in res.stderr and not log.exists()


def test_the_approach_carries_the_first_rows_feedforward(guard):
    """capture --feedforward --zero-before: the approach's rows hold the first row's
    feedforward voltages (what holds the arm at the trajectory's start), not 0 mV; a link
    lost as the approach is planned leaves the rows for the reconnect to take up."""
    from guardid.capture.run import _Legs
    from guardid.link.session import LazyRows

    first = [[0, 0, 150, 2400]]  # counts, then feedforward [mV]
    rows = LazyRows(30, lambda a, b: np.array(first * (b - a)))
    legs = _Legs(rows, counted=False)
    legs.approach(_Session([((0, -1334), (0, 0))]), guard, feedforward=True)
    assert legs.lead == legs.start_approach > 0
    assert legs.rows[0][:2] == [0, -1334] and legs.rows[0][2:] == [150, 2400]
    lost = _Legs(rows, counted=False)
    lost.approach(_Session([], fail_at=0), guard, feedforward=True)
    assert lost.rows is rows and lost.lead == 0


@pytest.mark.parametrize("how", ["disk full", "a bug in a caller's per-row work"])
def test_the_zero_read_before_the_run_stays_in_the_footer_whatever_ends_it(
    tmp_path, guard, monkeypatch, how
):
    """A disk that fills at the 37th row (space back for the footer), or any other error
    mid-run: the footer written after the robot was put idle keeps the zero read before."""
    from test_capture_outputs import DiskFull

    from guardid.capture import capture
    from guardid.excitation.sines import SumOfSines
    from guardid.link import Session, open_port
    from guardid.log import LogWriteError, LogWriter

    on_row, error = None, LogWriteError
    if how == "disk full":
        monkeypatch.setattr(LogWriter, "_write", staticmethod(DiskFull(37, heals=True)))
    else:
        error = ZeroDivisionError

        def on_row(t, *_):
            if t > 0.5:
                raise ZeroDivisionError("a caller's bug")

    port = open_port("sim://guard?seed=3")
    session = Session(port)
    session.handshake()
    log = tmp_path / "run.csv"
    traj = SumOfSines([[0.3], [0.1]], [[0.2], [0.3]], [[0.0], [0.0]], [0.0, 0.2])
    with pytest.raises(error):
        capture(session, guard, traj, 10.0, log, {"robot": "guard"}, on_row=on_row,
                zero_rest_s=1.0, zero_before=True)  # fmt: skip
    port.close()
    footer = _footer(log)
    assert footer["ended"].startswith(("log write error", "error: ZeroDivisionError"))
    assert footer["current_zero_before"]["tilt"]["rows"] == math.ceil(1.0 / 0.015)


def test_a_zero_not_read_at_one_rest_says_what_was_done_with_the_other(guard):
    """The zero before the run not read, the one after read: subtracted, the one after is
    taken off as a constant; under --current-zero ignore the warning says it is left in."""
    after = {"pan": {"mean_a": 0.001, "std_a": 0.008, "rows": 400}}
    run = dataclasses.replace(_run(after), current_zero_before={"not_measured": "link error: x"})
    for mode, said in (
        ("subtract", "the one read after it is taken off as a constant"),
        ("ignore", "the one read after it is left in (--current-zero ignore)"),
    ):
        _, read = subtract_zeros([run], guard, mode)
        (line,) = [w for w in read.warnings if "was not read before the run" in w]
        assert said in line, line
