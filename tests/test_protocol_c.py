"""C codec (firmware_proto/guard_proto.c) against the Python codec, via ctypes.

The library is compiled with the host compiler into pytest's tmp_path, with
``-std=c99 -Wall -Wextra -Werror -pedantic``; the module is skipped if no compiler exists.
"""

from __future__ import annotations

import ctypes
import json
import random
import shutil
import subprocess
from pathlib import Path

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from test_protocol_codec import message_strategy
from test_protocol_parser import protocol_chunks, protocol_damaged_stream

from guardid import protocol as P
from guardid.protocol.vectors import flatten, random_message, unflatten

FW = Path(__file__).resolve().parents[1] / "firmware_proto"
VECTORS = json.loads((FW / "test_vectors.json").read_text())
CFLAGS = ["-std=c99", "-Wall", "-Wextra", "-Werror", "-pedantic", "-O2"]
STATS = ["bytes", "frames", "overflows", "cobs_errors", "short_frames", "crc_errors"]
STATS += ["bad_version", "unknown_id", "bad_length", "seq_gaps", "seq_backwards"]
STRIDE = 4 + 64


def _compiler():
    return next((c for c in ("gcc", "cc", "clang") if shutil.which(c)), None)


@pytest.fixture(scope="module")
def protocol_clib(tmp_path_factory):
    cc = _compiler()
    if cc is None:
        pytest.skip("no C compiler (gcc/cc/clang) on PATH: C codec not tested")
    out = tmp_path_factory.mktemp("cproto")
    lib = out / "libgp.so"
    srcs = [str(FW / "guard_proto.c"), str(FW / "test" / "gp_shim.c")]
    cmd = [cc, *CFLAGS, "-shared", "-fPIC", f"-I{FW}", *srcs, "-o", str(lib)]
    res = subprocess.run(cmd, capture_output=True, text=True)
    assert res.returncode == 0, res.stderr
    c = ctypes.CDLL(str(lib))
    c.shim_encode.restype = ctypes.c_size_t
    c.shim_encode.argtypes = [ctypes.c_uint8, ctypes.c_uint16, ctypes.POINTER(ctypes.c_int64),
                              ctypes.c_uint, ctypes.c_char_p]  # fmt: skip
    c.shim_feed.restype = ctypes.c_size_t
    c.shim_feed.argtypes = [ctypes.c_char_p, ctypes.c_size_t, ctypes.POINTER(ctypes.c_int64),
                            ctypes.c_size_t, ctypes.c_size_t]  # fmt: skip
    return c


def test_c_builds_standalone_without_warnings(tmp_path):
    """The codec alone (no shim) with a main, as a firmware project would build it."""
    cc = _compiler() or pytest.skip("no C compiler on PATH")
    main = tmp_path / "main.c"
    main.write_text('#include "guard_proto.h"\nint main(void) { gp_parser_t p; '
                    "gp_parser_init(&p); return (int)p.len; }\n")  # fmt: skip
    cmd = [cc, *CFLAGS, f"-I{FW}", str(FW / "guard_proto.c"), str(main), "-o", str(tmp_path / "a")]
    res = subprocess.run(cmd, capture_output=True, text=True)
    assert res.returncode == 0 and res.stderr == "", res.stderr


def c_encode(c, msg, seq) -> bytes:
    vals = flatten(msg)
    arr = (ctypes.c_int64 * max(1, len(vals)))(*vals)
    buf = ctypes.create_string_buffer(P.MAX_ENCODED + 1)
    n = c.shim_encode(msg.MSG_ID, seq, arr, P.n_joints_of(msg), buf)
    return buf.raw[:n]


def c_parse(c, data: bytes, chunks=None):
    """Frames parsed by the C parser (fresh) and its stats."""
    c.shim_reset()
    frames = []
    for chunk in chunks or [data]:
        cap = chunk.count(0) + 1
        rec = (ctypes.c_int64 * (cap * STRIDE))()
        nf = c.shim_feed(chunk, len(chunk), rec, STRIDE, cap)
        for k in range(nf):
            r = rec[k * STRIDE : (k + 1) * STRIDE]
            msg = unflatten(P.BY_ID[r[0]].SPEC.name, r[4 : 4 + r[3]], r[2])
            frames.append(P.Frame(r[0], r[1], msg))
    stats = (ctypes.c_uint32 * len(STATS))()
    c.shim_stats(stats)
    return frames, dict(zip(STATS, stats, strict=True))


def py_stats(parser):
    return {k: v for k, v in parser.stats.as_dict().items() if k in STATS}


@pytest.mark.parametrize("vec", VECTORS["frames"], ids=lambda v: f"{v['name']}-{v['seq']}")
def test_c_golden_vector(protocol_clib, vec):
    msg = unflatten(vec["name"], vec["flat"], vec["n_joints"])
    assert c_encode(protocol_clib, msg, vec["seq"]).hex() == vec["hex"]
    frames, stats = c_parse(protocol_clib, bytes.fromhex(vec["hex"]))
    assert frames == [P.Frame(vec["msg_id"], vec["seq"], msg)]


def test_c_bad_vectors(protocol_clib):
    kinds = {"cobs": "cobs_errors", "short": "short_frames", "crc": "crc_errors"}
    kinds.update({"version": "bad_version", "unknown_id": "unknown_id", "length": "bad_length"})
    for vec in VECTORS["bad_frames"]:
        frames, stats = c_parse(protocol_clib, bytes.fromhex(vec["hex"]))
        assert frames == [] and stats[kinds[vec["kind"]]] == 1 and stats["frames"] == 0, vec


def test_c_and_python_agree_on_10k_random_messages(protocol_clib):
    rng = random.Random(5)
    msgs = [(random_message(rng), rng.randint(0, 0xFFFF)) for _ in range(10_000)]
    wires = []
    for msg, seq in msgs:
        w = P.encode(msg, seq)
        assert c_encode(protocol_clib, msg, seq) == w, msg
        wires.append(w)
    frames, _ = c_parse(protocol_clib, b"".join(wires))
    assert frames == [P.Frame(m.MSG_ID, s, m) for m, s in msgs]


@pytest.mark.parametrize("name", [m.name for m in P.SPEC.messages])
def test_c_round_trip_every_message(protocol_clib, name):
    @settings(max_examples=60, deadline=None, derandomize=True)
    @given(msg=message_strategy(name), seq=st.integers(0, 0xFFFF))
    def check(msg, seq):
        wire = c_encode(protocol_clib, msg, seq)
        assert wire == P.encode(msg, seq)
        assert c_parse(protocol_clib, wire)[0] == [P.Frame(msg.MSG_ID, seq, msg)]

    check()


def test_c_parser_matches_python_on_damaged_stream(protocol_clib):
    data, intact, errors, gaps = protocol_damaged_stream(20_000, seed=11, p_damage=0.2)
    chunks = list(protocol_chunks(data, random.Random(12)))
    parser = P.FrameParser()
    py_frames = [f for ch in chunks for f in parser.feed(ch)]
    c_frames, c_stats = c_parse(protocol_clib, data, chunks)
    assert c_frames == py_frames == intact
    assert c_stats == py_stats(parser)
    assert parser.stats.errors == errors and parser.stats.seq_gaps == gaps


def test_c_parser_matches_python_on_pure_garbage(protocol_clib):
    rng = random.Random(13)
    data = bytes(rng.choice([0, 1, 2, 3, 0xFF, rng.randint(0, 255)]) for _ in range(200_000))
    parser = P.FrameParser()
    parser.feed(data)
    assert c_parse(protocol_clib, data)[1] == py_stats(parser)
