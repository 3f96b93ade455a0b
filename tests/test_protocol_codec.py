"""Python codec: generated files up to date, golden vectors, round trips (hypothesis)."""

from __future__ import annotations

import json
import runpy
from pathlib import Path

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from guardid import protocol as P
from guardid.protocol.vectors import flatten, unflatten

ROOT = Path(__file__).resolve().parents[1]
FW = ROOT / "firmware_proto"
VECTORS = json.loads((FW / "test_vectors.json").read_text())


def test_generated_files_are_not_stale():
    gen = runpy.run_path(str(FW / "gen_header.py"), run_name="gen")
    for path, text in gen["outputs"]().items():
        assert path.read_text("utf-8") == text, f"{path} is stale: run firmware_proto/gen_header.py"
    vec = runpy.run_path(str(FW / "gen_vectors.py"), run_name="gen")
    assert vec["OUT"].read_text("utf-8") == vec["render"](), "run firmware_proto/gen_vectors.py"


def test_packaged_yaml_equals_source():
    assert (ROOT / "guardid/protocol/messages.yaml").read_bytes() == (
        FW / "messages.yaml"
    ).read_bytes()


@pytest.mark.parametrize("vec", VECTORS["frames"], ids=lambda v: f"{v['name']}-{v['seq']}")
def test_golden_vector(vec):
    msg = unflatten(vec["name"], vec["flat"], vec["n_joints"])
    assert P.encode(msg, vec["seq"]).hex() == vec["hex"]
    frame = P.decode(bytes.fromhex(vec["hex"]))
    assert frame == P.Frame(vec["msg_id"], vec["seq"], msg)
    assert {k: list(v) if isinstance(v, tuple) else v for k, v in msg._asdict().items()} == vec[
        "fields"
    ]


@pytest.mark.parametrize("vec", VECTORS["bad_frames"], ids=lambda v: v["kind"])
def test_bad_vector(vec):
    assert P.decode(bytes.fromhex(vec["hex"])) == vec["kind"]


def message_strategy(name: str | None = None):
    """Hypothesis strategy of messages (all kinds, or only ``name``), any joint count."""

    def for_spec(spec):
        def build(n):
            args = [
                st.tuples(*[st.integers(f.lo, f.hi)] * n)
                if f.per_joint
                else st.integers(f.lo, f.hi)
                for f in spec.fields
            ]
            return st.tuples(*args).map(lambda a: P.MESSAGES[spec.name](*a))

        return st.integers(1, P.MAX_JOINTS).flatmap(build) if spec.per_joint else build(0)

    specs = [P.SPEC.by_name(name)] if name else list(P.SPEC.messages)
    return st.sampled_from(specs).flatmap(for_spec)


@pytest.mark.parametrize("name", [m.name for m in P.SPEC.messages])
def test_round_trip_every_message(name):
    @settings(max_examples=60, deadline=None, derandomize=True)
    @given(msg=message_strategy(name), seq=st.integers(0, 0xFFFF))
    def check(msg, seq):
        _round_trip(msg, seq)

    check()


def _round_trip(msg, seq):
    wire = P.encode(msg, seq)
    assert wire.count(0) == 1 and wire.endswith(b"\x00")
    assert len(wire) <= P.MAX_ENCODED + 1
    assert P.decode(wire) == P.Frame(msg.MSG_ID, seq, msg)
    parser = P.FrameParser()
    assert parser.feed(wire) == [P.Frame(msg.MSG_ID, seq, msg)]
    assert unflatten(msg.SPEC.name, flatten(msg), P.n_joints_of(msg)) == msg


def test_every_message_has_a_class_and_unique_id():
    assert len(P.BY_ID) == len(P.SPEC.messages) >= 17
    for name in ("Hello", "Info", "SetPid", "SetMode", "Setpoint", "SetVoltage", "StartStream",
                 "StopStream", "Estop", "ClearEstop", "Ping", "Pong", "Ack", "Nak",
                 "Telemetry", "Fault", "SetWatchdog"):  # fmt: skip
        assert hasattr(P, name)
    assert all(m.to_host == (m.msg_id >= 0x80) for m in P.SPEC.messages)


def test_telemetry_two_joints_fits_link_budget():
    t = P.Telemetry(1, 0, 1, (1, 2), (3, 4), (5, 6), (7, 8))
    wire = len(P.encode(t, 0))
    assert wire <= 42
    assert wire * (1 / 0.015) / 11520 < 0.35


def test_encode_rejects_out_of_range_and_ragged_arrays():
    with pytest.raises(ValueError):
        P.encode(P.SetMode(256), 0)
    with pytest.raises(ValueError):
        P.encode(P.Setpoint(0, 0, (1, 2, 3, 4, 5)), 0)
    with pytest.raises(ValueError):
        P.encode(P.Telemetry(0, 0, 0, (1, 2), (1,), (1, 2), (1, 2)), 0)


def test_to_si_scales_fields():
    si = P.to_si(P.SetPid(0, 40_000_000, 10_000_000, 1_000_000))
    assert si == pytest.approx({"joint": 0, "kp": 40.0, "ki": 10.0, "kd": 1.0})
    si = P.to_si(P.Telemetry(5, 0, 1, (1, 2), (12000, -500), (250, 0), (0, 0)))
    assert si["voltage"] == pytest.approx((12.0, -0.5)) and si["current"] == pytest.approx(
        (0.25, 0)
    )


def test_encoder_numbers_and_wraps():
    enc = P.Encoder(first_seq=0xFFFF)
    frames = P.FrameParser().feed(enc.encode(P.Hello()) + enc.encode(P.Hello()))
    assert [f.seq for f in frames] == [0xFFFF, 0]


def test_readme_documents_every_message():
    readme = (FW / "README.md").read_text("utf-8")
    for m in P.SPEC.messages:
        assert f"| 0x{m.msg_id:02X} | {m.name} |" in readme, m.name
