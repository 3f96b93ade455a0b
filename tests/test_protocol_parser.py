"""FrameParser: chunking, resync, bounded buffer, and the 10^5-frame damage fuzz.

Why the expected counts are exact: every damage event touches exactly one segment (the
bytes between two 0x00 delimiters) and never creates a 0x00 (bit flips are chosen so the
flipped byte is non-zero; garbage is drawn from 1..255; duplicated bytes are copies of
non-zero bytes), except "merge", which removes exactly one delimiter and so turns two
frames into one segment. Each non-empty segment is either one valid frame or exactly one
counted error (the parser stops at the first failing check). A damaged segment could only
pass if the damage kept the CRC-32 right (probability 2**-32 per segment); the test is
seeded, so its outcome is fixed. Lost frames are frames of a direction after its first
and before its last recovered frame, so each one shows up exactly once as a sequence gap.
"""

from __future__ import annotations

import json
import random
from pathlib import Path

from guardid import protocol as P
from guardid.protocol.vectors import random_message

N_FRAMES = 100_000


def protocol_damaged_stream(n_frames: int, seed: int, p_damage: float = 0.1):
    """(wire bytes, intact frames in order, expected error count, expected seq gaps)."""
    rng = random.Random(seed)
    encoders = [P.Encoder(rng.randint(0, 0xFFFF)), P.Encoder(rng.randint(0, 0xFFFF))]
    frames, wires = [], []
    for _ in range(n_frames):
        msg = random_message(rng)
        enc = encoders[msg.MSG_ID >> 7]
        frames.append(P.Frame(msg.MSG_ID, enc.seq, msg))
        wires.append(enc.encode(msg))
    lost = [False] * n_frames
    errors = 0
    out = []
    i = 0
    while i < n_frames:
        w = wires[i]
        kind = rng.choice(["flip", "drop", "dup", "dupdelim", "merge", "garbage"])
        if (
            rng.random() >= p_damage
            or i in (0, n_frames - 1)
            or (kind == "merge" and i + 2 >= n_frames)
        ):
            out.append(w)
            i += 1
            continue
        body = bytearray(w[:-1])
        k = rng.randrange(len(body))
        if kind == "flip":
            bits = [b for b in range(8) if body[k] ^ (1 << b)]
            body[k] ^= 1 << rng.choice(bits)
            out.append(bytes(body) + b"\x00")
            lost[i] = True
        elif kind == "drop":
            del body[k]
            out.append(bytes(body) + b"\x00")
            lost[i] = True
        elif kind == "dup":
            body.insert(k, body[k])
            out.append(bytes(body) + b"\x00")
            lost[i] = True
        elif kind == "dupdelim":
            out.append(w + b"\x00")  # the extra empty segment is idle fill: no error
            i += 1
            continue
        elif kind == "merge":
            out.append(bytes(body) + wires[i + 1])
            lost[i] = lost[i + 1] = True
            i += 1
        else:  # garbage segment before an intact frame
            n = rng.choice([rng.randint(1, 40), rng.randint(60, 300)])
            out.append(bytes(rng.randint(1, 255) for _ in range(n)) + b"\x00" + w)
        errors += 1
        i += 1
    intact = [f for f, gone in zip(frames, lost, strict=True) if not gone]
    gaps = 0
    for d in (0, 1):
        idx = [j for j, f in enumerate(frames) if f.msg_id >> 7 == d]
        keep = [j for j in idx if not lost[j]]
        gaps += sum(1 for j in idx if lost[j] and keep[0] < j < keep[-1])
    return b"".join(out), intact, errors, gaps


def protocol_chunks(data: bytes, rng: random.Random, max_chunk: int = 700):
    i = 0
    while i < len(data):
        n = rng.randint(1, max_chunk)
        yield data[i : i + n]
        i += n


def test_fuzz_damage_counts_are_exact():
    data, intact, errors, gaps = protocol_damaged_stream(N_FRAMES, seed=1)
    parser = P.FrameParser()
    got = []
    for chunk in protocol_chunks(data, random.Random(2)):
        got.extend(parser.feed(chunk))
    st = parser.stats
    assert got == intact  # nothing invented, every untouched frame recovered, in order
    assert st.errors == errors
    assert st.seq_gaps == gaps
    assert st.seq_backwards == 0
    assert st.frames == len(intact) and st.bytes == len(data)
    assert st.overflows > 0 and st.crc_errors > 0 and st.cobs_errors > 0


def test_byte_at_a_time_equals_one_chunk():
    data, intact, errors, _ = protocol_damaged_stream(2000, seed=3, p_damage=0.3)
    a, b = P.FrameParser(), P.FrameParser()
    got_a = a.feed(data)
    got_b = [f for i in range(len(data)) for f in b.feed(data[i : i + 1])]
    assert got_a == got_b == intact
    assert a.stats == b.stats and a.stats.errors == errors


def test_overlong_garbage_is_dropped_and_buffer_stays_bounded():
    parser = P.FrameParser()
    frame = P.encode(P.Ping(7), 0)
    for _ in range(100):
        assert parser.feed(b"\x55" * 1000) == []
        assert len(parser._buf) <= P.MAX_ENCODED
    assert parser.feed(b"\x00" + frame) == [P.Frame(P.Ping.MSG_ID, 0, P.Ping(7))]
    assert parser.stats.overflows == 1 and parser.stats.errors == 1


def test_segment_at_the_size_limit_is_decoded_not_overflowed():
    parser = P.FrameParser()
    parser.feed(b"\x55" * P.MAX_ENCODED + b"\x00")
    parser.feed(b"\x55" * (P.MAX_ENCODED + 1) + b"\x00")
    assert parser.stats.overflows == 1 and parser.stats.errors == 2


def test_sequence_gaps_per_direction_and_backwards():
    parser = P.FrameParser()
    wire = b"".join(
        [P.encode(P.Hello(), 10), P.encode(P.Ack(0, 1), 500), P.encode(P.Hello(), 13)]
        + [P.encode(P.Ack(0, 1), 501), P.encode(P.Ack(0, 1), 400)]
    )
    assert len(parser.feed(wire)) == 5
    assert parser.stats.seq_gaps == 2 and parser.stats.seq_backwards == 1


def test_idle_delimiters_are_not_errors():
    parser = P.FrameParser()
    assert len(parser.feed(b"\x00\x00" + P.encode(P.Hello(), 0) + b"\x00\x00")) == 1
    assert parser.stats.errors == 0


# The golden bad frames (firmware_proto/test_vectors.json, one per rejection reason), each
# with the counter that names its reason; test_c_bad_vectors holds the C parser to them.
BAD_KINDS = {
    "cobs": "cobs_errors",
    "short": "short_frames",
    "crc": "crc_errors",
    "version": "bad_version",
    "unknown_id": "unknown_id",
    "length": "bad_length",
}


def test_streaming_parser_drops_every_golden_bad_frame():
    """Promise: FrameParser.feed yields no frame for a rejected segment and counts it once
    under its own reason, as the C parser does. The 'version' vector is a well-formed PING
    (msg 2, seq 7, nonce 1234, CRC right) whose version byte is 2: only the version check
    stops it. Each vector goes to a fresh parser, then to one that has just parsed a PING
    (seq 6: the same message kind and length), which takes the scanned path of that kind."""
    vectors = json.loads(
        (Path(__file__).resolve().parents[1] / "firmware_proto/test_vectors.json").read_text()
    )["bad_frames"]
    assert sorted(v["kind"] for v in vectors) == sorted(BAD_KINDS)
    for vec in vectors:
        wire = bytes.fromhex(vec["hex"])
        fresh = P.FrameParser()
        assert fresh.feed(wire) == [], vec
        st = fresh.stats
        assert getattr(st, BAD_KINDS[vec["kind"]]) == 1 and st.errors == 1, (vec, st)
        assert st.frames == 0 and st.seq_gaps == 0, (vec, st)

        primed = P.FrameParser()
        ping = P.Frame(P.Ping.MSG_ID, 6, P.Ping(1234))
        assert primed.feed(P.encode(ping.msg, ping.seq)) == [ping]
        assert primed.feed(wire) == [], vec
        st = primed.stats
        assert getattr(st, BAD_KINDS[vec["kind"]]) == 1 and st.errors == 1, (vec, st)
        assert st.frames == 1 and st.seq_gaps == 0, (vec, st)
