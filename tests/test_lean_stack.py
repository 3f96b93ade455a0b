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
from pathlib import Path

import numpy as np
import pytest

from guardid import protocol as P
from guardid.capture.stop import CaptureStopped, StopAwarePort, StopRequest
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
