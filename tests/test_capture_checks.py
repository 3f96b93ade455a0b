"""Nothing moves before it is checked: the trajectory against the robot description
(joint count; position, velocity, acceleration limits on the 1 ms grid of excite) and
the robot's INFO against the same description."""

from __future__ import annotations

import math
from pathlib import Path

import pytest
import yaml
from capturetools import IDLE, Witness, gentle_trajectory, witnessed
from click.testing import CliRunner

from guardid.capture.checks import NEEDED_CAPABILITIES, check_info
from guardid.cli import main
from guardid.errors import ConfigError
from guardid.excitation import limit_usage
from guardid.excitation.limits import first_violation
from guardid.excitation.sines import SumOfSines
from guardid.fakeport import register_device_factory
from guardid.firmware import FirmwareEmulator
from guardid.plant import make_plant
from guardid.protocol import ENUMS, MESSAGES, PROTOCOL_VERSION
from guardid.robot import load_robot

GUARD = load_robot("guard")
TILT_HI = 0.6108652381980153  # rad, guard.yaml: +35 deg
PAN_VEL = 0.9  # rad/s, guard.yaml


def test_first_violation_of_position_worked_by_hand():
    """tilt = 0.2 + 0.5 sin(2 pi 0.05 t) passes +35 deg when sin(w t) = (hi - 0.2) / 0.5,
    t* = asin(0.82173) / (0.1 pi) = 3.0685 s; velocity 0.157 rad/s and acceleration
    0.049 rad/s^2 stay far inside; pan stands still."""
    traj = SumOfSines([[0.0], [0.5]], [[0.05], [0.05]], [[0.0], [0.0]], [0.0, 0.2])
    bad = first_violation(traj, GUARD)
    t_star = math.asin((TILT_HI - 0.2) / 0.5) / (2 * math.pi * 0.05)
    assert (bad.joint, bad.kind, bad.limit) == ("tilt", "position", TILT_HI)
    assert t_star <= bad.time_s <= t_star + 1e-3  # the first 1 ms grid point past t*
    assert TILT_HI < bad.value < TILT_HI + 0.5 * 0.1 * math.pi * 1e-3 + 1e-12
    assert "joint tilt" in bad.describe() and "35.0 deg" in bad.describe()


def test_first_violation_of_velocity_worked_by_hand():
    """pan = 0.5 sin(2 t - pi/2): qd = 1.0 sin(2 t) [rad/s] crosses 0.9 at
    t* = asin(0.9) / 2 = 0.5599 s; qdd peaks at 2.0 < 3 rad/s^2."""
    f = 2.0 / (2 * math.pi)
    traj = SumOfSines([[0.5], [0.0]], [[f], [f]], [[-math.pi / 2], [0.0]], [0.0, 0.2])
    bad = first_violation(traj, GUARD)
    t_star = math.asin(0.9) / 2
    assert (bad.joint, bad.kind, bad.limit) == ("pan", "velocity", PAN_VEL)
    assert t_star <= bad.time_s <= t_star + 1e-3
    assert "51.6 deg/s" in bad.describe()  # 0.9 rad/s


def _pan_velocity_negative_first() -> SumOfSines:
    """pan = 0.5 sin(2 t + pi/2): qd = cos(2 t + pi/2) = -1.0 sin(2 t) [rad/s] reaches
    -0.9 first, at t* = asin(0.9) / 2 = 0.5599 s, and +0.9 only at (pi + asin(0.9)) / 2 =
    2.1307 s; qdd peaks at 2.0 < 3 rad/s^2; pan has no position limit; tilt stands still."""
    f = 2.0 / (2 * math.pi)
    return SumOfSines([[0.5], [0.0]], [[f], [f]], [[math.pi / 2], [0.0]], [0.0, 0.2])


def test_first_violation_of_velocity_on_the_negative_side_worked_by_hand():
    """Promise: the velocity limit binds both ways, so the first crossing is the negative
    one at t* = asin(0.9) / 2 = 0.5599 s, reported with its sign."""
    bad = first_violation(_pan_velocity_negative_first(), GUARD)
    t_star = math.asin(0.9) / 2
    assert (bad.joint, bad.kind, bad.limit) == ("pan", "velocity", -PAN_VEL)
    assert t_star <= bad.time_s <= t_star + 1e-3  # the first 1 ms grid point past t*
    # |qdd| <= 2 rad/s^2, so one 1 ms step goes at most 2e-3 rad/s past -0.9
    assert -PAN_VEL - 2e-3 - 1e-12 < bad.value < -PAN_VEL
    assert "velocity -51.6 deg/s at t = 0.560 s" in bad.describe()


def test_first_violation_agrees_with_excites_limit_report(tmp_path):
    traj = SumOfSines.load(gentle_trajectory(tmp_path / "t.yaml"))
    assert first_violation(traj, GUARD) is None and all(u.within for u in limit_usage(traj, GUARD))
    for k in (1.8, 2.5, 10.0):  # acceleration, velocity, then position limits pass
        big = traj.scaled([k, k])
        assert (first_violation(big, GUARD) is None) == all(
            u.within for u in limit_usage(big, GUARD)
        )


def _capture(traj, *extra, port="/dev/ttyNOPE0"):
    """A capture whose port does not exist: a refusal about the trajectory proves the
    check ran before the port was opened."""
    args = ["capture", "--trajectory", str(traj), "--duration", "2", "--port", port,
            "-o", str(Path(traj).with_suffix(".csv")), "--quiet", *extra]  # fmt: skip
    with witnessed() as robots:
        res = CliRunner().invoke(main, args)
    return res, robots


def _error(res) -> str:
    assert res.exit_code == 2, res.output
    assert res.exception is None or isinstance(res.exception, SystemExit), res.exception
    (line,) = [x for x in res.output.splitlines() if x.strip()]
    assert line.startswith("guardid: error: ")
    return line


def test_a_trajectory_ten_times_too_large_is_refused_before_anything_opens(tmp_path):
    traj = tmp_path / "big.yaml"
    SumOfSines.load(gentle_trajectory(tmp_path / "t.yaml")).scaled([10, 10]).save(traj)
    for port in ("/dev/ttyNOPE0", "sim://guard"):
        res, robots = _capture(traj, port=port)
        line = _error(res)
        assert "big.yaml: joint " in line and " at t = " in line and "beyond its limit" in line
        assert "nothing moved" in line
        assert robots == [] and not traj.with_suffix(".csv").exists()


def test_a_trajectory_over_the_velocity_limit_backwards_is_refused(tmp_path):
    """Promise: a 2 s capture whose pan speed passes -0.9 rad/s at 0.560 s (and +0.9 only
    after 2.13 s, beyond the capture) is refused before the port opens: nothing moves."""
    traj = tmp_path / "back.yaml"
    _pan_velocity_negative_first().save(traj)
    res, robots = _capture(traj, port="sim://guard")
    line = _error(res)
    assert "back.yaml: joint pan: velocity -51.6 deg/s at t = 0.560 s" in line, line
    assert "nothing moved" in line
    assert robots == [] and not traj.with_suffix(".csv").exists()


@pytest.mark.parametrize("n", [1, 3])
def test_a_trajectory_with_the_wrong_joint_count_is_refused(tmp_path, n):
    traj = tmp_path / f"j{n}.yaml"
    SumOfSines([[0.1]] * n, [[0.1]] * n, [[0.0]] * n, [0.1] * n).save(traj)
    res, robots = _capture(traj, port="sim://guard")
    line = _error(res)
    assert f"has {n} joint" in line and "guard has 2 (pan, tilt)" in line
    assert robots == [] and not traj.with_suffix(".csv").exists()


# ------------------------------------------------------------------ INFO against the YAML
def _guard_variant(tmp_path, edit) -> Path:
    data = yaml.safe_load(Path(GUARD.source).read_text())
    edit(data)
    path = tmp_path / "variant.yaml"
    path.write_text(yaml.safe_dump(data, sort_keys=False))
    return path


def _set_tilt_cpr(d):
    d["joints"][1]["encoder"]["counts_per_rev"] = 64


def _set_period(d):
    d["sample_period"] = 0.01


@pytest.mark.parametrize(
    "edit,words",
    [
        (_set_tilt_cpr, ["joint tilt", "64000", "48000", "encoder counts"]),
        (_set_period, ["sample_period 10 ms", "tick period of 15 ms"]),
    ],
)
def test_a_robot_whose_info_disagrees_with_the_yaml_is_not_moved(tmp_path, edit, words):
    """The port simulates the shipped guard; capture is given a YAML that differs."""
    robot = _guard_variant(tmp_path, edit)
    traj = gentle_trajectory(tmp_path / "t.yaml")
    res, robots = _capture(traj, "--robot", str(robot), port="sim://guard")
    line = _error(res)
    for w in words:
        assert w in line, (w, line)
    assert "sim://guard" in line
    (w,) = robots
    moved = [c for c in w.commands if c[0] in ("SETPOINT", "SET_PID", "START_STREAM")]
    assert moved == [] and all(c[1] == IDLE for c in w.commands if c[0] == "SET_MODE")
    assert w.moving_ticks == 0 and not traj.with_suffix(".csv").exists()


class ThreeJointInfo(FirmwareEmulator):
    """The guard emulator, but its INFO claims a third joint (a different robot)."""

    def _on_hello(self, frame) -> None:
        info = FirmwareEmulator._on_hello(self, frame)  # queue the true INFO ...
        self._out.clear()  # ... and replace it
        caps = sum(1 << ENUMS["capability"][c] for c in NEEDED_CAPABILITIES)
        self._send(MESSAGES["INFO"](PROTOCOL_VERSION, 3, caps, 1, self.tick_us, 250, 8,
                                    (*self.cpr, 1000)))  # fmt: skip
        return info

    _HANDLERS = {**FirmwareEmulator._HANDLERS, "Hello": _on_hello}


def test_a_robot_with_more_joints_than_the_yaml_is_not_moved(tmp_path):
    made = []

    def factory(robot, options):
        fw = ThreeJointInfo(GUARD, make_plant(GUARD, options))
        made.append(Witness(fw))
        return made[-1]

    traj = gentle_trajectory(tmp_path / "t.yaml")
    old = register_device_factory(factory)
    try:
        res = CliRunner().invoke(
            main, ["capture", "--trajectory", str(traj), "--duration", "2", "--port",
                   "sim://guard", "-o", str(tmp_path / "t.csv"), "--quiet"],
        )  # fmt: skip
    finally:
        register_device_factory(old)
    line = _error(res)
    assert "describes 2 joints" in line and "sim://guard reports 3" in line
    (w,) = made
    assert w.moving_ticks == 0 and not (tmp_path / "t.csv").exists()


def test_info_without_the_needed_capabilities_is_refused():
    info = {"joint_count": 2, "counts_per_rev": (24000, 48000), "tick_period": 0.015}
    check_info({**info, "capabilities": 0b01111}, GUARD, "sim://guard")  # all four: fine
    with pytest.raises(ConfigError, match="lacks setpoint_buffer, watchdog"):
        check_info({**info, "capabilities": 0b00011}, GUARD, "sim://guard")


def test_a_sums_of_sines_capture_without_duration_runs_one_period(tmp_path):
    """No --duration: one period of the trajectory, 10 s for gentle_trajectory's 0.2 and 0.3
    Hz (worked out by hand: their common period 1 / 0.1 Hz), written in the log's header as
    a plain number (numpy's float64 made the header's YAML fail with a traceback)."""
    from guardid.excitation.sines import common_period
    from guardid.log import read_log

    assert type(common_period([0.2, 0.3])) is float and common_period([0.2, 0.3]) == pytest.approx(
        10.0
    )
    traj = gentle_trajectory(tmp_path / "t.yaml")
    log = tmp_path / "run.csv"
    res = CliRunner().invoke(main, ["capture", "--trajectory", str(traj), "--quiet", "-o",
                                    str(log)])  # fmt: skip
    assert res.exit_code == 0, res.output
    data = read_log(log)
    assert data.header["duration_s"] == pytest.approx(10.0)
    assert len(data.columns["tick"]) == pytest.approx(10.0 / 0.015, abs=2)
