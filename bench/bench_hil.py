"""Lock-step hardware-in-the-loop speed through the whole stack, as a multiple of real time.

Host session -> codec -> sim:// port -> firmware emulator (fixed-point PID) -> simulated
guard plant -> sensors -> telemetry -> parser, for a closed-loop run of sums of sines.
Run: python bench/bench_hil.py [seconds of robot time, default 600]
"""

from __future__ import annotations

import math
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


def main(robot_seconds: float = 600.0) -> None:
    rows = sines_setpoints(robot_seconds)
    n = len(rows)
    port = open_port("sim://guard?seed=1")
    session = Session(port)
    start = time.perf_counter()
    session.handshake()
    frames = 0
    for index, _ in session.track(rows):
        frames += index >= 0
    session.finish()
    wall = time.perf_counter() - start
    port.close()
    print(f"robot time {robot_seconds:.0f} s, {frames} telemetry frames, wall {wall:.2f} s")
    print(f"lock-step HIL speed: {robot_seconds / wall:.0f}x real time (target >= 200x)")
    print(f"per tick: {wall / n * 1e6:.1f} us; link errors {session.stats.errors}")


if __name__ == "__main__":
    main(float(sys.argv[1]) if len(sys.argv) > 1 else 600.0)
