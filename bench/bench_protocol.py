"""Wire protocol figures: parser throughput and link budget (run by hand).

``python bench/bench_protocol.py [--frames N]`` prints the Python parser throughput on a
recorded-like 2-joint telemetry stream (frames/s, fed in 4 KiB chunks as serial reads
return them), the bytes per telemetry frame on the wire and the link utilisation at
115200 baud 8N1 (11520 bytes/s) at 66.7 frames/s. Targets: >= 1e5 frames/s, < 35 %.
"""

from __future__ import annotations

import argparse
import math
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # run from a source checkout

from guardid import protocol as P  # noqa: E402

BAUD_BYTES_PER_S = 115200 / 10  # 8N1: 10 bits per byte
FRAME_RATE = 1 / 0.015  # frames/s, one telemetry frame per 15 ms tick
COUNTS_PER_RAD = (24000 / (2 * math.pi), 48000 / (2 * math.pi))


def telemetry_stream(n: int) -> bytes:
    """A synthetic recording: 2 joints tracking sums of sines, PID-like voltages."""
    enc = P.Encoder()
    out = []
    for k in range(n):
        t = k * 0.015
        q = (1.0 * math.sin(0.7 * t) + 0.3 * math.sin(2.1 * t), 0.3 * math.sin(1.3 * t))
        pos = tuple(int(qi * c) for qi, c in zip(q, COUNTS_PER_RAD, strict=True))
        volt = tuple(int(6000 * math.cos(w * t)) for w in (0.7, 1.3))
        cur = tuple(int(400 * math.sin(w * t + 0.3)) for w in (0.7, 1.3))
        sp = tuple(p + 5 for p in pos)
        out.append(enc.encode(P.Telemetry(k, 0, 1, pos, volt, cur, sp)))
    return b"".join(out)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--frames", type=int, default=200_000)
    args = ap.parse_args()
    data = telemetry_stream(args.frames)
    chunks = [data[i : i + 4096] for i in range(0, len(data), 4096)]
    best = math.inf
    for _ in range(3):
        parser = P.FrameParser()
        t0 = time.perf_counter()
        n = sum(len(parser.feed(c)) for c in chunks)
        best = min(best, time.perf_counter() - t0)
        assert n == args.frames and parser.stats.errors == 0
    t0 = time.perf_counter()
    enc = P.Encoder()
    msg = P.Telemetry(1, 0, 1, (1000, -2000), (6000, -6000), (300, -300), (1005, -1995))
    for _ in range(50_000):
        enc.encode(msg)
    enc_rate = 50_000 / (time.perf_counter() - t0)
    frame_bytes = len(data) / args.frames
    util = frame_bytes * FRAME_RATE / BAUD_BYTES_PER_S
    print(f"parser throughput      : {args.frames / best:12,.0f} frames/s (target >= 100,000)")
    print(f"parser byte rate       : {len(data) / best / 1e6:12.1f} MB/s")
    print(f"encoder throughput     : {enc_rate:12,.0f} frames/s")
    print(f"telemetry frame (2 jt) : {frame_bytes:12.1f} bytes on the wire (incl. delimiter)")
    print(f"link at 66.7 frames/s  : {frame_bytes * FRAME_RATE:12.0f} bytes/s of 11520")
    print(f"link utilisation       : {100 * util:12.1f} % (target < 35 %)")


if __name__ == "__main__":
    main()
