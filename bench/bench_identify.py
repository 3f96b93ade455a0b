"""Offline identification of a one-hour log, end to end, as a multiple of real time.

Captures one hour of the optimised excitation from the simulated guard robot (lock-step,
not timed), then times guardid.identify.identify() with LS, RLS and Hopfield on it:
conditioning (filters, derivatives, alignment, stiction mask), base regressor and the three
estimators. Run: python bench/bench_identify.py [seconds of log, default 3600]
"""

from __future__ import annotations

import sys
import tempfile
import time
from pathlib import Path

from guardid.capture import capture
from guardid.excitation import load_trajectory
from guardid.identify import identify
from guardid.identify.runs import load_run
from guardid.link import Session, open_port
from guardid.robot import load_robot


def main(seconds: float = 3600.0) -> None:
    guard = load_robot("guard")
    with tempfile.TemporaryDirectory() as tmp:
        traj_path = Path(tmp) / "traj.yaml"
        from click.testing import CliRunner

        from guardid.cli import main as cli

        CliRunner().invoke(cli, ["excite", "-o", str(traj_path)], catch_exceptions=False)
        trajectory = load_trajectory(traj_path)
        log = Path(tmp) / "hour.csv"
        port = open_port("sim://guard?seed=1")
        session = Session(port)
        session.handshake()
        start = time.perf_counter()
        capture(session, guard, trajectory, seconds, log, {"robot": "guard"})
        port.close()
        print(f"captured {seconds:.0f} s of log in {time.perf_counter() - start:.1f} s")
        start = time.perf_counter()
        run = load_run(log)
        print(
            f"read the log ({log.stat().st_size / 1e6:.1f} MB): {time.perf_counter() - start:.2f} s"
        )
    start = time.perf_counter()
    result = identify(
        run.t, run.q, run.current, guard, methods=("ls", "rls", "hopfield"),
        highest_harmonic_hz=0.5,
    )  # fmt: skip
    wall = time.perf_counter() - start
    print(
        f"identify (conditioning + regressor + LS + RLS + Hopfield) on {len(run.t)} samples: "
        f"{wall:.2f} s = {seconds / wall:.0f}x real time (target >= 1000x); "
        f"{result.rows} rows after decimation"
    )


if __name__ == "__main__":
    main(float(sys.argv[1]) if len(sys.argv) > 1 else 3600.0)
