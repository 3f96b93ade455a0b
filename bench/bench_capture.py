"""Wall time of a 60 s ``guardid capture`` from ``sim://guard`` after start-up, per seed.

Runs the whole command (``guardid capture --quiet``, in this process through click's test
runner, lock-step ``sim://guard?seed=N``) on a ``guardid excite --no-optimise`` trajectory,
once per seed. "After start-up" is the log footer's ``wall_time_s``: from just after the
handshake (the log is created then) to the footer. CPU time is that of the whole command
in this process (start-up included), which a busy machine disturbs less than the wall
clock. Prints the median and the worst over the seeds.
Run: python bench/bench_capture.py [robot seconds, default 60] [seeds, default 15]
"""

from __future__ import annotations

import os
import statistics
import sys
import tempfile
import time
from pathlib import Path

from click.testing import CliRunner

from guardid.cli import main
from guardid.log import read_log


def run_one(runner: CliRunner, traj: Path, out: Path, seconds: float, seed: int):
    """(footer wall time after start-up [s], command CPU [s], rows) of one capture."""
    args = ["capture", "--quiet", "--port", f"sim://guard?seed={seed}", "--trajectory",
            str(traj), "--duration", f"{seconds:g}", "-o", str(out)]  # fmt: skip
    cpu = time.process_time()
    result = runner.invoke(main, args, catch_exceptions=False)
    cpu = time.process_time() - cpu
    if result.exit_code != 0:
        raise SystemExit(f"capture failed (exit {result.exit_code}): {result.output}")
    log = read_log(out)
    return float(log.footer["wall_time_s"]), cpu, len(log.columns["tick"])


def main_bench(seconds: float = 60.0, seeds: int = 15) -> None:
    runner = CliRunner()
    with tempfile.TemporaryDirectory() as tmp:
        traj = Path(tmp) / "traj.yaml"
        made = runner.invoke(main, ["excite", "--robot", "guard", "--no-optimise", "-o", str(traj)])
        if made.exit_code != 0:
            raise SystemExit(f"excite failed: {made.output}")
        runs = [
            run_one(runner, traj, Path(tmp) / f"run{s}.csv", seconds, s)
            for s in range(1, seeds + 1)
        ]
    walls, cpus = sorted(r[0] for r in runs), sorted(r[1] for r in runs)
    print(f"{seconds:g} s capture x {seeds} seeds, rows per run {sorted({r[2] for r in runs})}")
    print(
        f"wall after start-up: median {statistics.median(walls):.3f} s, worst {walls[-1]:.3f} s "
        f"(target < 1 s); whole command CPU: median {statistics.median(cpus):.3f} s, "
        f"worst {cpus[-1]:.3f} s; load average {os.getloadavg()[0]:.1f}"
    )


if __name__ == "__main__":
    main_bench(
        float(sys.argv[1]) if len(sys.argv) > 1 else 60.0,
        int(sys.argv[2]) if len(sys.argv) > 2 else 15,
    )
