"""The quantisation bootstrap (guardid/uncertainty, issue 27) on the kept Monte Carlo logs.

Per kept log of ``bench/bench_std_check.py --keep DIR`` (``SET_SEED.csv``): identify (WLS,
defaults, in this process), then K replicas of the log through the closed loop
(:func:`guardid.uncertainty.quantisation_bootstrap`, a fixed K), everything saved to
``OUT/SET_SEED.npz``. Then, per set, the std check of bench_std_check (its ``statistics`` and
``verdict``, numpy on the saved estimates against the robot YAML's truth) for:

* ``wls``: the run's own estimate and std (what identify reports without the bootstrap);
* ``+Q``: the run's estimate, std from cov + the persistent part;
* ``-b +Q``: the corrected estimate theta - b, std from cov + persistent + spread / K;
* ``-b``: the corrected estimate with cov + spread / K.

    nice -n 10 python bench/bench_quantisation_bootstrap.py --keep /tmp/mc_std/keep
        --sets default1200:20,schroeder60 --replicas 8 --out /tmp/qb/boot [--jobs 2]
        [--first-seed 5000] [--seeds 40] [--use K]
"""

from __future__ import annotations

import argparse
import time
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import numpy as np
from bench_std_check import EXTRA_SETS, SETS, statistics, truth_values, verdict


def run_one(job):
    """Identify one kept log and bootstrap it; (name, seed, seconds or error)."""
    from guardid.identify.pipeline import IdentifyOptions, identify
    from guardid.identify.runs import load_run
    from guardid.robot import load_robot
    from guardid.uncertainty import BootstrapOptions, quantisation_bootstrap

    keep, out, name, seed, replicas, robot = job
    target = Path(out) / f"{name}_{seed}.npz"
    if target.exists():
        return name, seed, 0.0
    log = Path(keep) / f"{name}_{seed}.csv"
    if not log.exists():
        return name, seed, f"no log {log}"
    d = load_robot(robot)
    run = load_run(log)
    opts = IdentifyOptions(methods=("wls",))
    t0 = time.process_time()
    res = identify([run], d, opts)
    t1 = time.process_time()
    bs = quantisation_bootstrap([run], d, res, "wls", BootstrapOptions(replicas=replicas,
                                tolerance=0.0), opts)  # fmt: skip
    t2 = time.process_time()
    fit = res.results["wls"]
    np.savez(target, names=np.array(res.names), theta=fit.theta, cov=fit.cov, errors=bs.errors,
             covs=bs.covs, fit_s=t1 - t0, boot_s=t2 - t1)  # fmt: skip
    return name, seed, t2 - t0


def variants(data, use=None):
    """(theta, std) per variant of one saved log; ``use``: the first K replicas only."""
    from guardid.uncertainty import QuantisationBootstrap

    k = len(data["errors"]) if use is None else use
    bs = QuantisationBootstrap(tuple(data["names"]), data["theta"], data["errors"][:k],
                               data["covs"][:k])  # fmt: skip
    cov, theta = data["cov"], data["theta"]
    sd = lambda c: np.sqrt(np.diag(c))  # noqa: E731
    return {
        "wls": (theta, sd(cov)),
        "+Q": (theta, sd(cov + bs.persistent)),
        "-b +Q": (bs.corrected(theta), sd(bs.covariance(cov))),
        "-b": (bs.corrected(theta), sd(cov + bs.spread / bs.replicas)),
    }


def evaluate(out, name, seeds, robot, use=None) -> list[str]:
    files = [Path(out) / f"{name}_{s}.npz" for s in seeds]
    files = [f for f in files if f.exists()]
    if len(files) < 3:
        return [f"{name}: fewer than 3 logs bootstrapped"]
    datas = [np.load(f) for f in files]
    truth = truth_values(robot)
    names = [str(n) for n in datas[0]["names"]]
    lines = []
    per = [variants(d, use) for d in datas]
    ks = [len(d["errors"]) if use is None else use for d in datas]
    boot_s = np.array([float(d["boot_s"]) for d in datas])
    fit_s = np.array([float(d["fit_s"]) for d in datas])
    for v in per[0]:
        theta = np.array([p[v][0] for p in per])
        std = np.array([p[v][1] for p in per])
        rows, share = statistics(names, theta, std, truth)
        _, text = verdict(rows, share, len(files))
        lines.append(f"{name:14s} {v:6s} {len(files):3d} seeds K={min(ks)}: {text}")
    b = np.array([d["errors"][: (use or None)].mean(0) / np.sqrt(np.diag(d["cov"])) for d in datas])
    lines.append(
        f"{name:14s} replicas' bias b/std, median over logs: "
        + ", ".join(f"{n} {x:+.2f}" for n, x in zip(names, np.median(b, 0), strict=True))
    )
    lines.append(f"{name:14s} CPU s per log: fit {np.median(fit_s):.1f}, bootstrap "
                 f"{np.median(boot_s):.1f} (K={min(ks)})")  # fmt: skip
    return lines


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--keep", required=True)
    ap.add_argument("--out", required=True)
    ap.add_argument("--sets", default="default60")
    ap.add_argument("--seeds", type=int, default=40)
    ap.add_argument("--first-seed", type=int, default=5000)
    ap.add_argument("--replicas", type=int, default=8)
    ap.add_argument("--jobs", type=int, default=2)
    ap.add_argument("--use", type=int, default=None, help="evaluate with the first K replicas")
    ap.add_argument("--eval-only", action="store_true")
    a = ap.parse_args()
    known = {**SETS, **EXTRA_SETS}
    wanted = [w.partition(":") for w in a.sets.split(",")]
    sets = {n: range(a.first_seed, a.first_seed + (int(k) if k else a.seeds)) for n, _, k in wanted}
    Path(a.out).mkdir(parents=True, exist_ok=True)
    if not a.eval_only:
        jobs = [(a.keep, a.out, n, s, a.replicas, known[n].robot) for n in sets for s in sets[n]]
        with ProcessPoolExecutor(max_workers=a.jobs) as pool:
            for i, (n, s, r) in enumerate(pool.map(run_one, jobs)):
                print(f"[{i + 1}/{len(jobs)}] {n} {s}: {r if isinstance(r, str) else f'{r:.0f} s'}",
                      flush=True)  # fmt: skip
    for n in sets:
        print("\n".join(evaluate(a.out, n, sets[n], known[n].robot, a.use)), flush=True)


if __name__ == "__main__":
    main()
