"""The lock-step stack's fast paths give what the general paths give.

Frames packed from flat values (``Encoder.packer``) against the golden vectors (hex made
by firmware_proto/gen_vectors.py and checked against the C codec); telemetry routed by the
parser against the vectors' field values; a session reading ``sim://`` in one call
against one reading through a plain ``read()`` proxy; the plant's ``step_sensors`` against
``step``.
"""

from __future__ import annotations

import json
import math
from contextlib import contextmanager
from pathlib import Path

import numpy as np
import pytest

from guardid import protocol as P
from guardid.capture.stop import CaptureStopped, StopAwarePort, StopRequest
from guardid.fakeport import register_device_factory
from guardid.firmware import make_sim_device
from guardid.firmware.pid import mv_from_volts
from guardid.link import Session, open_port
from guardid.plant import Plant
from guardid.plant.payload import PayloadChange

VECTORS = json.loads(
    (Path(__file__).resolve().parents[1] / "firmware_proto/test_vectors.json").read_text()
)["frames"]


@pytest.mark.parametrize("vec", VECTORS, ids=lambda v: f"{v['name']}-{v['seq']}")
def test_packer_gives_the_golden_bytes_and_numbers_frames(vec):
    enc = P.Encoder(vec["seq"])
    frame = enc.packer(P.MESSAGES[vec["name"]], vec["n_joints"])
    assert frame(*vec["flat"]).hex() == vec["hex"]
    assert enc.seq == (vec["seq"] + 1) % 65536  # numbered like Encoder.encode


def test_packer_refuses_out_of_range_values_without_using_a_number():
    enc = P.Encoder(7)
    frame = enc.packer(P.MESSAGES["SETPOINT"], 2)
    with pytest.raises(ValueError, match="SETPOINT"):
        frame(1, 0, 2**31, 0)  # position is i32
    assert enc.seq == 7


def _fields(msg) -> dict:
    return {k: list(v) if isinstance(v, tuple) else v for k, v in msg._asdict().items()}


def test_routed_frames_reach_the_sink_with_the_vectors_fields_and_are_counted():
    stream = b"".join(bytes.fromhex(v["hex"]) for v in VECTORS)
    parser, routed = P.FrameParser(), []
    parser.route(P.MESSAGES["TELEMETRY"].MSG_ID, P.MESSAGES["TELEMETRY"], routed.append)
    others = []
    for k in range(0, len(stream), 7):  # arbitrary chunks
        others += parser.feed(stream[k : k + 7])
    telemetry = [v for v in VECTORS if v["name"] == "TELEMETRY"]
    assert telemetry and [_fields(m) for m in routed] == [v["fields"] for v in telemetry]
    assert [(f.msg_id, f.seq) for f in others] == [
        (v["msg_id"], v["seq"]) for v in VECTORS if v["name"] != "TELEMETRY"
    ]
    assert parser.stats.frames == len(VECTORS) and parser.stats.errors == 0


class ReadOnlyProxy:
    """A port wrapper that offers read() only (the general poll path)."""

    def __init__(self, port) -> None:
        self._port = port

    def read(self, size: int = 1) -> bytes:
        return self._port.read(size)

    def __getattr__(self, name):
        return getattr(self._port, name)


def _run(wrap, ticks: int = 300):
    port = open_port("sim://guard?seed=5")
    try:
        session = Session(wrap(port))
        session.handshake()
        t = np.arange(ticks) * 0.015
        rows = np.column_stack([800 * np.sin(2 * np.pi * t), 300 * np.cos(3 * t)]).astype(int)
        got = [(i, tuple(tel)) for i, tel in session.track(rows)]
        session.finish()
        return got, session.stats.as_dict()
    finally:
        port.close()


def test_one_call_reads_give_the_telemetry_of_plain_reads():
    fast, fast_stats = _run(lambda p: p)
    stop_aware, _ = _run(lambda p: StopAwarePort(p, StopRequest()))
    plain, plain_stats = _run(ReadOnlyProxy)
    rows = [i for i, _ in fast if i >= 0]
    assert rows == list(range(300))  # every tick of the trajectory, in order
    assert fast == plain == stop_aware and fast_stats == plain_stats
    assert hasattr(StopAwarePort(open_port("sim://guard"), StopRequest()), "read_some")


def _plants():
    payload = (PayloadChange(1.5, 0.4, (0.05, 0.0, 0.0)),)
    return [Plant("guard", seed=3, payload=payload) for _ in range(2)]


def test_step_sensors_is_step_without_the_sample():
    full, lean = _plants()
    for k in range(300):  # drive, reverse, coast to a stop (stick), payload at 1.5 s
        u = [6.0 * math.sin(0.05 * k), 0.0 if 150 < k < 220 else 4.0 * math.cos(0.03 * k)]
        sample = full.step(u)
        counts, volts, amps = lean.step_sensors(u)
        assert (tuple(counts), tuple(volts), tuple(amps)) == (
            sample.counts,
            sample.voltage,
            sample.current,
        )
        assert all(type(c) is int for c in counts)
    assert full.state == lean.state


def test_stop_aware_one_call_read_stops_only_when_it_would_wait():
    port = open_port("sim://guard?seed=1")
    try:
        stop = StopRequest()
        reader = StopAwarePort(port, stop)
        port.write(P.encode(P.MESSAGES["PING"](1), 0))  # the PONG is waiting at once
        stop.request()
        assert P.decode(reader.read_some()).msg == P.MESSAGES["PONG"](1, 0)  # handed over
        with pytest.raises(CaptureStopped):
            reader.read_some()  # nothing waiting: this read would wait
        stop.disarm()
        assert reader.read_some() == b""  # idle device: the read times out empty
    finally:
        port.close()


def test_mass_alone_is_the_mass_part_of_the_fitted_evaluator():
    dyn = Plant("guard")._dyn
    rng = np.random.default_rng(4)
    for q1, q2, v1, v2 in rng.uniform(-3.0, 3.0, (200, 4)).tolist():
        assert dyn.mass(q2) == dyn(q1, q2, v1, v2)[:3]


class OneCallRecorder:
    """A port proxy keeping what the host read and wrote, offering read_some (so the
    session takes the one-call fast path) as well as read."""

    def __init__(self, port) -> None:
        self._port = port
        self.received, self.sent = bytearray(), bytearray()

    def read_some(self) -> bytes:
        data = self._port.read_some()
        self.received += data
        return data

    def read(self, size: int = 1) -> bytes:
        data = self._port.read(size)
        self.received += data
        return data

    def write(self, data) -> int:
        self.sent += data
        return self._port.write(data)

    def __getattr__(self, name):
        return getattr(self._port, name)


class PlainRecorder(OneCallRecorder):
    """The same without read_some: the session polls with in_waiting and read()."""

    read_some = None


class AheadRecorder(OneCallRecorder):
    """The one-call recorder passing run-ahead on (``Session.track(run_ahead=True)``),
    counting its reads."""

    reads_ahead = True

    def read_some(self, ahead_ticks: int = 0) -> bytes:
        self.reads = getattr(self, "reads", 0) + 1
        data = self._port.read_some(ahead_ticks)
        self.received += data
        return data


def _recorded_run(url: str, recorder, ticks: int = 600, watchdog_s=None, feedforward=False):
    """(host-read bytes, host-written bytes, fault stats) of a closed-loop run."""
    port = recorder(open_port(url))
    try:
        session = Session(port)
        session.handshake()
        if watchdog_s is not None:
            session.set_watchdog(watchdog_s)
        t = np.arange(ticks) * 0.015
        rows = np.column_stack([900 * np.sin(1.3 * t), 400 * np.sin(2.1 * t) + 300])
        if feedforward:  # + feedforward [mV] per joint
            rows = np.column_stack([rows, 800 * np.cos(1.3 * t), 300 * np.cos(2.1 * t)])
        run_ahead = recorder is AheadRecorder
        track = session.track(rows.astype(int), feedforward=feedforward, run_ahead=run_ahead)
        assert sum(i >= 0 for i, _ in track) == ticks
        if run_ahead:  # the path under test: several ticks per read
            assert port.reads < ticks / 2
        session.finish()
        assert port.engine.clean == ("disconnect_s" not in url)  # the path under test
        return bytes(port.received), bytes(port.sent), port.fault_stats
    finally:
        port.close()


@contextmanager
def reference_device():
    """While active, sim:// ports get the emulator reading its plant through
    ``Plant.step`` (the full SensorSample path) instead of ``step_sensors``; yields the
    plant's samples, one per tick."""
    samples = []

    def factory(robot, options):
        device = make_sim_device(robot, options)

        def read_plant(volts):
            sample = device.plant.step(volts)
            samples.append(sample)
            return [int(c) for c in sample.counts], sample.voltage, sample.current

        device._read_plant = read_plant
        return device

    old = register_device_factory(factory)
    try:
        yield samples
    finally:
        register_device_factory(old)


@pytest.mark.parametrize("query", ["seed=3", "seed=8&phase=1"])
def test_sim_port_bytes_equal_a_straightforward_reference_path(query):
    """Fast path: clean-link ticks without the fault layer, one-call reads, packed frames,
    step_sensors. Reference: the general event loop (a disconnect scheduled far beyond
    the run makes the link not clean), plain reads, Plant.step; and every telemetry
    frame is the general encoder's frame of the plant's readings in milli-units."""
    got, sent, stats = _recorded_run(f"sim://guard?{query}", OneCallRecorder)
    with reference_device() as samples:
        ref = _recorded_run(f"sim://guard?{query}&disconnect_s=1000", PlainRecorder)
    assert got == ref[0] and sent == ref[1]
    for st in (stats, ref[2]):  # the fault layer's byte accounting, with faults or not
        assert st.down.bytes_in == st.down.bytes_out == len(got)
        assert st.up.bytes_in == st.up.bytes_out == len(sent)
        assert st.down.bytes_dropped == st.up.bytes_dropped == 0 and not st.bursts
    by_tick = {s.tick: s for s in samples}
    telemetry = 0
    for seg in got.split(b"\x00")[:-1]:
        frame = P.decode(seg)
        if type(frame.msg) is not P.MESSAGES["TELEMETRY"]:
            continue
        telemetry += 1
        sample, msg = by_tick[frame.msg.tick], frame.msg
        assert msg.position == sample.counts  # [counts]
        assert msg.voltage == tuple(mv_from_volts(v) for v in sample.voltage)  # [mV]
        assert msg.current == tuple(mv_from_volts(i) for i in sample.current)  # [mA]
        assert P.encode(msg, frame.seq) == seg + b"\x00"
    assert telemetry > 600


def test_fused_free_acceleration_is_dyn_solved_for_qdd():
    """free_accel's fused expressions give dyn's numbers exactly, and solve the model's
    equations of motion (numpy on the generic mass matrix and bias)."""
    plant = Plant("guard")
    dyn, model, params = plant._dyn, plant.model, plant.params[0]
    rng = np.random.default_rng(9)
    for q1, q2, v1, v2, e1, e2, c1, c2, ia1, ia2 in rng.uniform(-3.0, 3.0, (100, 10)).tolist():
        ia1, ia2 = abs(ia1) * 1e-3, abs(ia2) * 1e-3  # small inertia corrections [kg m^2]
        got = dyn.free_accel(e1, e2, c1, c2, ia1, ia2)(q1, q2, v1, v2)
        m11, m12, m22, b1, b2 = dyn(q1, q2, v1, v2)
        r1, r2 = e1 - c1 * v1 - b1, e2 - c2 * v2 - b2
        m11, m22 = m11 - ia1, m22 - ia2
        det = m11 * m22 - m12 * m12
        assert got == ((r1 * m22 - r2 * m12) / det, (r2 * m11 - r1 * m12) / det)
        q, qd = np.array([[q1, q2]]), np.array([[v1, v2]])
        mm = model.mass_matrix(q, params)[0] - np.diag([ia1, ia2])
        rhs = np.array([e1 - c1 * v1, e2 - c2 * v2]) - model.bias(q, qd, params)[0]
        assert np.allclose(got, np.linalg.solve(mm, rhs), rtol=1e-7, atol=1e-9)


@pytest.mark.parametrize(
    ("query", "watchdog_s", "feedforward"),
    [("seed=3", None, False), ("seed=8&phase=1&noise=0", 0.06, False), ("seed=4", None, True)],
)
def test_run_ahead_gives_the_bytes_of_one_tick_at_a_time(query, watchdog_s, feedforward):
    """Run-ahead (several ticks per read, the setpoints of a read's frames in one write)
    against the reference path (general event loop, plain reads, Plant.step): the same
    bytes in both directions, hence no setpoint late or missing (an underrun bit, a NAK),
    no tick run beyond the last row's before the host's SET_MODE idle (an extra
    TELEMETRY), no watchdog trip but where one tick at a time trips it, at the same tick:
    a 60 ms watchdog (2 ticks ahead) trips in the last row's ticks, where the host has no
    setpoint left to send (a FAULT frame)."""
    url = f"sim://guard?{query}"
    got, sent, _ = _recorded_run(url, AheadRecorder, 400, watchdog_s, feedforward)
    with reference_device():
        ref = _recorded_run(url + "&disconnect_s=1000", PlainRecorder, 400, watchdog_s, feedforward)
    assert got == ref[0] and sent == ref[1]
    names = [type(P.decode(seg).msg).__name__ for seg in got.split(b"\x00")[:-1]]
    assert "Nak" not in names and names.count("Fault") == (watchdog_s is not None)


def test_a_capture_ended_by_until_idles_the_robot_at_that_rows_tick(tmp_path):
    """A row's answer may end a capture (``until``, capture --until-std): then no
    run-ahead, the robot hears SET_MODE idle at the tick of the row that ended it (with
    run-ahead it would have run up to depth - 1 ticks further, their TELEMETRY sent)."""
    from guardid.capture.run import capture
    from guardid.excitation.sines import SumOfSines
    from guardid.robot import load_robot

    traj = SumOfSines([[0.3], [0.1]], [[0.2], [0.3]], [[0.0], [0.0]], [0.0, 0.2])
    port = AheadRecorder(open_port("sim://guard?seed=2"))
    try:
        session = Session(port)
        session.handshake()
        ticks = []
        result = capture(session, load_robot("guard"), traj, 3.0, tmp_path / "run.csv", {},
                         on_record=lambda tick, *_: ticks.append(tick),
                         until=lambda: len(ticks) >= 50)  # fmt: skip
    finally:
        port.close()
    assert result.ended == "identified" and result.rows == 50
    frames = [P.decode(seg) for seg in bytes(port.received).split(b"\x00")[:-1]]
    telemetry = [f.msg.tick for f in frames if type(f.msg) is P.MESSAGES["TELEMETRY"]]
    assert max(telemetry) == ticks[-1]


def test_telemetry_clamps_readings_beyond_int16_milli_units_and_numbers_frames_on():
    """A reading beyond +-32.767 V or A goes out as the int16 limit (worked out by hand:
    40 A -> 32767 mA, -33 V -> -32768 mV); in-range values rounded half up; no sequence
    number lost to the clamping."""
    device = make_sim_device("guard", open_port("sim://guard").options)
    readings = iter(
        [([5, -7], [1.2346, -33.0], [40.0, -0.0004]), ([6, -8], [0.5, 0.25], [1.0, 2.0])]
    )
    device._read_plant = lambda volts: next(readings)
    device.streaming = True
    device.advance()
    device.advance()
    frames = [P.decode(seg) for seg in device.take_output().split(b"\x00")[:-1]]
    assert [f.seq for f in frames] == [0, 1]
    first, second = (f.msg for f in frames)
    assert (first.position, first.voltage, first.current) == ((5, -7), (1235, -32768), (32767, 0))
    assert (second.voltage, second.current) == ((500, 250), (1000, 2000))
