"""Rows lost without a gap in the ticks (a log cut by hand, its ticks renumbered) split the
run at the jump they leave, as a long gap does, and every command says so.

Truth: the reach of guard.yaml's drives worked out by hand (no-load speed, gravity's
back-drive from the arm's mass and lever), steps placed at known fractions of it, the step
and its time read from the log's text with numpy, and the robot YAML's values of the
motor constants and base parameters (the simulator runs the YAML).
"""

from __future__ import annotations

import math
import re

import numpy as np
import pytest
import yaml
from badinput_tools import invoke
from logedit import column, spliced

from guardid.identify.jumps import JUMP_MARGIN, drive_reach, find_jumps
from guardid.identify.runs import Run, load_run
from guardid.robot import load_robot

PERIOD = 0.015  # guard's tick [s]
# guard.yaml by hand: pan no-load 12 V / (0.02 V s/rad x 500) = 1.2 rad/s, no gravity about
# its vertical axis; tilt: the arm's 3.5 kg at |(0.10 + 0.12, 0.02)| = 0.22091 m from the
# horizontal tilt axis, 7.5850 N m at most (at q2 = -5.2 deg, inside the limits), driving
# 8 ohm x 7.5850 / (0.7 x 0.02 x 1000) = 4.3343 V of back-EMF: (12 + 4.3343) / 20 rad/s
GRAVITY_TILT = 3.5 * 9.81 * math.hypot(0.22, 0.02)
BACK_TILT = 8.0 * GRAVITY_TILT / (0.7 * 0.02 * 1000)
SPEED = np.array([12.0 / 10.0, (12.0 + BACK_TILT) / 20.0])  # [rad/s]
COUNT = 2 * math.pi / np.array([48 * 500, 48 * 1000])  # one encoder count [rad]
THRESHOLD = 2 * SPEED * PERIOD + COUNT  # a one-tick step beyond this is a jump [rad]


@pytest.fixture(scope="module")
def guard():
    return load_robot("guard")


def test_the_guards_reach_worked_out_by_hand(guard):
    reach = drive_reach(guard)
    assert reach.names == ("pan", "tilt")
    assert reach.back_drive_v[0] == pytest.approx(0.0, abs=1e-9)
    assert reach.back_drive_v[1] == pytest.approx(BACK_TILT, rel=1e-3)
    np.testing.assert_allclose(reach.speeds(), SPEED, rtol=1e-3)
    np.testing.assert_allclose(reach.count, COUNT, rtol=1e-12)
    assert JUMP_MARGIN == 2.0  # THRESHOLD's factor


def _still_run(step: float, joint: int = 1, volts: float = 0.0, torque=False, skip=0) -> Run:
    """1000 rows of a joint at rest, one step of ``step`` [rad] on ``joint`` between rows
    499 and 500 (``skip`` ticks lost between them), ``volts`` on every row."""
    ticks = np.arange(1000) + np.where(np.arange(1000) >= 500, skip, 0)
    q = np.zeros((1000, 2))
    q[500:, joint] = step
    voltage = np.full((1000, 2), volts)
    return Run("still.csv", "guard", ticks, ticks * PERIOD, q, np.zeros((1000, 2)), voltage,
               torque=torque)  # fmt: skip


@pytest.mark.parametrize("joint", [0, 1])
def test_a_step_beyond_the_reach_is_a_jump_and_one_within_it_is_not(guard, joint):
    reach = drive_reach(guard)
    assert find_jumps(_still_run(0.97 * THRESHOLD[joint], joint), reach, PERIOD) == []
    (jump,) = find_jumps(_still_run(1.03 * THRESHOLD[joint], joint), reach, PERIOD)
    assert jump.index == 500 and jump.joint == ("pan", "tilt")[joint]
    assert jump.at_s == pytest.approx(499 * PERIOD)
    assert jump.step == pytest.approx(1.03 * THRESHOLD[joint])
    assert jump.limit == pytest.approx(THRESHOLD[joint], rel=1e-3)


def test_the_logs_own_voltage_above_the_supply_widens_the_reach(guard):
    """At 14.9 V (either sign) on the tilt's column its no-load speed is 14.9 / 20 rad/s: a
    step of 1.03 times the 12 V threshold is within (14.9 + 4.3343) / 20 x 2 T + one count.
    NaN readings are passed over; a reading beyond the sensor's 15 V range is no voltage the
    drive gave, and a column of nothing else leaves the supply's reach."""
    reach = drive_reach(guard)
    step = 1.03 * THRESHOLD[1]
    assert step < 2 * (14.9 + BACK_TILT) / 20.0 * PERIOD + COUNT[1]
    assert find_jumps(_still_run(step, volts=14.9), reach, PERIOD) == []
    assert find_jumps(_still_run(step, volts=-14.9), reach, PERIOD) == []
    run = _still_run(step, volts=-14.9)
    run.voltage[::3] = np.nan
    assert find_jumps(run, reach, PERIOD) == []
    assert len(find_jumps(_still_run(step, volts=11.0), reach, PERIOD)) == 1  # the supply's
    assert len(find_jumps(_still_run(step, volts=1e6), reach, PERIOD)) == 1  # beyond 15 V
    assert len(find_jumps(_still_run(step, volts=np.nan), reach, PERIOD)) == 1


def test_a_joint_without_a_drive_is_not_checked(guard):
    """The tilt described as torque-driven (``drive: null``, no encoder): any step of its is
    no jump, the pan's are checked as before."""
    from dataclasses import replace

    tilt = replace(guard.joints[1], drive=None, encoder=None)
    reach = drive_reach(replace(guard, joints=(guard.joints[0], tilt)))
    assert reach.speeds()[1] == np.inf
    assert find_jumps(_still_run(100 * THRESHOLD[1], joint=1), reach, PERIOD) == []
    assert len(find_jumps(_still_run(1.03 * THRESHOLD[0], joint=0), reach, PERIOD)) == 1


def test_gravity_of_either_sign_and_an_unlimited_joint_count(guard):
    """The arm's COM mirrored through the tilt axis (x 0.12 -> -0.32 m: the same 0.22091 m
    lever on the other side) turns gravity's torque negative over the whole travel: the same
    back-drive. Without position limits the tilt's poses span the circle: the same peak."""
    from dataclasses import replace

    arm = guard.links[1]
    mirrored = replace(arm, com=np.array([-0.32, 0.02, 0.0]))
    reach = drive_reach(replace(guard, links=(guard.links[0], mirrored)))
    assert reach.back_drive_v[1] == pytest.approx(BACK_TILT, rel=1e-3)
    tilt = guard.joints[1]
    free = replace(tilt, limits=replace(tilt.limits, position=None))
    reach = drive_reach(replace(guard, joints=(guard.joints[0], free)))
    assert reach.back_drive_v[1] == pytest.approx(BACK_TILT, rel=2e-3)


def test_a_foreign_run_off_the_tick_grid_is_not_checked(guard):
    """A foreign log's host times may come in bursts: without ticks nothing is checked."""
    from dataclasses import replace

    run = replace(_still_run(100 * THRESHOLD[1]), ticks=None)
    assert find_jumps(run, drive_reach(guard), PERIOD) == []


def test_rows_further_apart_may_step_further(guard):
    """Across one lost tick the rows are 2 T apart: the reach doubles (less one count)."""
    reach = drive_reach(guard)
    assert find_jumps(_still_run(1.03 * THRESHOLD[1], skip=1), reach, PERIOD) == []
    assert len(find_jumps(_still_run(2.06 * THRESHOLD[1], skip=1), reach, PERIOD)) == 1


def test_no_reach_without_a_drive_and_no_jump_in_a_torque_log(guard):
    assert drive_reach(load_robot("dfki_double_pendulum")) is None  # torque-driven joints
    assert drive_reach(load_robot("flexlink")) is None  # the flexible link: no joints
    run = _still_run(100 * THRESHOLD[1], torque=True)
    assert find_jumps(run, drive_reach(guard), PERIOD) == []
    assert find_jumps(_still_run(100 * THRESHOLD[1]), None, PERIOD) == []


def test_honest_captures_step_well_inside_the_reach(
    gap_guard_captures, far_start_capture, variant_schroeder_300s
):
    """No jump on the suite's intact captures, the far start's saturated PID among them:
    their largest step is less than half of the threshold (numpy on the log's columns)."""
    for path in [*gap_guard_captures.values(), far_start_capture, variant_schroeder_300s]:
        run = load_run(path)
        reach = drive_reach(load_robot(_robot_source(path)))
        assert find_jumps(run, reach, run.sample_period_s) == [], path
        threshold = 2 * reach.speeds(run.voltage) * run.sample_period_s + reach.count
        assert np.max(np.abs(np.diff(run.q, axis=0)) / threshold) < 0.5, path


def _robot_source(path) -> str:
    head = path.read_text()[:4000]
    found = re.search(r"^# robot_source: (.+)$", head, re.M)
    return found.group(1).strip() if found else re.search(r"^# robot: (.+)$", head, re.M).group(1)


def _one_tick_step(text: str, start: int, count: int) -> np.ndarray:
    """|q after the cut - q before it| per joint [rad], from the log's own columns."""
    q = np.array([column(text, "q_pan_rad"), column(text, "q_tilt_rad")]).T
    return np.abs(q[start + count] - q[start - 1])


def _offsets(params_path) -> tuple[dict, dict]:
    """({parameter: (value - YAML) / std} of WLS, {joint: (Ke - YAML Ke) / std})."""
    data = yaml.safe_load(params_path.read_text())
    wls = data["methods"]["wls"]
    base = {p["name"]: (v - p["yaml_value"]) / s for p, v, s in
            zip(data["base_parameters"], wls["values"], wls["std"], strict=True)}  # fmt: skip
    return base, data


def test_a_spliced_guard_log_is_split_at_the_jump_not_refused(gap_guard_captures, tmp_path):
    """200 rows cut out of a 60 s guard capture, its ticks renumbered: before, identify
    refused it as swapped columns (both motors' Ke 5 to 16 times too small); now the run is
    split at the jump, named on one line, and the estimate keeps the truth within 3 std."""
    text = gap_guard_captures[1].read_text()
    start, count = 2000, 200
    step = _one_tick_step(text, start, count)
    assert step[0] > 3 * THRESHOLD[0]  # the pan's step: a jump by the hand threshold
    log = tmp_path / "spliced.csv"
    log.write_text(spliced(text, start, count))
    out = tmp_path / "p.yaml"
    res = invoke("identify", log, "--method", "wls", "-o", out)
    assert res.exit_code == 0, res.stderr
    jump = r"jump after ([0-9.]+) s: (\w+) moved ([0-9.]+) between two rows"
    found = re.findall(jump, res.stderr)
    assert len(found) == 1, res.stderr
    at, joint, moved = found[0]
    assert float(at) == pytest.approx(column(text, "time_s")[start - 1], abs=1e-3)
    assert joint == "pan" and float(moved) == pytest.approx(step[0], rel=1e-2)
    base, _ = _offsets(out)
    assert max(abs(x) for x in base.values()) < 3.0, base


def test_a_spliced_variant_log_keeps_its_motors_constants(variant_schroeder_300s, tmp_path):
    """2337 rows cut out of a 300 s variant capture and its ticks renumbered: before, exit 0
    with the tilt motor's Ke far off its YAML value (60 std on another seed); now split at
    the jump, every Ke within 4 std of the YAML's 0.025 V s/rad."""
    text = variant_schroeder_300s.read_text()
    start, count = 12000, 2337
    variant = load_robot(_robot_source(variant_schroeder_300s))
    threshold = 2 * drive_reach(variant).speeds() * 0.01 + drive_reach(variant).count
    assert np.max(_one_tick_step(text, start, count) / threshold) > 1.5
    log = tmp_path / "spliced.csv"
    log.write_text(spliced(text, start, count))
    out = tmp_path / "p.yaml"
    res = invoke("identify", log, "--robot", _robot_source(variant_schroeder_300s),
                 "--method", "wls", "-o", out)  # fmt: skip
    assert res.exit_code == 0, res.stderr
    assert len(re.findall(r"spliced\.csv: jump after", res.stderr)) == 1, res.stderr
    motors = {m: re.search(rf"motor {m}: R [0-9.]+ \+- [0-9.e-]+ ohm, Ke ([0-9.]+) \+- ([0-9.e-]+)",
                           res.stdout) for m in ("pan", "tilt")}  # fmt: skip
    for m, found in motors.items():
        ke, std = float(found.group(1)), float(found.group(2))
        assert abs(ke - 0.025) < 4 * std, (m, ke, std)


def test_validate_scores_each_side_of_a_jump(gap_guard_captures, tmp_path):
    text = gap_guard_captures[1].read_text()
    log = tmp_path / "spliced.csv"
    log.write_text(spliced(text, 2000, 200))
    params = tmp_path / "p.yaml"
    assert invoke("identify", gap_guard_captures[2], "--method", "ls", "-o", params).exit_code == 0
    res = invoke("validate", log, "--params", params)
    assert res.exit_code == 0, res.stderr
    assert f"run {log}[1] (" in res.stdout and f"run {log}[2] (" in res.stdout
    assert "jump after" in res.stdout


def test_a_step_of_less_than_one_count_is_never_a_jump(guard):
    """With the pan's supply at 10 mV its drive reaches 1e-3 rad/s, 3e-5 rad in two ticks;
    the encoder's rounding alone can show one count, 2.6e-4 rad, in any step."""
    from dataclasses import replace

    pan = guard.joints[0]
    weak = replace(pan, drive=replace(pan.drive, supply_voltage=0.01))
    reach = drive_reach(replace(guard, joints=(weak, guard.joints[1])))
    assert find_jumps(_still_run(0.9 * COUNT[0], joint=0), reach, PERIOD) == []
    assert len(find_jumps(_still_run(1.2 * COUNT[0], joint=0), reach, PERIOD)) == 1


def test_cross_validation_holds_out_both_sides_of_a_jump_as_one_fold(gap_guard_captures, tmp_path):
    log = tmp_path / "spliced.csv"
    log.write_text(spliced(gap_guard_captures[1].read_text(), 2000, 200))
    res = invoke("identify", log, gap_guard_captures[2], "--method", "ls", "--cv",
                 "--cutoff", "4")  # fmt: skip
    assert res.exit_code == 0, res.stderr
    rows = [line.split()[0] for line in res.stdout.splitlines() if line.endswith("%")]
    assert rows == [str(log), str(gap_guard_captures[2]), "mean"], res.stdout
    assert "spliced.csv: jump after" in res.stdout, res.stdout


def test_the_tracker_restarts_at_a_jump_instead_of_reporting_a_change(gap_guard_captures, tmp_path):
    """Replayed across the jump, the RLS tracker reported five payload changes from 29.9 s
    on; restarted there, none (the simulated robot's payload never changes)."""
    log = tmp_path / "spliced.csv"
    log.write_text(spliced(gap_guard_captures[1].read_text(), 2000, 200))
    res = invoke("identify", log, "--method", "wls,rls")
    assert res.exit_code == 0, res.stderr
    assert "its causal filter restarted after each of 1 jumps" in res.stdout, res.stdout
    assert "no parameter change detected" in res.stdout, res.stdout
