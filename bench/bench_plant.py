"""Benchmark: guard plant under a plain 15 ms PID, simulated speed as a multiple of real time.

Run by hand: ``python bench/bench_plant.py [seconds]`` (default 600 s of robot time).
Prints the figure for the default plant (fitted two-revolute evaluator) and for the
generic mass_matrix_1/bias_1 path, each with the default number of RK4 sub-steps and 1.
"""

from __future__ import annotations

import sys
import time

from guardid.commands.simulate import Pid, SumOfSines
from guardid.plant import DEFAULT_SUBSTEPS, Plant
from guardid.robot import load_robot


def bench(duration: float, fast, substeps: int) -> tuple[float, float]:
    """(real-time factor, microseconds per tick) for ``duration`` s of robot time."""
    desc = load_robot("guard")
    ref = SumOfSines(desc)
    plant = Plant(desc, seed=1, q0=ref(0.0), fast=fast, substeps=substeps)
    pids = [Pid(j.pid, plant.dt, j.drive.supply_voltage) for j in desc.joints]
    ticks = int(round(duration / plant.dt))
    volts = [0.0, 0.0]
    t0 = time.perf_counter()
    for _ in range(ticks):
        s = plant.step(volts)
        r = ref(s.time)
        volts = [pids[0](r[0] - s.q_sensed[0]), pids[1](r[1] - s.q_sensed[1])]
    wall = time.perf_counter() - t0
    return duration / wall, wall / ticks * 1e6


def main() -> None:
    duration = float(sys.argv[1]) if len(sys.argv) > 1 else 600.0
    for fast, label in (("auto", "fitted 2R evaluator"), (False, "generic mass_matrix_1/bias_1")):
        for sub in sorted({DEFAULT_SUBSTEPS, 1}, reverse=True):
            factor, per_tick = bench(duration, fast, sub)
            print(f"guard + 15 ms PID, {duration:g} s, {label}, {sub} RK4 sub-steps/tick: "
                  f"{factor:.0f}x real time ({per_tick:.1f} us/tick)")  # fmt: skip


if __name__ == "__main__":
    main()
