"""Lock-step hardware-in-the-loop speed through the whole stack, as a multiple of real time.

Host session -> codec -> sim:// port -> firmware emulator (fixed-point PID) -> simulated
guard plant -> sensors -> telemetry -> parser, for a closed-loop run of sums of sines.
Prints the median over runs (and the worst) by wall clock, and by CPU time, which a busy
machine disturbs less. Run: python bench/bench_hil.py [robot seconds per run, default 60]
[runs, default 5]
"""

from __future__ import annotations

import math
import os
import statistics
import sys
import time

import numpy as np

from guardid.link import Session, open_port
from guardid.robot import load_robot


def sines_setpoints(robot_seconds: float) -> np.ndarray:
    """(n, 2) guard setpoints [counts], one row per 15 ms tick: sums of sines in range."""
    guard = load_robot("guard")
    period = guard.sample_period
    t = np.arange(int(robot_seconds / period)) * period
    q = np.column_stack(
        [0.5 * np.sin(2 * np.pi * 0.1 * t), 0.2 + 0.12 * np.sin(2 * np.pi * 0.13 * t)]
    )
    per_rad = np.array([48 * 500, 48 * 1000]) / (2 * math.pi)
    return np.rint(q * per_rad).astype(np.int64)


def one_run(rows) -> tuple[float, float, int, int]:
    """(wall s, CPU s, telemetry frames, link errors) of one lock-step run over ``rows``."""
    port = open_port("sim://guard?seed=1")
    session = Session(port)
    start, cpu = time.perf_counter(), time.process_time()
    session.handshake()
    frames = 0
    for index, _ in session.track(rows):
        frames += index >= 0
    session.finish()
    wall, cpu = time.perf_counter() - start, time.process_time() - cpu
    port.close()
    return wall, cpu, frames, session.stats.errors


def main(robot_seconds: float = 60.0, runs: int = 5) -> None:
    rows = sines_setpoints(robot_seconds)
    n = len(rows)
    results = [one_run(rows) for _ in range(runs)]
    walls = sorted(r[0] for r in results)
    cpus = sorted(r[1] for r in results)
    wall, cpu = statistics.median(walls), statistics.median(cpus)
    print(f"robot time {robot_seconds:.0f} s x {runs} runs, {results[0][2]} telemetry frames, "
          f"link errors {sum(r[3] for r in results)}")  # fmt: skip
    print(
        f"lock-step HIL speed: median {robot_seconds / wall:.0f}x real time by wall clock "
        f"(worst {robot_seconds / walls[-1]:.0f}x), {robot_seconds / cpu:.0f}x by CPU time "
        f"(target >= 200x); load average {os.getloadavg()[0]:.1f}"
    )
    print(f"per tick: median {wall / n * 1e6:.1f} us wall, {cpu / n * 1e6:.1f} us CPU")


if __name__ == "__main__":
    main(
        float(sys.argv[1]) if len(sys.argv) > 1 else 60.0,
        int(sys.argv[2]) if len(sys.argv) > 2 else 5,
    )
