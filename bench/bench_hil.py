"""Lock-step hardware-in-the-loop speed through the whole stack, as a multiple of real time.

Host session -> codec -> sim:// port -> firmware emulator (fixed-point PID) -> simulated
guard plant -> sensors -> telemetry -> parser, for a closed-loop run of sums of sines
(``Session.track(run_ahead=True)``, as ``guardid capture`` runs it without --until-std).
Prints the median over runs (and the worst) by wall clock, and by CPU time, which a busy
machine disturbs less. Run: python bench/bench_hil.py [robot seconds per run, default 60]
[runs, default 5]

``--vs-plant`` (``python bench/bench_hil.py --vs-plant [seconds] [runs]``): the plant alone
against the whole stack, by CPU time, in interleaved pairs (the order alternating): the plant
of the same ``sim://`` port (same seed) stepped with the very voltages the stack's firmware
applied (recorded in a first, untimed run), against the whole stack's run; prints per pair
the plant's and the stack's CPU per tick [us] and the ratio plant / stack (1 would mean the
stack costs nothing beyond its plant), then the median and the worst ratio.
"""

from __future__ import annotations

import math
import os
import statistics
import sys
import time

import numpy as np

from guardid.fakeport import register_device_factory
from guardid.fakeport.options import parse_sim_url
from guardid.firmware import make_sim_device
from guardid.link import Session, open_port
from guardid.plant import make_plant
from guardid.robot import load_robot

URL = "sim://guard?seed=1"


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
    port = open_port(URL)
    session = Session(port)
    start, cpu = time.perf_counter(), time.process_time()
    session.handshake()
    frames = 0
    for index, _ in session.track(rows, run_ahead=True):
        frames += index >= 0
    session.finish()
    wall, cpu = time.perf_counter() - start, time.process_time() - cpu
    port.close()
    return wall, cpu, frames, session.stats.errors


def applied_voltages(rows) -> list:
    """The voltages [V] the firmware applies to its plant at every tick of a run of
    ``rows`` (a run of the stack, untimed, with the plant's input recorded)."""
    volts = []

    def factory(robot, options):
        device = make_sim_device(robot, options)
        read_plant = device._read_plant

        def recorded(u):
            volts.append(list(u))
            return read_plant(u)

        device._read_plant = recorded
        return device

    old = register_device_factory(factory)
    try:
        one_run(rows)
    finally:
        register_device_factory(old)
    return volts


def plant_alone(volts) -> float:
    """CPU seconds of the port's plant stepped through ``volts`` (as the firmware reads it)."""
    options = parse_sim_url(URL)
    plant = make_plant(load_robot(options.robot), options)
    step = getattr(plant, "step_sensors", None) or plant.step
    cpu = time.process_time()
    for u in volts:
        step(u)
    return time.process_time() - cpu


def vs_plant(robot_seconds: float = 60.0, runs: int = 5) -> None:
    """Plant alone against the whole stack, CPU per tick, ``runs`` interleaved pairs."""
    rows = sines_setpoints(robot_seconds)
    volts = applied_voltages(rows)
    n = len(volts)  # plant steps, the same in both
    ratios = []
    print(f"{robot_seconds:g} s of robot time ({n} ticks) per run, {URL}, CPU time")
    for k in range(runs):
        if k % 2:
            stack = one_run(rows)[1]
            plant = plant_alone(volts)
        else:
            plant = plant_alone(volts)
            stack = one_run(rows)[1]
        ratios.append(plant / stack)
        print(f"pair {k + 1}: plant alone {plant / n * 1e6:.1f} us/tick, whole stack "
              f"{stack / n * 1e6:.1f} us/tick (adds {(stack - plant) / n * 1e6:.1f}), "
              f"ratio {plant / stack:.2f}")  # fmt: skip
    print(f"ratio plant alone / whole stack (CPU): median {statistics.median(ratios):.2f}, "
          f"worst {min(ratios):.2f} over {runs} pairs (target >= 0.7); load average "
          f"{os.getloadavg()[0]:.1f}")  # fmt: skip


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
    args = [a for a in sys.argv[1:] if a != "--vs-plant"]
    (vs_plant if "--vs-plant" in sys.argv else main)(
        float(args[0]) if args else 60.0, int(args[1]) if len(args) > 1 else 5
    )
