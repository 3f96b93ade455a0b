"""The firmware emulator's state machine, through the real codec and the sim:// port.

A stand-in plant (a motor whose speed is proportional to its voltage) keeps these tests
independent of the rigid-body simulator; the full plant is exercised in test_hil.py.
"""

from __future__ import annotations

import math
from types import SimpleNamespace

import pytest

from guardid.errors import LinkError
from guardid.fakeport import register_device_factory
from guardid.firmware import FirmwareEmulator, FixedPid, pid_gains_q16
from guardid.link import Session, open_port
from guardid.protocol import ENUMS
from guardid.robot import load_robot

STATUS = ENUMS["status"]


class SpeedPlant:
    """Joint speed = gain * voltage [counts per tick per V]; current = voltage / 8 ohm."""

    def __init__(self, n: int, gain: float = 2.0) -> None:
        self.pos = [0.0] * n
        self.gain = gain
        self.applied: list[list[float]] = []

    def step(self, volts):
        self.applied.append(list(volts))
        self.pos = [p + self.gain * v for p, v in zip(self.pos, volts, strict=True)]
        return SimpleNamespace(
            counts=[math.floor(p) for p in self.pos],
            voltage=list(volts),
            current=[v / 8.0 for v in volts],
        )


@pytest.fixture
def rig():
    """A Session on a lock-step sim:// port whose device is the emulator on SpeedPlant."""
    made = {}

    def factory(robot, options):
        desc = load_robot(robot)
        made["plant"] = SpeedPlant(desc.n_dof)
        made["fw"] = FirmwareEmulator(desc, made["plant"])
        return made["fw"]

    old = register_device_factory(factory)
    port = open_port("sim://guard?seed=3", timeout_s=0.1)
    session = Session(port, timeout_s=1.0)
    try:
        yield session, made["fw"], made["plant"]
    finally:
        port.close()
        register_device_factory(old)


def test_handshake_reports_robot_facts(rig):
    session, fw, _ = rig
    info = session.handshake()
    assert info["joint_count"] == 2
    assert info["counts_per_rev"] == (48 * 500, 48 * 1000)
    assert info["tick_period"] == pytest.approx(0.015)
    assert info["setpoint_depth"] == 8


def test_setpoints_apply_at_their_tick_and_underrun_is_flagged(rig):
    session, fw, plant = rig
    session.handshake()
    rows = [[100 * k, -50 * k] for k in range(20)]
    seen = {}
    for index, t in session.track(rows):
        seen[index] = t
    # every tick of the trajectory was reported with the setpoint stamped for it
    for k in range(20):
        assert seen[k].setpoint_counts == tuple(rows[k])
        assert not seen[k].status & (1 << STATUS["setpoint_underrun"])
    # no more setpoints: the next tick holds the last one and flags an underrun
    session.poll()
    t = session.next_telemetry()
    assert t.setpoint_counts == tuple(rows[-1])
    assert t.status & (1 << STATUS["setpoint_underrun"])
    assert session.stats.errors == 0 and session.stats.seq_gaps == 0


def test_late_and_excess_setpoints_are_refused(rig):
    session, fw, _ = rig
    session.handshake()
    session.set_mode("position")
    now = session.ping()
    session.send_setpoint(now, [0, 0])  # the tick in force is already computed: late
    for k in range(1, 10):  # 9 ahead: the 9th overflows the 8-deep buffer
        session.send_setpoint(now + k, [0, 0])
    naks = []
    for _ in range(3):
        naks += [f.msg for f in session.poll() if type(f.msg).__name__ == "Nak"]
    errors = sorted(n.error for n in naks)
    assert errors == sorted([ENUMS["error"]["setpoint_late"], ENUMS["error"]["buffer_full"]])


def test_watchdog_trips_when_host_goes_silent(rig):
    session, fw, plant = rig
    session.handshake()
    session.set_mode("voltage")
    session.start_stream()
    session.send_voltage([6.0, -3.0])
    # host silent: read telemetry only (reads are not host frames)
    ticks = []
    while len(ticks) < 40:
        session.poll()
        while session.telemetry:
            ticks.append(session.telemetry.popleft())
    tripped = [t for t in ticks if t.status & (1 << STATUS["watchdog_tripped"])]
    assert tripped, "watchdog never tripped"
    first = tripped[0].tick
    # 250 ms at 15 ms per tick: trips on the 17th tick after the last host frame
    assert first * 0.015 >= 0.25 and (first - 1) * 0.015 < 0.25 + 0.015 * 2
    assert all(v == 0.0 for v in plant.applied[first]), "motors not at 0 V after the trip"
    assert any(f.code == ENUMS["fault"]["watchdog"] for f in session.faults)
    assert fw.mode == ENUMS["mode"]["idle"]
    session.set_mode("voltage")  # an accepted moving mode clears the latched bit
    t = session.next_telemetry()
    assert not t.status & (1 << STATUS["watchdog_tripped"])


def test_estop_stops_motors_at_once(rig):
    session, fw, plant = rig
    session.handshake()
    session.set_mode("voltage")
    session.start_stream()
    session.send_voltage([12.0, 12.0])
    session.next_telemetry()
    session.next_telemetry()
    assert fw.applied_mv != [0, 0]
    n_before = len(plant.applied)
    session.estop()
    t = session.next_telemetry()
    assert plant.applied[n_before] == [0.0, 0.0]  # the very next period is unpowered
    assert t.status & (1 << STATUS["estop"])
    with pytest.raises(LinkError, match="estop_active"):
        session.set_mode("position")


@pytest.mark.parametrize("version", [0, 3])
def test_protocol_mismatch_is_a_clear_error(rig, version):
    session, fw, _ = rig
    fw.protocol_version = version  # older than the oldest guardid talks to, or newer
    with pytest.raises(LinkError, match=f"protocol version {version}, guardid speaks 1..2"):
        session.handshake()


def test_version_1_firmware_is_still_spoken_to(rig):
    session, fw, _ = rig
    fw.protocol_version = 1
    assert session.handshake()["protocol_version"] == 1


def test_joint_limit_blocks_motion_past_the_limit(rig):
    session, fw, plant = rig
    session.handshake()
    hi = fw.limits[1][1]
    plant.pos[1] = hi + 5.0
    session.set_mode("voltage")
    session.start_stream()
    session.send_voltage([0.0, 5.0])
    session.next_telemetry()
    t = session.next_telemetry()
    assert t.status & (1 << STATUS["limit_j1"])
    assert plant.applied[-1][1] == 0.0


def test_fixed_point_pid_matches_float_pid():
    """The integer PID follows a float PID of the same gains to within rounding."""
    cpr, tick_us = 24000, 15000
    kp, ki, kd = 40.0, 10.0, 1.0
    pid = FixedPid(12000)
    pid.set_gains(pid_gains_q16(40_000_000, 10_000_000, 1_000_000, cpr, tick_us))
    rad = 2 * math.pi / cpr
    integral = 0.0
    prev = 0.0
    for k in range(200):
        err_counts = int(300 * math.sin(k / 15.0))
        e = err_counts * rad
        integral += e * 0.015
        u = kp * e + ki * integral + kd * (e - prev) / 0.015
        prev = e
        out = pid.step(err_counts, 0)
        assert abs(out - 1000 * u) <= 2 + 1e-4 * k * abs(1000 * u)
