"""guardid doctor: every simulated wiring fault found and named, none on a clean robot;
the moves' safety (limits checked first, motors idle on a runaway or fault); the host checks."""

from __future__ import annotations

import math
from contextlib import contextmanager

import numpy as np
import pytest
from badinput_tools import ERROR_PREFIX, invoke

from guardid.doctor import FAIL, OK, UNKNOWN, WARN, latency_check, run_checks
from guardid.doctor.bench import MovesStopped, pulse_plan
from guardid.doctor.checks import JointYaml, link_check
from guardid.fakeport import register_device_factory
from guardid.firmware.emulator import FirmwareEmulator, make_sim_device
from guardid.link import Session, open_port
from guardid.plant.variation import SupplyVariation
from guardid.robot import load_robot

GUARD = load_robot("guard")


def doctor_checks(query: str = ""):
    """run_checks on sim://guard?seed=1&QUERY; (checks, the emulated device after)."""
    port = open_port(f"sim://guard?seed=1{query}")
    try:
        session = Session(port)
        session.handshake()
        checks = run_checks(session, GUARD, latency_check(port.portstr))
        return checks, port.engine.device
    finally:
        port.close()


def failed(checks) -> set[tuple[str, str]]:
    return {(c.name, c.joint) for c in checks if c.verdict == FAIL}


FAULTS = {
    "encoder_reversed:tilt": {("encoder direction vs motor voltage", "tilt")},
    "motor_reversed:pan": {("encoder direction vs motor voltage", "pan")},
    "current_offset:pan=0.1": {("current offset at rest", "pan")},
    "current_gain:tilt=0.5": {("current sign under load", "tilt")},
    "current_gain:pan=-1": {("current sign under load", "pan")},
    "cpr:pan=96": {("counts per revolution", "pan")},
    "stuck:tilt": {("encoder counts under voltage", "tilt")},
    "stuck:pan": {("encoder counts under voltage", "pan")},
}


@pytest.mark.parametrize("wiring", sorted(FAULTS))
def test_each_wiring_fault_is_found_and_named_alone(wiring):
    checks, device = doctor_checks(f"&wiring={wiring}")
    assert failed(checks) == FAULTS[wiring]
    assert device.mode == 0 and not device.streaming  # left idle


@pytest.mark.parametrize("firmware", ["py", "c", "avr"])
def test_clean_robot_has_no_false_alarm(firmware):
    checks, device = doctor_checks(f"&firmware={firmware}")
    verdicts = {(c.name, c.joint): c.verdict for c in checks}
    assert failed(checks) == set()
    assert verdicts[("USB latency timer", "")] == UNKNOWN  # a URL
    assert all(v == OK for k, v in verdicts.items() if k[0] != "USB latency timer")
    assert len(checks) == 13


@pytest.mark.parametrize("firmware", ["c", "avr"])
def test_faults_found_with_the_c_and_avr_firmware(firmware):
    wiring = "encoder_reversed:tilt,motor_reversed:pan,current_offset:pan=0.1,cpr:pan=96"
    checks, _ = doctor_checks(f"&firmware={firmware}&wiring={wiring}")
    assert failed(checks) == {
        ("encoder direction vs motor voltage", "tilt"),
        ("encoder direction vs motor voltage", "pan"),
        ("current offset at rest", "pan"),
        ("counts per revolution", "pan"),
    }


def test_the_known_move_measures_the_counts_per_revolution():
    """cpr:pan=96 against the YAML's 48: the back-EMF says ~96 counts per motor rev."""
    checks, _ = doctor_checks("&wiring=cpr:pan=144")
    row = next(c for c in checks if c.name == "counts per revolution" and c.joint == "pan")
    cpr = float(row.measured.split()[0].lstrip("~"))
    assert abs(cpr - 144) < 0.05 * 144


def test_supply_measured_against_the_seeded_supply():
    """supply=0.4: the run's supply is 12 V x (1 + u), u from the seed's own stream."""
    for seed in range(20):  # a seed whose supply is more than 25 % off
        factor = next(SupplyVariation(0.4, 0.0).factors(seed))
        if abs(factor - 1) > 0.3:
            break
    port = open_port(f"sim://guard?seed={seed}&supply=0.4")
    try:
        session = Session(port)
        session.handshake()
        checks = run_checks(session, GUARD)
    finally:
        port.close()
    row = next(c for c in checks if c.name == "supply voltage")
    assert row.verdict == FAIL
    measured = float(row.measured.split()[0])
    assert abs(measured - 12.0 * factor) < 0.03 * 12.0 * factor


def test_cli_exit_code_and_table():
    res = invoke("doctor", "--port", "sim://guard?wiring=stuck:pan")
    assert res.exit_code == 1
    line = next(x for x in res.stdout.splitlines() if x.startswith("encoder counts under"))
    assert "pan" in line and "FAIL" in line
    assert "fix:" in res.stdout and "1 of" in res.stdout
    clean = invoke("doctor")
    assert clean.exit_code == 0, clean.stdout + clean.stderr
    assert "FAIL" not in clean.stdout


@pytest.mark.parametrize(
    "args, option",
    [
        (["doctor", "--port", "sim://guard?wiring=cpr:pan"], "wiring"),
        (["doctor", "--port", "sim://guard?wiring=flipped:pan"], "wiring"),
        (["doctor", "--port", "sim://guard?wiring=stuck:elbow"], "wiring"),
        (["doctor", "--port", "sim://guard?wiring=stuck:pan=1"], "wiring"),
        (["doctor", "--port", "sim://guard?wiring=current_gain:pan=0"], "wiring"),
        (["doctor", "--port", "sim://guard?wiring=cpr:pan=9.5"], "wiring"),
        (["doctor", "--port", "sim://guard?wiring=stuck:pan,stuck:pan"], "wiring"),
        (["doctor", "--port", "sim://guard?wiring=current_drift:pan=0.2"], "wiring"),
        (["doctor", "--port", "sim://guard?wiring=current_drift:pan"], "wiring"),
        (["fake-port", "--wiring", "motor_reversed"], "--wiring"),
    ],
)
def test_bad_wiring_is_one_line_naming_the_option(args, option):
    res = invoke(*args)
    assert res.exit_code == 2
    lines = res.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith(ERROR_PREFIX), res.stderr
    assert f"{option}=" in lines[0]


# ---------------------------------------------------------------- the simulated wiring
def _plants(wiring: str, seed: int = 3):
    """A clean plant and one behind ``wiring``, same seed."""
    from guardid.fakeport import parse_sim_url
    from guardid.plant import make_plant

    clean = make_plant(GUARD, parse_sim_url(f"sim://guard?seed={seed}"))
    wired = make_plant(GUARD, parse_sim_url(f"sim://guard?seed={seed}&wiring={wiring}"))
    return clean, wired


def test_wiring_against_the_clean_plant():
    """Each fault's signals, from a clean plant of the same seed driven by the same (or,
    motor_reversed, the opposite) voltage."""
    wiring = "encoder_reversed:tilt,current_offset:pan=0.1,current_gain:pan=0.5,cpr:pan=96"
    clean, wired = _plants(wiring)
    for k in range(40):
        u = [4.0, 7.0] if k < 20 else [-3.0, 0.0]
        a, b = clean.step(u), wired.step(u)
        assert b.counts[1] == -a.counts[1]
        assert b.counts[0] == math.floor(a.q[0] * 2 * clean.joints[0].counts_per_rad)
        assert b.current[0] == pytest.approx(0.5 * a.current[0] + 0.1, abs=1e-12)
        assert b.current[1] == a.current[1] and b.voltage == a.voltage
    clean, wired = _plants("motor_reversed:pan,stuck:tilt")
    for _ in range(30):
        a, b = clean.step([-5.0, 6.0]), wired.step([5.0, 6.0])
        assert b.counts[0] == a.counts[0]  # the motor turned against the board's voltage
        assert b.voltage[0] == -a.voltage[0] and b.current[0] == -a.current[0]
        assert b.counts[1] == 0 and a.q[1] != 0.0  # the tilt moves, its counts do not
    counts, volts, amps = wired.step_sensors([1.0, 1.0])
    a = clean.step([-1.0, 1.0])
    assert counts == [a.counts[0], 0] and volts[0] == -a.voltage[0] and amps[0] == -a.current[0]


def test_a_drifting_current_zero_grows_with_the_robots_time():
    """current_drift: the sensor's zero moves by rate x the robot's time since power-up
    (tick k ends at k x 0.015 s), before its ADC: with sensor noise off each reading is the
    ADC level nearest the true current plus rate x t (guard.yaml: +-2 A over 10 bits, a
    3.90625 mA step, worked out here), on top of an offset after the ADC; the motion is
    untouched. The board reads the given rate whatever the sensor's gain."""
    step = 4.0 / 1024
    for gain in (1.0, 0.5):
        extra = f",current_gain:pan={gain}" if gain != 1.0 else ""
        clean, wired = _plants(f"current_drift:pan=0.002,current_offset:pan=0.01{extra}&noise=0")
        for k in range(1, 4001):
            a, b = clean.step([0.5, 0.0]), wired.step([0.5, 0.0])
            assert b.counts == a.counts
            inside = a.current_true[0] + 0.002 * k * 0.015 / gain  # the sensor's own amperes
            level = math.floor(inside / step + 0.5) * step
            assert b.current[0] == pytest.approx(gain * level + 0.01, abs=1e-12), k


# ---------------------------------------------------------------- safety of the moves
def test_pulse_refused_when_the_limits_leave_no_room():
    """A joint whose whole range is less than a pulse's reach is never moved."""
    yaml = JointYaml("tilt", 1000.0, ke=20.0, r=8.0, supply_v=12.0, current_range_a=2.0,
                     counts_per_rev=48)  # fmt: skip
    joint = GUARD.joints[1]
    lo, hi = joint.limits.position
    reach = 6.0 / 20.0 * 20 * 0.015  # V / Ke x pulse [rad], worked out by hand: 0.09 rad
    narrow = type("J", (), {"limits": type("L", (), {"position": (0.0, reach)})()})()
    with pytest.raises(MovesStopped) as info:
        pulse_plan(narrow, yaml, 0, 0.015)
    assert info.value.check.verdict == FAIL and "room" in info.value.check.name
    sign, volts, (w_lo, w_hi) = pulse_plan(joint, yaml, round(lo * 1000), 0.015)
    assert sign == 1 and volts == 6.0  # from the low stop: up first
    assert w_lo < lo * 1000 and w_hi <= math.ceil((lo + 4 * reach + 0.02) * 1000)
    assert pulse_plan(joint, yaml, round(hi * 1000), 0.015)[0] == -1


def test_slow_settling_keeps_the_watchdog_fed(monkeypatch):
    """Resting 450 ms between the joints' pulses (longer than the 250 ms watchdog) in
    voltage mode: 0 V is sent meanwhile, so the second joint still gets its pulses."""
    import guardid.doctor.bench as bench

    monkeypatch.setattr(bench, "STILL_TICKS", 30)
    checks, _ = doctor_checks()
    assert failed(checks) == set()


def test_runaway_joint_idles_the_motors():
    """An encoder of 40x the YAML's counts runs out of the pulse's window: motors idled."""
    checks, device = doctor_checks("&wiring=cpr:pan=2000")
    row = checks[-1]
    assert (row.name, row.joint, row.verdict) == ("moves stopped", "pan", FAIL)
    assert device.mode == 0 and device.applied_mv == [0, 0]


@contextmanager
def emulator_with(**handlers):
    """sim:// ports get a FirmwareEmulator whose handlers ``handlers`` replace."""

    class Broken(FirmwareEmulator):
        _HANDLERS = {**FirmwareEmulator._HANDLERS, **handlers}

    def factory(robot, options):
        plain = make_sim_device(robot, options)
        return Broken(plain.description, plain.plant)

    old = register_device_factory(factory)
    try:
        yield
    finally:
        register_device_factory(old)


def test_watchdog_that_never_trips_fails():
    def ignore(self, frame):  # ACK, keep the default 250 ms... then never trip it
        self.watchdog_ms = 10**9
        self._ack(frame)

    with emulator_with(SetWatchdog=ignore):
        checks, _ = doctor_checks()
    assert ("watchdog", "") in failed(checks)


def test_estop_that_does_not_latch_fails():
    def ack_only(self, frame):
        self._ack(frame)

    with emulator_with(Estop=ack_only):
        checks, _ = doctor_checks()
    assert failed(checks) == {("e-stop", "")}


def test_estop_held_at_start_moves_nothing():
    def stays(self, frame):  # the button is held: CLEAR_ESTOP changes nothing
        self._ack(frame)

    with emulator_with(ClearEstop=stays):
        port = open_port("sim://guard?seed=1")
        try:
            device = port.engine.device
            device.estop = True
            session = Session(port)
            session.handshake()
            checks = run_checks(session, GUARD)
            assert failed(checks) == {("e-stop", "")}
            assert all(c.verdict == UNKNOWN for c in checks if c.name == "moves")
            assert device.plant.tick > 0 and device.applied_mv == [0, 0]
        finally:
            port.close()


# ---------------------------------------------------------------- host checks
def test_link_check_thresholds_in_ticks():
    period = 0.015
    assert link_check(np.full(20, 0.016), period).verdict == OK
    assert link_check(np.r_[np.full(19, 0.016), 0.1], period).verdict == WARN
    bad = link_check(np.r_[np.full(19, 0.016), 0.2], period)
    assert bad.verdict == FAIL and bad.fix


def test_latency_timer_from_sysfs(tmp_path):
    for name, value in (("ttyUSB0", "16"), ("ttyUSB1", "1")):
        (tmp_path / name).mkdir()
        (tmp_path / name / "latency_timer").write_text(value + "\n")
    slow = latency_check("/dev/ttyUSB0", tmp_path)
    assert slow.verdict == WARN and "16 ms" in slow.measured
    assert str(tmp_path / "ttyUSB0" / "latency_timer") in slow.fix
    assert latency_check("/dev/ttyUSB1", tmp_path).verdict == OK
    assert latency_check("/dev/ttyACM0", tmp_path).verdict == OK
    assert latency_check("/dev/pts/7", tmp_path).verdict == UNKNOWN
    assert latency_check("sim://guard", tmp_path).verdict == UNKNOWN
