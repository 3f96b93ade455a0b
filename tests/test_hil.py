"""Hardware in the loop without hardware: host session <-> sim:// or pty <-> firmware
emulator <-> simulated guard plant (the acceptance checks of the fake-device issue)."""

from __future__ import annotations

import math
import os
import subprocess
import sys

import numpy as np
import pytest
import serial
from linktools import Recorder, expected_damage, teed_devices

from guardid.link import Session, open_port
from guardid.plant import Plant
from guardid.protocol import ENUMS, decode
from guardid.robot import load_robot

GUARD = load_robot("guard")
PERIOD = GUARD.sample_period
CPR = np.array([48 * 500, 48 * 1000])  # counts per joint revolution
PER_RAD = CPR / (2 * math.pi)
N_TICKS = 4000  # 60 s


def reference_trajectory(n: int = N_TICKS) -> np.ndarray:
    """(n, 2) joint angles [rad]: smooth sums of sines inside the tilt joint's travel."""
    t = np.arange(n) * PERIOD
    ramp = np.minimum(t / 3.0, 1.0) ** 2
    q1 = ramp * (0.5 * np.sin(2 * np.pi * 0.1 * t) + 0.2 * np.sin(2 * np.pi * 0.23 * t))
    q2 = 0.2 + ramp * (0.12 * np.sin(2 * np.pi * 0.13 * t) + 0.05 * np.sin(2 * np.pi * 0.31 * t))
    return np.column_stack([q1, q2])


def setpoints(n: int = N_TICKS) -> np.ndarray:
    return np.rint(reference_trajectory(n) * PER_RAD).astype(np.int64)


def run(port, n: int = N_TICKS, ahead: int = 0, timeout_s: float = 2.0):
    """Closed-loop run over ``port``; returns (telemetry by trajectory index, session).

    ``ahead`` > 0: the trajectory has that many more rows than are recorded, so the host
    answers every one of the ``n`` frames with a setpoint and then stops (a lock-step pty
    server then never needs its timing-based fallback for a host that went quiet).
    ``timeout_s``: the session's wait for an answer (simulated time on sim://, wall-clock
    on a pty).
    """
    session = Session(port, timeout_s=timeout_s)
    session.handshake()
    for j, joint in enumerate(GUARD.joints):
        session.set_pid(j, joint.pid.kp, joint.pid.ki, joint.pid.kd)
    rows = {}
    for index, t in session.track(setpoints(n + ahead)):
        if 0 <= index < n:
            rows[index] = t
        if index == n - 1:
            break
    session.finish()
    return rows, session


@pytest.fixture(scope="module")
def lockstep_run():
    port = Recorder(open_port("sim://guard?seed=1"))
    try:
        rows, session = run(port)
    finally:
        port.close()
    return rows, session, bytes(port.received)


def float_pid_reference(first_tick: int, n: int = N_TICKS) -> np.ndarray:
    """Independent closed loop: a float PID straight on the plant, no protocol, no firmware.

    Same timing as the firmware: the voltage computed at tick k (from the counts at k) is
    held over k .. k+1, PWM-quantised by the plant.
    """
    plant = Plant(GUARD, seed=1)
    sp = setpoints(n) / PER_RAD
    gains = [(j.pid.kp, j.pid.ki, j.pid.kd) for j in GUARD.joints]
    integ = np.zeros(2)
    prev = np.zeros(2)
    volts = [0.0, 0.0]
    q_hist = []
    lead = first_tick  # the tick at which the trajectory's first setpoint applies
    for k in range(1, n + lead):
        s = plant.step(volts)
        q = np.array(s.counts) / PER_RAD
        idx = k - lead
        target = sp[idx] if idx >= 0 else np.zeros(2)
        e = target - q
        integ = np.clip(integ + e * PERIOD, -12 / 10, 12 / 10)
        u = [kp * e[j] + ki * integ[j] + kd * (e[j] - prev[j]) / PERIOD
             for j, (kp, ki, kd) in enumerate(gains)]  # fmt: skip
        prev = e
        volts = [max(-12.0, min(12.0, v)) for v in u]
        if idx >= 0:
            q_hist.append(q)
    return np.array(q_hist[:n])


def test_closed_loop_tracks_like_an_independent_pid(lockstep_run):
    rows, session, _ = lockstep_run
    assert sorted(rows) == list(range(N_TICKS))  # every tick, none missing
    st = session.stats
    assert st.errors == 0 and st.seq_gaps == 0 and st.seq_backwards == 0
    q = np.array([rows[k].counts for k in range(N_TICKS)]) / PER_RAD
    sp = np.array([rows[k].setpoint_counts for k in range(N_TICKS)]) / PER_RAD
    assert np.array_equal(np.rint(sp * PER_RAD), setpoints())
    ref = float_pid_reference(rows[0].tick)
    # the fixed-point firmware PID behaves like the float PID on the same plant
    assert np.max(np.abs(q - ref)) < np.radians(0.3)
    err = np.sqrt(np.mean((sp - q) ** 2, axis=0))
    err_ref = np.sqrt(np.mean((sp - ref) ** 2, axis=0))
    assert np.allclose(err, err_ref, rtol=0.05)
    # and it does track: a P-dominated loop lags by about v/kp plus friction
    assert np.all(err < np.radians(6.0))
    no_underrun = [not rows[k].status & (1 << ENUMS["status"]["setpoint_underrun"]) for k in rows]
    assert all(no_underrun)


def test_same_seed_gives_byte_identical_telemetry(lockstep_run):
    _, _, received = lockstep_run
    port = Recorder(open_port("sim://guard?seed=1"))
    try:
        run(port)
    finally:
        port.close()
    assert bytes(port.received) == received
    port = Recorder(open_port("sim://guard?seed=2"))
    try:
        run(port, 200)
    finally:
        port.close()
    assert bytes(port.received) != received[: len(port.received)]


def test_pty_gives_the_same_telemetry_as_sim(lockstep_run):
    """``guardid fake-port`` in lock-step: the first 100 ticks (1.5 s, in the ramp-in into
    the motion) over a pty equal the sim:// run tick for tick. The pty server steps after the
    host's answer and ``--settle-ms`` of silence, or after ``--idle-ms`` without an answer
    (the first frames, which the host need not answer). Both are generous here, so that a
    host descheduled by load beside the test (for less than 50 ms between two writes of its
    start-up sequence, or 500 ms before an answer) cannot make the server step early; the
    trajectory runs ``ahead`` of the recorded rows, so every recorded frame is answered and
    the end needs no fallback. The session's wait is a generous bound ended by the frame."""
    rows_sim, _, _ = lockstep_run
    n = 100
    env = dict(os.environ)
    env.pop("GUARDID_FAKEPORT_DEVICE", None)
    proc = subprocess.Popen(
        [sys.executable, "-m", "guardid", "fake-port", "--robot", "guard", "--seed", "1",
         "--idle-ms", "500", "--settle-ms", "50"],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env,
    )  # fmt: skip
    try:
        path = proc.stdout.readline().strip()
        assert path.startswith("/dev/"), proc.stderr.read()
        port = serial.Serial(path, 115200, timeout=2.0)
        try:
            rows, session = run(port, n, ahead=8, timeout_s=60.0)
        finally:
            port.close()
    finally:
        proc.terminate()
        proc.wait(timeout=60)
    assert sorted(rows) == list(range(n))
    assert session.stats.errors == 0
    first_sim = rows_sim[0].tick
    first_pty = rows[0].tick
    for k in range(n):
        a, b = rows_sim[k], rows[k]
        assert (a.tick - first_sim, a.counts, a.voltage_mv, a.current_ma, a.status) == (
            b.tick - first_pty,
            b.counts,
            b.voltage_mv,
            b.current_ma,
            b.status,
        ), f"tick {k} differs"


def test_injected_link_damage_equals_host_counters():
    with teed_devices() as tees:
        port = Recorder(open_port("sim://guard?seed=5&drop=2e-4&flip=2e-5&latency_ms=16"))
        try:
            rows, session = run(port, 1500)
            damage = port.fault_stats.down
        finally:
            port.close()
    clean = bytes(tees[0].sent)
    delivered = bytes(port.received)
    assert damage.bytes_dropped + damage.bytes_flipped > 5, "the seed injected too little"
    expected_errors, lost = expected_damage(clean, delivered)
    assert session.stats.errors == expected_errors
    assert session.stats.seq_gaps == len(lost)
    # lost telemetry shows as missing ticks, never as invented rows
    first = next(iter(rows.values())).tick - next(iter(rows))
    lost_ticks = set()
    for seg in lost:
        frame = decode(seg)
        if type(frame.msg).__name__ == "Telemetry" and 0 <= frame.msg.tick - first < 1500:
            lost_ticks.add(frame.msg.tick - first)
    assert lost_ticks, "no telemetry was lost: the test shows nothing"
    assert set(rows) == set(range(1500)) - lost_ticks
    for k, t in rows.items():
        assert t.tick == first + k


def test_watchdog_puts_real_motors_at_zero_volts():
    port = open_port("sim://guard?seed=4")
    try:
        session = Session(port, timeout_s=2.0)
        session.handshake()
        session.set_mode("voltage")
        session.start_stream()
        session.send_voltage([6.0, 6.0])
        seen = []
        while len(seen) < 60:
            seen.append(session.next_telemetry())
    finally:
        port.close()
    bit = 1 << ENUMS["status"]["watchdog_tripped"]
    trip = next(i for i, t in enumerate(seen) if t.status & bit)
    assert all(t.status & bit for t in seen[trip:])
    # the mean voltage of the period after the trip is the unpowered motor's: ~0 V
    assert max(abs(v) for v in seen[trip + 1].voltage_mv) < 60
    assert min(abs(v) for v in seen[trip - 2].voltage_mv) > 5000
