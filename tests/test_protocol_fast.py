"""The protocol's C codec on the host's hot paths (guardid.protocol.fastcodec) gives what the
Python path gives: the same bytes, frames, numbering, errors and counters.

Truth: the Python codec's ``encode`` of whole messages, the golden vectors, the exact
damage counts of tests/test_protocol_parser.py's stream, and the Python path itself
(``fastcodec`` off) for whole lock-step runs, clean and faulty.
"""

from __future__ import annotations

import collections
import os
import random
import sys

import numpy as np
import pytest
import test_lean_stack as lean
import test_protocol_parser as fuzz

from guardid import protocol as P
from guardid.link import Session, open_port
from guardid.link.session import LazyRows, Telemetry
from guardid.native import find_compiler
from guardid.protocol import fastcodec
from guardid.protocol.vectors import random_message

pytestmark = pytest.mark.skipif(
    find_compiler() is None or os.environ.get("GUARDID_NATIVE") == "0", reason="needs a C compiler"
)
M = P.MESSAGES


def test_rows_packer_gives_the_frames_of_each_message_across_both_wraps():
    """Ticks across the u32 wrap, numbers across the u16 wrap, rows from a list or a
    LazyRows: the bytes of ``encode`` per message."""
    rows = [[k * 1000 - 2**31 + 5, -k] for k in range(6)]
    lazy = LazyRows(6, lambda a, b: rows[a:b], chunk=4)
    cases = [(M["SETPOINT"], 2, rows, lambda r: ((r[0], r[1]),)),
             (M["SETPOINT_FF"], 1, lazy, lambda r: ((r[0],), (r[1],)))]  # fmt: skip
    for cls, n, data, arrays in cases:
        enc = P.Encoder(65533)
        got = enc.rows_packer(cls, n)(2**32 - 3, 1, data, 1, 5)
        ticks = [(2**32 - 3 + i) % 2**32 for i in range(5)]
        msgs = [cls(tick, 1, *arrays(rows[1 + i])) for i, tick in enumerate(ticks)]
        want = b"".join(P.encode(m, (65533 + i) % 65536) for i, m in enumerate(msgs))
        assert got == want and enc.seq == 2


def test_rows_packer_refuses_a_value_out_of_range_after_the_rows_before_it():
    rows = [[1, 2], [3, 4], [2**31, 0], [5, 6]]  # position is i32
    for module in (fastcodec.module(), None):
        fastcodec._module = module
        try:
            enc = P.Encoder(10)
            with pytest.raises(ValueError, match="SETPOINT: "):
                enc.rows_packer(M["SETPOINT"], 2)(100, 0, rows, 0, 4)
        finally:
            fastcodec._module = False
        assert enc.seq == 12  # the two frames before it numbered, as one at a time


@pytest.mark.parametrize("value", [2**31, -(2**31) - 1, 2**70, 1.0])
def test_fast_packer_refuses_what_struct_refuses(value):
    enc = P.Encoder(3)
    with pytest.raises(ValueError, match="SETPOINT"):
        enc.packer(M["SETPOINT"], 2)(1, 0, value, 0)
    assert enc.seq == 3


def test_fast_packer_takes_the_extremes_of_each_field():
    spec = M["TELEMETRY"].SPEC
    for pick in (lambda f: f.lo, lambda f: f.hi):
        flat = [pick(f) for f in spec.fixed] + [pick(f) for f in spec.per_joint for _ in (0, 1)]
        want = P.encode(M["TELEMETRY"](*flat[:3], *(tuple(flat[3 + 2 * k : 5 + 2 * k])
                                                     for k in range(4))), 9)  # fmt: skip
        assert P.Encoder(9).packer(M["TELEMETRY"], 2)(*flat) == want


def _telemetry_message(rng: random.Random):
    """Mostly 2-joint TELEMETRY (the C scan's stream), now and then any message."""
    if rng.random() < 0.1:
        return random_message(rng)
    pair = lambda lo, hi: (rng.randint(lo, hi), rng.randint(lo, hi))  # noqa: E731
    return M["TELEMETRY"](rng.randint(0, 2**32 - 1), rng.randint(0, 255), 1,
                          pair(-(2**31), 2**31 - 1), pair(-32768, 32767),
                          pair(-32768, 32767), pair(-(2**31), 2**31 - 1))  # fmt: skip


def test_damaged_telemetry_stream_gives_the_exact_counts(monkeypatch):
    """tests/test_protocol_parser.py's damage (flips, drops, duplicates, merges, garbage,
    idle fill) on a stream of mostly telemetry, in random chunks: every intact frame, the
    exact error and gap counts; most frames through the C scan."""
    monkeypatch.setattr(fuzz, "random_message", _telemetry_message)
    data, intact, errors, gaps = fuzz.protocol_damaged_stream(20_000, seed=5, p_damage=0.05)
    parser, scanned = P.FrameParser(), []
    scan = parser._scan
    parser._scan = lambda *a: (res := scan(*a), scanned.append(len(res[0])))[0]
    got = []
    for chunk in fuzz.protocol_chunks(data, random.Random(6)):
        got += parser.feed(chunk)
    st = parser.stats
    assert got == intact and st.errors == errors and st.seq_gaps == gaps
    assert st.frames == len(intact) and st.crc_errors > 0 and st.cobs_errors > 0
    assert sum(scanned) > len(intact) / 3


def test_routed_telemetry_reaches_a_deque_or_a_function_in_order():
    enc = P.Encoder(65530)
    pack = enc.packer(M["TELEMETRY"], 2)
    rows = [(k, 0, 1, k, -k, 2, 3, 4, 5, 6, 7) for k in range(12)]
    stream = b"".join(pack(*r) for r in rows)
    for kind in ("deque", "function"):
        parser, box, called = P.FrameParser(), collections.deque(), []
        route = box.append if kind == "deque" else called.append.__call__  # not a bound append
        parser.route(M["TELEMETRY"].MSG_ID, Telemetry, route)
        for k in range(0, len(stream), 100):
            parser.feed(stream[k : k + 100])
        got = list(box) if kind == "deque" else called
        assert [t.tick for t in got] == list(range(12)) and parser.stats.frames == 12
        assert got[5] == Telemetry(5, 0, 1, (5, -5), (2, 3), (4, 5), (6, 7))


class _EmptySink(list):
    """A sink that is falsy while empty (a collection with a __call__)."""

    def __call__(self, msg):
        self.append(msg)


def test_a_sink_that_is_falsy_gets_messages_not_frames():
    """The scan wraps messages in Frame only where no route takes them: ``if sink`` would
    take an empty collection's sink for no route and hand it Frame tuples."""
    pack = P.Encoder(0).packer(M["TELEMETRY"], 2)
    sink, parser = _EmptySink(), P.FrameParser()
    parser.route(M["TELEMETRY"].MSG_ID, Telemetry, sink)
    parser.feed(pack(1, 0, 1, 1, 2, 3, 4, 5, 6, 7, 8))  # the Python path: its kind known
    sink.clear()
    parser.feed(b"".join(pack(k, 0, 1, k, 2, 3, 4, 5, 6, 7, 8) for k in (2, 3)))  # the scan
    assert sink == [Telemetry(k, 0, 1, (k, 2), (3, 4), (5, 6), (7, 8)) for k in (2, 3)]


@pytest.mark.parametrize("n_fixed", [-1, -(2**40), 65])
def test_scan_refuses_a_fixed_field_count_out_of_range(n_fixed):
    """A negative count would index the value array and the new tuple before their start."""
    frame = P.Encoder(0).packer(M["TELEMETRY"], 2)(1, 0, 1, 1, 2, 3, 4, 5, 6, 7, 8)
    with pytest.raises(ValueError, match="n_fixed"):
        fastcodec.module().scan(frame, M["TELEMETRY"].MSG_ID, len(frame) - 2, -1, n_fixed,
                                tuple, None)  # fmt: skip


def _lockstep_run(url: str, ticks: int):
    """(bytes read, bytes written, counters, telemetry) of a run-ahead closed-loop run."""
    port = lean.AheadRecorder(open_port(url))
    try:
        session = Session(port)
        session.handshake()
        t = np.arange(ticks) * 0.015
        rows = np.column_stack([900 * np.sin(1.3 * t), 400 * np.sin(2.1 * t) + 300])
        seen = [tm for _, tm in session.track(rows.astype(int), run_ahead=True)]
        session.finish()
        return bytes(port.received), bytes(port.sent), session.stats.as_dict(), seen
    finally:
        port.close()


@pytest.mark.parametrize("query", ["seed=3", "seed=6&drop=2e-3&flip=1e-3&upstream=1"])
def test_lockstep_run_is_the_same_with_the_python_codec(query, monkeypatch):
    """Both directions' bytes, the host's counters and telemetry: C codec against Python
    codec, on a clean link and on one that drops and flips bytes both ways."""
    fast = _lockstep_run(f"sim://guard?{query}", 300)
    monkeypatch.setattr(fastcodec, "_module", None)
    slow = _lockstep_run(f"sim://guard?{query}", 300)
    assert fast == slow
    if "drop" in query:
        assert fast[2]["crc_errors"] + fast[2]["cobs_errors"] > 0


def test_the_c_codec_is_built_where_a_compiler_is():
    assert fastcodec.module() is not None  # else the tests above compare Python with itself


def test_a_compile_error_warns_and_means_the_python_path(monkeypatch, tmp_path):
    bad = tmp_path / "host" / "gp_pyext.c"
    bad.parent.mkdir()
    bad.write_text("int broken(void) { int unused; return 1; }\n")  # -Werror: unused
    for name in fastcodec.SOURCES[1:]:
        (tmp_path / name).write_bytes((fastcodec.FIRMWARE_DIR / name).read_bytes())
    monkeypatch.setattr(fastcodec, "FIRMWARE_DIR", tmp_path)
    monkeypatch.setenv("GUARDID_CACHE_DIR", str(tmp_path / "cache"))
    with pytest.warns(UserWarning, match="C fast path is off: building gp_pyext failed"):
        assert fastcodec._load() is None


def test_a_cache_it_cannot_write_warns_and_means_the_python_path(monkeypatch, tmp_path):
    """The cache directory under a file (as a read-only home would): a warning and the
    Python path, not an OSError out of every Encoder and FrameParser (a capture stopped)."""
    (tmp_path / "file").write_text("")
    monkeypatch.setenv("GUARDID_CACHE_DIR", str(tmp_path / "file" / "cache"))
    with pytest.warns(UserWarning, match="C fast path is off: .*Not a directory"):
        assert fastcodec._load() is None


def test_no_compiler_or_switched_off_means_the_python_path(monkeypatch):
    monkeypatch.setenv("GUARDID_NATIVE", "0")
    assert fastcodec._load() is None
    monkeypatch.delenv("GUARDID_NATIVE")
    monkeypatch.setenv("CC", "/nonexistent/cc")
    assert find_compiler() is None and fastcodec._load() is None
    monkeypatch.setattr(fastcodec, "_module", None)
    parser = P.FrameParser()
    assert parser._scan is None
    frame = P.encode(M["PING"](5), 1)
    assert parser.feed(frame + frame) == [P.Frame(2, 1, M["PING"](5))] * 2


def test_a_python_from_max_python_on_means_the_python_path(monkeypatch):
    monkeypatch.setattr(fastcodec, "MAX_PYTHON", tuple(sys.version_info[:2]))
    assert fastcodec._load() is None
    monkeypatch.setattr(fastcodec, "MAX_PYTHON", (sys.version_info[0] + 1, 0))
    assert fastcodec._load() is not None
