"""A link that survives noise: commands resent, duplicates harmless, the port exclusive.

The retry tests run on a scripted port with its own simulated clock (no wall-clock
waits): it answers every command by the protocol's rules, written here from the README,
but swallows the first ``k`` answers. The firmware's duplicate rule is checked on the
emulator; tests/test_firmware_c.py holds the C core to the same bytes.
"""

from __future__ import annotations

import os
import subprocess
import sys
import tty
from types import SimpleNamespace

import pytest
from click.testing import CliRunner
from linktools import BothWays, Recorder, Sines, expected_damage, teed_devices
from test_firmware_emulator import SpeedPlant

from guardid.capture import capture
from guardid.cli import main
from guardid.errors import LinkError
from guardid.firmware import FirmwareEmulator
from guardid.link import RetryPolicy, Session, open_port
from guardid.log import read_log
from guardid.protocol import ENUMS, MESSAGES, Encoder, FrameParser, decode
from guardid.robot import load_robot

M = MESSAGES
MODE = ENUMS["mode"]
FAULT = ENUMS["fault"]
GUARD = load_robot("guard")
NOISY = "sim://guard?drop=1e-3&flip=1e-4&latency_ms=16&seed={}"


# ---------------------------------------------------------------------- scripted port
class ScriptedPort:
    """A lock-step port that answers HELLO/PING/commands but loses the first ``lose``
    answers. Reading with nothing to deliver advances its clock by ``step_s``."""

    def __init__(self, lose: int = 0, nak: int | None = None, step_s: float = 0.01) -> None:
        self.lose = lose
        self.nak = nak
        self.step_s = step_s
        self.portstr = "scripted://robot"
        self.options = SimpleNamespace(lockstep=True)
        self.sim_time_s = 0.0
        self.writes: list[tuple[float, bytes]] = []  # (simulated time [s], frame)
        self._parser = FrameParser()
        self._encoder = Encoder()
        self._rx = bytearray()

    @property
    def in_waiting(self) -> int:
        return len(self._rx)

    def write(self, data: bytes) -> int:
        self.writes.append((self.sim_time_s, bytes(data)))
        for f in self._parser.feed(data):
            answer = self._answer(f)
            if self.lose > 0:
                self.lose -= 1
            else:
                self._rx += self._encoder.encode(answer)
        return len(data)

    def _answer(self, f):
        if type(f.msg) is M["HELLO"]:
            return M["INFO"](1, 2, 0x1F, 7, 15000, 250, 8, (24000, 48000))
        if type(f.msg) is M["PING"]:
            return M["PONG"](f.msg.nonce, 1000 + len(self.writes))
        if self.nak is not None:
            return M["NAK"](f.seq, f.msg_id, self.nak)
        return M["ACK"](f.seq, f.msg_id)

    def read(self, size: int = 1) -> bytes:
        if not self._rx:
            self.sim_time_s += self.step_s
        out = bytes(self._rx[:size])
        del self._rx[:size]
        return out


@pytest.mark.parametrize("lost", [0, 1, 2, 4])
def test_a_command_succeeds_after_its_lost_answers(lost):
    port = ScriptedPort(lose=lost)
    session = Session(port, timeout_s=1.0)
    session.set_mode("position")
    assert len(port.writes) == lost + 1 and session.resends == lost
    # every attempt is the same frame: same sequence number, so the firmware sees a repeat
    assert {frame for _, frame in port.writes} == {port.writes[0][1]}
    assert decode(port.writes[0][1]).msg == M["SET_MODE"](MODE["position"])
    # growing waits: 0.1, 0.2, 0.4, 0.8 s between sends (simulated time, 10 ms reads)
    gaps = [b[0] - a[0] for a, b in zip(port.writes, port.writes[1:], strict=False)]
    assert gaps == pytest.approx([0.1, 0.2, 0.4, 0.8][:lost], abs=0.011)


def test_handshake_and_ping_are_resent_too():
    port = ScriptedPort(lose=2)
    session = Session(port, timeout_s=1.0)
    assert session.handshake()["joint_count"] == 2
    assert len(port.writes) == 3
    port.lose = 1
    tick = session.ping()
    assert len(port.writes) == 5 and tick == 1000 + 5  # the answer to the second PING


def test_no_answer_is_one_line_naming_command_and_port_after_bounded_attempts():
    port = ScriptedPort(lose=10**6)
    session = Session(port, timeout_s=1.0)
    with pytest.raises(LinkError) as info:
        session.set_pid(0, 10.0, 0.0, 0.1)
    msg = str(info.value)
    assert "\n" not in msg and "SET_PID" in msg and "scripted://robot" in msg
    assert "5 attempts" in msg
    assert len(port.writes) == 5
    # the waits 0.1 + 0.2 + 0.4 + 0.8 + 1.0 s (capped at timeout_s) bound the whole command
    assert port.sim_time_s == pytest.approx(2.5, abs=0.06)


def test_retry_policy_is_bounded_by_its_attempts_and_longest_wait():
    policy = RetryPolicy(attempts=3, first_wait_s=0.05, backoff=3.0, max_wait_s=0.3)
    assert policy.waits_s() == pytest.approx([0.05, 0.15, 0.3])
    port = ScriptedPort(lose=10**6, step_s=0.005)
    with pytest.raises(LinkError, match="no answer to STOP_STREAM after 3 attempts"):
        Session(port, retry=policy).stop_stream()
    assert len(port.writes) == 3 and port.sim_time_s == pytest.approx(0.5, abs=0.02)
    with pytest.raises(ValueError):
        RetryPolicy(attempts=0)


def test_a_nak_is_an_answer_and_is_not_resent():
    port = ScriptedPort(nak=ENUMS["error"]["estop_active"])
    with pytest.raises(LinkError, match="SET_MODE refused by the robot: estop_active"):
        Session(port).set_mode("position")
    assert len(port.writes) == 1


def test_streamed_setpoints_are_sent_once():
    port = ScriptedPort(lose=10**6)
    session = Session(port)
    session.send_setpoint(5, (1, 2))
    session.send_voltage((0.5, -0.5))
    assert len(port.writes) == 2 and session.resends == 0


# ---------------------------------------------------------------------- firmware
def _emulator():
    return FirmwareEmulator(GUARD, SpeedPlant(GUARD.n_dof))


def _replies(fw, frame: bytes, parser: FrameParser):
    fw.receive(frame)
    return [f.msg for f in parser.feed(fw.take_output())]


def test_repeated_estop_is_acked_again_and_reported_once():
    fw, parser, enc = _emulator(), FrameParser(), Encoder()
    frame = enc.encode(M["ESTOP"]())
    first = _replies(fw, frame, parser)
    again = _replies(fw, frame, parser)
    assert [type(m) for m in first] == [M["ACK"], M["FAULT"]]
    assert again == [M["ACK"](0, M["ESTOP"].MSG_ID)]  # no second FAULT


def test_repeated_command_is_not_applied_again():
    fw, parser, enc = _emulator(), FrameParser(), Encoder()
    go = enc.encode(M["SET_MODE"](MODE["position"]))
    assert _replies(fw, go, parser) == [M["ACK"](0, M["SET_MODE"].MSG_ID)]
    for _ in range(17):  # 17 silent ticks x 15 ms >= 250 ms: the watchdog trips
        fw.advance()
    assert fw.mode == MODE["idle"] and fw.watchdog_tripped
    fw.take_output()
    # the same frame again (a retry whose first ACK was lost): ACKed, nothing re-applied
    assert _replies(fw, go, parser) == [M["ACK"](0, M["SET_MODE"].MSG_ID)]
    assert fw.mode == MODE["idle"] and fw.watchdog_tripped
    # a new command with the same content is applied
    assert _replies(fw, enc.encode(M["SET_MODE"](MODE["position"])), parser)[0].ack_seq == 1
    assert fw.mode == MODE["position"] and not fw.watchdog_tripped


def test_same_sequence_number_with_other_content_is_a_new_command():
    """A new host session restarts at seq 0: its SET_MODE idle must not be taken for the
    previous session's SET_MODE position with the same seq."""
    fw, parser = _emulator(), FrameParser()
    _replies(fw, Encoder(0).encode(M["SET_MODE"](MODE["position"])), parser)
    assert fw.mode == MODE["position"]
    _replies(fw, Encoder(0).encode(M["SET_MODE"](MODE["idle"])), parser)
    assert fw.mode == MODE["idle"]


def test_repeated_refusal_gets_the_same_nak_and_hello_ping_are_answered_anew():
    fw, parser, enc = _emulator(), FrameParser(), Encoder()
    bad = enc.encode(M["SET_PID"](7, 1, 1, 1))
    nak = M["NAK"](0, M["SET_PID"].MSG_ID, ENUMS["error"]["bad_joint"])
    assert _replies(fw, bad, parser) == [nak] and _replies(fw, bad, parser) == [nak]
    ping = enc.encode(M["PING"](9))
    assert _replies(fw, ping, parser) == [M["PONG"](9, 0)]
    fw.advance()
    assert _replies(fw, ping, parser) == [M["PONG"](9, 1)]  # the tick of now


# ---------------------------------------------------------------------- noisy captures
@pytest.mark.parametrize("seed", [0, 1, 3, 4, 6, 8])
def test_noisy_capture_starts_finishes_and_counts_the_damage(tmp_path, seed):
    """Seeds 0, 1, 3, 4 and 6 lost an answer at start-up and stopped with 0 rows when
    commands were sent once; the footer's counts equal the damage counted independently
    from the bytes the device sent and the bytes the host read."""
    with teed_devices() as tees:
        port = Recorder(open_port(NOISY.format(seed)))
        try:
            session = Session(port, timeout_s=1.0)
            session.handshake()
            log = tmp_path / "run.csv"
            result = capture(session, GUARD, Sines(), 8.0, log, {"robot": "guard"})
        finally:
            port.close()
    assert result.ended == "complete"
    errors, lost = expected_damage(bytes(tees[0].sent), bytes(port.received))
    footer = read_log(log).footer
    link = footer["link"]
    assert link["crc_errors"] + link["framing_errors"] == errors
    assert link["seq_gaps"] == gaps_between_delivered(bytes(tees[0].sent), lost)
    ticks = read_log(log).columns["tick"].astype(int)
    first = ticks[0] - int(round(read_log(log).columns["time_s"][0] / GUARD.sample_period))
    lost_rows = {
        f.msg.tick - first
        for f in map(decode, lost)
        if type(f.msg) is M["TELEMETRY"] and 0 <= f.msg.tick - first < footer["ticks_expected"]
    }
    assert footer["ticks_expected"] - footer["rows"] == len(lost_rows)


def gaps_between_delivered(clean: bytes, lost: list[bytes]) -> int:
    """Frames lost between the first and the last frame that arrived: the gaps the host can
    see in the sequence numbers (a frame lost before the first arrival leaves no gap)."""
    frames = [s for s in clean.split(b"\x00") if s]
    gone = set(lost)
    arrived = [k for k, s in enumerate(frames) if s not in gone]
    return sum(1 for s in frames[arrived[0] : arrived[-1]] if s in gone)


def test_noisy_capture_resends_and_streams_each_setpoint_once(tmp_path):
    """Seed 0 loses the PONG at start-up: the PING is resent; every setpoint is sent once."""
    port = BothWays(open_port(NOISY.format(0)))
    try:
        session = Session(port, timeout_s=1.0)
        session.handshake()
        result = capture(session, GUARD, Sines(), 4.0, tmp_path / "r.csv", {"robot": "guard"})
    finally:
        port.close()
    assert result.ended == "complete" and session.resends >= 1
    sent = [f.msg for f in FrameParser().feed(bytes(port.sent))]
    pings = [m for m in sent if type(m) is M["PING"]]
    assert len(pings) == 1 + session.resends and len(set(pings)) == 1
    ticks = [m.tick for m in sent if type(m) is M["SETPOINT"]]
    assert len(ticks) == len(set(ticks)) == ticks[-1] - ticks[0] + 1


def test_upstream_damage_is_survived(tmp_path):
    """Host->device bytes damaged too: lost commands are resent, the capture finishes."""
    with teed_devices() as tees:
        port = open_port("sim://guard?drop=3e-3&flip=3e-4&latency_ms=16&upstream=1&seed=2")
        try:
            session = Session(port, timeout_s=1.0)
            session.handshake()
            result = capture(session, GUARD, Sines(), 6.0, tmp_path / "r.csv", {"robot": "g"})
            up = port.fault_stats.up
        finally:
            port.close()
    assert result.ended == "complete" and up.bytes_dropped + up.bytes_flipped > 0
    assert tees[0].device.mode == MODE["idle"] and not tees[0].device.streaming


# ---------------------------------------------------------------------- exclusive port
@pytest.fixture
def pty_path():
    master, slave = os.openpty()
    tty.setraw(slave)
    try:
        yield os.ttyname(slave)
    finally:
        os.close(master)
        os.close(slave)


def test_a_port_in_use_is_a_one_line_error_naming_it(pty_path):
    first = open_port(pty_path)
    try:
        with pytest.raises(LinkError) as info:
            open_port(pty_path)
        msg = str(info.value)
        assert "\n" not in msg and msg.startswith(f"port {pty_path}: already in use")
    finally:
        first.close()
    open_port(pty_path).close()  # free again once the first is closed


def test_the_error_names_the_other_program(pty_path):
    code = f"from guardid.link import open_port; p = open_port({pty_path!r}); print('ok', flush=True); input()"  # noqa: E501
    other = subprocess.Popen(
        [sys.executable, "-c", code], stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True
    )
    try:
        assert other.stdout.readline().strip() == "ok"
        with pytest.raises(LinkError, match=f"locked by pid {other.pid} "):
            open_port(pty_path)
    finally:
        other.communicate("\n", timeout=30)


REST = """kind: fourier
joints: [pan, tilt]
base_freq: 0.1
harmonics: 1
periods: 1
q0: [0.0, 0.1]
a: [[0.0], [0.0]]
b: [[0.0], [0.0]]
"""


def test_capture_on_a_port_in_use_says_so(pty_path, tmp_path):
    traj = tmp_path / "rest.yaml"
    traj.write_text(REST)
    held = open_port(pty_path)
    try:
        result = CliRunner().invoke(
            main,
            ["capture", "--port", pty_path, "--trajectory", str(traj), "-o",
             str(tmp_path / "run.csv")],
        )  # fmt: skip
    finally:
        held.close()
    assert result.exit_code == 3
    assert f"guardid: error: port {pty_path}: already in use" in result.output
    assert not (tmp_path / "run.csv").exists()


def test_sim_ports_are_independent_and_open_twice():
    a, b = open_port("sim://guard?seed=1"), open_port("sim://guard?seed=1")
    try:
        assert Session(a).ping() == Session(b).ping() == 0
    finally:
        a.close()
        b.close()
