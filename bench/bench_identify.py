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

``--floor`` (issue 30): guardid identify beside "the floor", a minimal plain numpy/scipy
pipeline doing the default equation's job (:func:`floor`, run as its own process by
``--floor-run LOG``), whole processes in turn (guardid, floor, guardid, floor, ...) on the
same log, ``--runs`` pairs (at least 5): the CPU time (user + sys of the process and its
children) and the peak RSS of each, and the ratios guardid / floor pair by pair (median and
worst). guardid runs with its default methods and with ``--method ls,wls`` (the floor's
own job); the floor prints its LS / WLS estimates, compared with guardid's params.yaml as
an independent check that it does the same job.

    python bench/bench_identify.py [--hours 1 4] [--runs 3] [--baseline DIR] [--reads-only]
    python bench/bench_identify.py --floor [--hours 1 4] [--runs 5]
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


def floor(path: str) -> dict:
    """The floor: guardid's default equation (the filtered momentum form) in plain numpy /
    scipy, with guardid's own model regressors. Returns {"ls": theta, "wls": theta} (the
    robot description's identified base parameters, in order).

    What it does, all of it vectorised: reads the log's tick, position and current columns
    with a compiled CSV reader (pandas' ``read_csv`` when installed, else ``np.loadtxt``,
    2.5x slower here than guardid's ``read_log``); velocities at the ticks by the
    three-point central difference; per period k (tick k-1 to k) the equation
    gain i_k T = Y_p(q_k, v_k) theta - Y_p(q_(k-1), v_(k-1)) theta + T/24 (-R_(k-2) + 13 R_(k-1)
    + 13 R_k - R_(k+1)) theta, with Y_p and R guardid's ``momentum_regressor`` and
    ``rest_regressor`` times the base map (formed 8192 ticks at a time); ticks slower than
    5 % of the joint's peak speed, lost ticks and the log's ends cut with a margin of 5
    ticks; the same causal Butterworth (order 2, cut-off 2 x the highest harmonic, at least
    2 Hz: guardid's rule) over the impulses and every column (``sosfilt``, one pass over the
    whole log, the cut periods zeroed); every m-th period kept (guardid's default
    spacing: every tick up to 65536 ticks, else ticks / 65536 rounded up, at most 16, its
    decimation at 2 Hz) where no cut lies within the last 20 ticks (guardid's transient);
    least squares over both joints' rows (``lstsq``), then WLS weighted by each joint's LS
    residual std. Not done (guardid does): the kink and slope corrections of the stencil,
    the exact friction integrals, restarting the filter after each cut, the motor
    equations, the checks, the report, the std (the rows' shared noise counted), the mean
    of each row's m ticks on a long log (rows on the tick count); and the
    batch RLS / Hopfield fits and the tracker's replay of the default
    methods.
    """
    import numpy as np
    from scipy.signal import butter, sosfilt

    from guardid.conditioning.units import drive_gain
    from guardid.dynamics import build_model
    from guardid.robot import load_robot

    try:  # the fastest compiled reader at hand (pandas is not a guardid dependency)
        import pandas

        data = pandas.read_csv(path, comment="#", usecols=[0, 4, 5, 8, 9]).to_numpy(float)
    except ImportError:
        data = np.loadtxt(path, delimiter=",", comments="#", skiprows=1, usecols=(0, 4, 5, 8, 9))
    desc = load_robot("guard")
    model = build_model(desc)
    dt = float(desc.sample_period)
    tick, q, cur = data[:, 0], data[:, 1:3], data[:, 3:5]
    n_t, n = q.shape
    free = [i for i, x in enumerate(model.base.names) if not x.startswith("Fo")]  # offset: null
    B = model.base.B[:, free]
    v = np.zeros_like(q)
    v[1:-1] = (q[2:] - q[:-2]) / (2.0 * dt)
    p_mom = np.empty((n_t, n, len(free)))
    rest = np.empty_like(p_mom)
    for s in range(0, n_t, 8192):
        c = slice(s, s + 8192)
        p_mom[c] = model.momentum_regressor(q[c], v[c]) @ B
        rest[c] = model.rest_regressor(q[c], v[c]) @ B
    phi = np.zeros_like(p_mom)
    phi[1:] = p_mom[1:] - p_mom[:-1]
    del p_mom
    w = np.array([-1.0, 13.0, 13.0, -1.0]) * (dt / 24.0)
    phi[2:-1] += w[0] * rest[:-3] + w[1] * rest[1:-2] + w[2] * rest[2:-1] + w[3] * rest[3:]
    del rest
    imp = cur * drive_gain(desc) * dt
    cut = np.abs(v) < 0.05 * np.abs(v).max(axis=0)
    cut[[0, 1, -1]] = True
    gap = np.flatnonzero(np.diff(tick) != 1)
    cut[gap] = cut[gap + 1] = True
    c = np.concatenate([np.zeros((1, n), int), np.cumsum(cut, axis=0)])
    k = np.arange(n_t)
    near = c[np.minimum(k + 6, n_t)] - c[np.maximum(k - 5, 0)] > 0  # margin of 5 ticks
    phi[near] = 0.0
    imp[near] = 0.0
    harmonic = 0.5  # the capture's excitation (its header: base_freq 0.1 Hz, 5 harmonics)
    sos = butter(2, max(2.0 * harmonic, 2.0), fs=1.0 / dt, output="sos")
    memory = 20  # guardid's transient_samples at 2 Hz: outputs dropped after a cut
    step = min(max(1, -(-n_t // 65536)), 16)  # guardid's default: at most 65536 rows
    rows = np.arange(memory, n_t, step)
    cn = np.concatenate([np.zeros((1, n), int), np.cumsum(near, axis=0)])
    ok = cn[rows + 1] - cn[rows + 1 - memory] == 0  # (M, n): no cut in the filter's memory
    A, y = [], []
    for j in range(n):
        f = sosfilt(sos, np.column_stack([imp[:, j], phi[:, j, :]]), axis=0)[rows][ok[:, j]]
        y.append(f[:, 0] / dt)
        A.append(f[:, 1:] / dt)
    theta = np.linalg.lstsq(np.concatenate(A), np.concatenate(y), rcond=None)[0]
    sd = [np.std(yj - Aj @ theta) for Aj, yj in zip(A, y, strict=True)]
    Aw = np.concatenate([Aj / s for Aj, s in zip(A, sd, strict=True)])
    yw = np.concatenate([yj / s for yj, s in zip(y, sd, strict=True)])
    wls = np.linalg.lstsq(Aw, yw, rcond=None)[0]
    return {"names": [model.base.names[i] for i in free], "ls": theta, "wls": wls}


def paired(label, cmd_a, cmd_b, runs):
    """``cmd_a`` and ``cmd_b`` in turn ``runs`` times (after one warm-up each): CPU and peak
    RSS of each, the ratios a / b pair by pair (median and worst). Returns the outputs."""
    run_child(cmd_a, None)
    run_child(cmd_b, None)
    a, b = [], []
    for _ in range(runs):
        a.append(run_child(cmd_a, None))
        b.append(run_child(cmd_b, None))
    cpu = [x[1] / y[1] for x, y in zip(a, b, strict=True)]
    rss = [x[2] / y[2] for x, y in zip(a, b, strict=True)]
    med = statistics.median
    print(
        f"{label}: guardid CPU median {med(x[1] for x in a):.2f} s (worst "
        f"{max(x[1] for x in a):.2f}), floor {med(x[1] for x in b):.2f} s (worst "
        f"{max(x[1] for x in b):.2f}); CPU ratio guardid/floor median {med(cpu):.2f}, worst "
        f"{max(cpu):.2f}; peak RSS guardid {max(x[2] for x in a):.0f} MB, floor "
        f"{max(x[2] for x in b):.0f} MB (ratio median {med(rss):.2f}); {runs} pairs"
    )
    return a[-1][3], b[-1][3]


def floor_main(args) -> None:
    hour = hour_log(args.cache)
    print(f"machine: {os.cpu_count()} cores, load average {os.getloadavg()[0]:.1f} at start")
    runs = max(args.runs, 5)
    for h in args.hours:
        log = repeated_log(hour, h)
        base = [sys.executable, "-m", "guardid", "identify", str(log)]
        fl = [sys.executable, str(Path(__file__).resolve()), "--floor-run", str(log)]
        params = args.cache / f"floor-check-{h}.yaml"
        for methods in args.methods:
            cmd = base + ([] if methods == "default" else ["--method", methods])
            paired(f"identify {h} h, methods {methods} / floor", cmd, fl, runs)
        subprocess.run([*base, "--method", "ls,wls", "-o", str(params), "--force"],
                       check=True, capture_output=True)  # fmt: skip
        _floor_check(params, subprocess.run(fl, check=True, capture_output=True, text=True))
    print(f"load average {os.getloadavg()[0]:.1f} at the end")


def _floor_check(params: Path, done) -> None:
    """The floor's estimates beside guardid's (the same job: close, not equal)."""
    import json

    import yaml

    out = json.loads(done.stdout.strip().splitlines()[-1])
    ours = yaml.safe_load(params.read_text())
    names = [b["name"] for b in ours["base_parameters"]]
    assert names == out["names"], (names, out["names"])
    text = []
    for m in ("ls", "wls"):
        g = ours["methods"][m]["values"]
        worst = max(abs(f - x) / max(abs(x), 0.05) for f, x in zip(out[m], g, strict=True))
        text.append(f"{m.upper()} largest difference {100 * worst:.1f} % (of |value|, >= 0.05)")
    print("floor against guardid: " + "; ".join(text))


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
    ap.add_argument("--floor", action="store_true", help="guardid beside the floor (issue 30).")
    ap.add_argument("--floor-run", default=None, help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.floor_run:
        import json

        out = floor(args.floor_run)
        print(json.dumps({k: [str(x) for x in v] if k == "names" else [float(x) for x in v]
                          for k, v in out.items()}))  # fmt: skip
        return
    if args.floor:
        floor_main(args)
        return
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
