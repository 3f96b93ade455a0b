"""CPU time (user + sys) [s] of the reproductions the test suite runs as fixtures, each in
a fresh Python process: best and median of ``--repeat`` runs, the runs interleaved.

    python bench/bench_reproduce_cpu.py [--repeat 3] [--blas-threads N] [NAME ...]

NAME: step (``seed000_step.run(0, seeds=3)``, tests/test_reproduce.py's ``step``), fast
(``seed000_fast.run(0, seeds=3)``), t1 (``seed001_table1.run(0)``, tests/conftest.py's
``seed001_table1_report``), t1x (``seed001_table1.run(0, exact_acceleration=True,
seeds=3)``); default all. ``--blas-threads``: OPENBLAS_NUM_THREADS for the runs (the
reproduce tests run on one). The guardid imported is the environment's (PYTHONPATH to
measure another tree). CPU time, not wall time: the machine is shared.
"""

from __future__ import annotations

import argparse
import os
import resource
import statistics
import subprocess
import sys

CALLS = {
    "step": "from guardid.reproduce import seed000_step as m; m.run(0, seeds=3)",
    "fast": "from guardid.reproduce import seed000_fast as m; m.run(0, seeds=3)",
    "t1": "from guardid.reproduce import seed001_table1 as m; m.run(0)",
    "t1x": "from guardid.reproduce import seed001_table1 as m; m.run(0, True, seeds=3)",
}


def cpu_of(code: str, env: dict) -> float:
    """User + sys CPU [s] of ``python -c code`` in a child process."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    subprocess.run([sys.executable, "-c", code], env=env, check=True)
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    return (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("names", nargs="*", help=f"of {', '.join(CALLS)} (default all)")
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--blas-threads", type=int, default=None)
    args = ap.parse_args()
    args.names = args.names or list(CALLS)
    if args.repeat < 1:
        ap.error("--repeat must be >= 1")
    if set(args.names) - set(CALLS):
        ap.error(f"unknown names {sorted(set(args.names) - set(CALLS))}")
    env = dict(os.environ)
    if args.blas_threads is not None:
        env["OPENBLAS_NUM_THREADS"] = str(args.blas_threads)
    import guardid

    print(f"# guardid from {os.path.dirname(guardid.__file__)}; load {os.getloadavg()[0]:.1f}")
    times: dict[str, list[float]] = {n: [] for n in args.names}
    for _ in range(args.repeat):
        for name in args.names:
            times[name].append(cpu_of(CALLS[name], env))
    for name, t in times.items():
        print(f"{name:5s} CPU best {min(t):6.1f} s  median {statistics.median(t):6.1f} s  "
              f"({', '.join(f'{x:.1f}' for x in t)})")  # fmt: skip


if __name__ == "__main__":
    main()
