"""What ``capture --stream`` costs the capture loop.

Run: python bench/bench_live.py [--rows 20000] [--repeats 15] [--seconds 20]

1. ``UdpStream.send_row`` alone: build one 2-joint row's object, JSON-encode it, hand it to
   a non-blocking UDP socket on 127.0.0.1 (a port nobody listens on), ``--rows`` rows per
   repeat; per row [us], median and worst over ``--repeats`` repeats (wall clock,
   ``time.perf_counter`` around the loop).
2. A ``--seconds`` s lock-step capture of sim://guard (which runs as fast as the CPU
   allows) with and without ``--stream``, interleaved, 5 pairs: process CPU time [s] of
   each, median and worst of the difference per row [us].
"""

from __future__ import annotations

import argparse
import contextlib
import socket
import statistics
import tempfile
import time
from pathlib import Path

import numpy as np
from click.testing import CliRunner

from guardid.cli import main
from guardid.live.udp import UdpStream, parse_stream_url


def free_port() -> int:
    """A UDP port on 127.0.0.1 nobody listens on (bound, read, released)."""
    with contextlib.closing(socket.socket(socket.AF_INET, socket.SOCK_DGRAM)) as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def send_cost_us(rows: int, repeats: int) -> list[float]:
    target = parse_stream_url(f"udp://127.0.0.1:{free_port()}")
    rng = np.random.default_rng(1)
    counts = rng.integers(-4000, 4000, (rows, 2))
    q = counts / 4000.0
    v, i, sp = rng.normal(size=(rows, 2)), rng.normal(size=(rows, 2)), q + 0.01
    out = []
    for _ in range(repeats):
        stream = UdpStream(target, ["pan", "tilt"])
        t0 = time.perf_counter()
        for k in range(rows):
            stream.send_row(k, k * 0.015, counts[k], q[k], v[k], i[k], sp[k], 0)
        out.append((time.perf_counter() - t0) / rows * 1e6)
        stream.close()
        assert stream.sent + stream.dropped == rows
    return out


def capture_cpu_s(d: Path, traj: Path, seconds: float, *extra) -> tuple[float, int]:
    log = d / "run.csv"
    t0 = time.process_time()
    res = CliRunner().invoke(
        main,
        [
            "capture",
            "--trajectory",
            str(traj),
            "--duration",
            str(seconds),
            "--quiet",
            "--force",
            "-o",
            str(log),
            *extra,
        ],
    )
    cpu = time.process_time() - t0
    assert res.exit_code == 0, res.output
    rows = sum(1 for line in log.read_text().splitlines()[1:] if not line.startswith("#"))
    return cpu, rows


def main_() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--rows", type=int, default=20000)
    ap.add_argument("--repeats", type=int, default=15)
    ap.add_argument("--seconds", type=float, default=20.0)
    a = ap.parse_args()
    cost = send_cost_us(a.rows, a.repeats)
    print(
        f"send_row: {a.rows} rows x {a.repeats}: median {statistics.median(cost):.1f} us "
        f"per row, worst {max(cost):.1f} us"
    )
    with tempfile.TemporaryDirectory() as tmp:
        d = Path(tmp)
        traj = d / "traj.yaml"
        assert CliRunner().invoke(main, ["excite", "--no-optimise", "-o", str(traj)]).exit_code == 0
        url = f"udp://127.0.0.1:{free_port()}"
        extra_us = []
        for _ in range(5):
            plain, n = capture_cpu_s(d, traj, a.seconds)
            streamed, m = capture_cpu_s(d, traj, a.seconds, "--stream", url)
            assert n == m
            extra_us.append((streamed - plain) / n * 1e6)
        print(
            f"capture {a.seconds:g} s ({n} rows), 5 pairs: --stream adds median "
            f"{statistics.median(extra_us):.1f} us CPU per row, worst {max(extra_us):.1f} us "
            f"(sample period 15000 us)"
        )


if __name__ == "__main__":
    main_()
