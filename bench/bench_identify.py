"""`guardid identify` as a user runs it, on a one-hour and a four-hour capture: wall time,
CPU time and peak memory of the whole command, and reading the one-hour log (``read_log``
once, and every read ``guardid identify`` makes of its log: three in older trees, one now).

The captures are made once and cached (``--cache``, default <tmp>/guardid-bench-cache):
one hour of the optimised excitation (``guardid excite``) captured from ``sim://guard`` in
lock-step; the four-hour log is that hour's rows four times over, ticks continuing with a
gap of 100 ticks at each join (lost rows: the conditioning restarts there, as it would
after a real gap; the excitation is periodic, so each hour is a whole number of periods).

Each command runs as a subprocess ``--runs`` times; the figures are the median and the worst
run. CPU time includes the command's own children (``guardid identify`` replays the
tracker in a forked process while it fits); peak memory is the largest maximum resident set
of the command and its children (``os.wait4``; each process counts the pages it shares with
the other). ``--reads-only`` times the reads alone (a cheap paired run against an old
tree, whose identify takes minutes). ``--baseline DIR``
runs the same commands with another source tree first on ``PYTHONPATH`` (for example
``git worktree add /tmp/old main``), alternating with this one, and prints the ratios
old/new of the medians: paired figures from the same run on the same (possibly busy) machine.

    python bench/bench_identify.py [--hours 1 4] [--runs 3] [--baseline DIR] [--reads-only]
"""

from __future__ import annotations

import argparse
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

READ_SNIPPET = (
    "import sys, time; from guardid.log import read_log; s = time.process_time(); "
    "d = read_log(sys.argv[1]); print(time.process_time() - s, len(d.columns['tick']))"
)

CLI_READ_SNIPPET = (  # the reads of guardid identify: the run, the header's harmonic, the
    # tracker's (a6256d5 read the header again for each; the run carries it now)
    "import importlib, sys, time; I = importlib.import_module('guardid.commands.identify'); "
    "from guardid.online.offline import log_highest_harmonic; s = time.process_time(); "
    "run, d = I._load(sys.argv[1], None, (), None, None, None); "
    "hasattr(run, 'highest_harmonic_hz') or log_highest_harmonic(sys.argv[1]); "
    "print(time.process_time() - s, len(run.t))"
)


def hour_log(cache: Path) -> Path:
    """The cached one-hour capture (made on first use)."""
    log = cache / "hour.csv"
    if log.exists():
        return log
    cache.mkdir(parents=True, exist_ok=True)
    traj = cache / "traj.yaml"
    guardid = [sys.executable, "-m", "guardid"]
    subprocess.run([*guardid, "excite", "-o", str(traj)], check=True, capture_output=True)
    part = cache / "hour.part.csv"
    part.unlink(missing_ok=True)
    start = time.perf_counter()
    subprocess.run(
        [*guardid, "capture", "--trajectory", str(traj), "--duration", "3600", "--quiet",
         "-o", str(part)], check=True,
    )  # fmt: skip
    print(f"captured one hour from sim://guard in {time.perf_counter() - start:.1f} s wall")
    part.rename(log)
    return log


def repeated_log(hour: Path, hours: int) -> Path:
    """``hours`` copies of the one-hour log's rows, ticks continuing (gap of 100 ticks)."""
    out = hour.with_name(f"hours{hours}.csv")
    if hours == 1 or out.exists():
        return hour if hours == 1 else out
    lines = hour.read_text().splitlines(keepends=True)
    first = next(k for k, ln in enumerate(lines) if k and not ln.startswith("#"))
    last = max(k for k, ln in enumerate(lines) if not ln.startswith("#")) + 1
    head, rows = lines[:first], lines[first:last]
    t0, t1 = int(rows[0].split(",", 1)[0]), int(rows[-1].split(",", 1)[0])
    part = out.with_suffix(".part")
    with open(part, "w", encoding="utf-8") as f:
        f.writelines(head)
        for rep in range(hours):
            shift = rep * (t1 - t0 + 1 + 100)
            for ln in rows:
                tick, time_s, rest = ln.split(",", 2)
                f.write(f"{int(tick) + shift},{float(time_s) + shift * 0.015:.6f},{rest}")
    part.rename(out)
    return out


def first_minutes(hour: Path, minutes: float) -> Path:
    """The one-hour log's header and its first ``minutes`` of rows (no footer)."""
    out = hour.with_name(f"minutes{minutes:g}.csv")
    if not out.exists():
        lines = hour.read_text().splitlines(keepends=True)
        first = next(k for k, ln in enumerate(lines) if k and not ln.startswith("#"))
        out.write_text("".join(lines[: first + int(minutes * 60 / 0.015)]))
    return out


def run_child(cmd, pythonpath: str | None) -> tuple[float, float, float, str]:
    """(wall s, CPU s, peak RSS MB, stdout) of one subprocess."""
    env = dict(os.environ)
    if pythonpath:
        env["PYTHONPATH"] = pythonpath
    start = time.perf_counter()
    # run from a neutral directory: the working directory comes first on sys.path
    proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, env=env,
                            text=True, cwd=tempfile.gettempdir())  # fmt: skip
    out = proc.stdout.read()
    _, status, usage = os.wait4(proc.pid, 0)
    wall = time.perf_counter() - start
    proc.returncode = os.waitstatus_to_exitcode(status)
    if proc.returncode != 0:
        raise SystemExit(f"failed ({proc.returncode}): {' '.join(map(str, cmd))}")
    return wall, usage.ru_utime + usage.ru_stime, usage.ru_maxrss / 1024.0, out


def measure(label, cmd, runs, trees):
    """Run ``cmd`` ``runs`` times per source tree (alternating); print and return medians."""
    results = {tree: [] for tree in trees}
    for _ in range(runs):
        for tree in trees:
            results[tree].append(run_child(cmd, tree))
    medians = {}
    for tree, rs in results.items():
        wall = [r[0] for r in rs]
        cpu = [r[1] for r in rs]
        rss = [r[2] for r in rs]
        own = [_own_seconds(r[3]) for r in rs]
        name = "this tree" if tree is None else f"baseline {tree}"
        inner = ""
        if None not in own:  # a snippet printing its own CPU time (after its imports)
            inner = f", in-process CPU median {statistics.median(own):.2f} s"
        print(
            f"{label} [{name}]: wall median {statistics.median(wall):.2f} s (worst "
            f"{max(wall):.2f}), CPU median {statistics.median(cpu):.2f} s{inner}, peak RSS "
            f"{max(rss):.0f} MB, {runs} runs"
        )
        medians[tree] = (statistics.median(wall), statistics.median(cpu))
        if inner:
            medians[tree] += (statistics.median(own),)
    if len(trees) == 2:
        old, new = medians[trees[1]], medians[trees[0]]
        text = f"{label}: old/new wall {old[0] / new[0]:.1f}x, CPU {old[1] / new[1]:.1f}x"
        if len(old) == len(new) == 3:
            text += f", in-process CPU {old[2] / new[2]:.1f}x"
        print(text + " (paired, same run)")
    return medians


def _own_seconds(out: str):
    """The first number a snippet printed (its own CPU time [s]), or None."""
    try:
        return float(out.split()[0])
    except (IndexError, ValueError):
        return None


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--hours", type=int, nargs="+", default=[1, 4])
    ap.add_argument("--runs", type=int, default=3)
    ap.add_argument(
        "--cache", type=Path, default=Path(tempfile.gettempdir()) / "guardid-bench-cache"
    )
    ap.add_argument("--baseline", default=None, help="Another source tree to compare with.")
    ap.add_argument("--methods", nargs="+", default=["default", "ls,wls"])
    ap.add_argument(
        "--minutes", type=float, default=None,
        help="Instead of --hours: the first MINUTES of the one-hour log (a cheaper paired run).",
    )  # fmt: skip
    ap.add_argument("--reads-only", action="store_true", help="Only the log reading figures.")
    args = ap.parse_args()
    trees = [None] + ([str(Path(args.baseline).resolve())] if args.baseline else [])
    hour = hour_log(args.cache)
    print(f"machine: {os.cpu_count()} cores, load average {os.getloadavg()[0]:.1f} at start")
    read = [sys.executable, "-c", READ_SNIPPET, str(hour)]
    print(f"one-hour log: {hour} ({hour.stat().st_size / 1e6:.1f} MB)")
    measure("read_log, one hour", read, args.runs, trees)
    cli_read = [sys.executable, "-c", CLI_READ_SNIPPET, str(hour)]
    measure("identify's reads of its log, one hour", cli_read, args.runs, trees)
    if args.reads_only:
        return
    logs = [(f"{h} h", repeated_log(hour, h)) for h in args.hours]
    if args.minutes is not None:
        logs = [(f"{args.minutes:g} min", first_minutes(hour, args.minutes))]
    for label, log in logs:
        for methods in args.methods:
            cmd = [sys.executable, "-m", "guardid", "identify", str(log)]
            if methods != "default":
                cmd += ["--method", methods]
            measure(f"identify {label}, methods {methods}", cmd, args.runs, trees)
    print(f"load average {os.getloadavg()[0]:.1f} at the end")


if __name__ == "__main__":
    main()
