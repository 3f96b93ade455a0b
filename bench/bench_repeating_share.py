"""The share of each parameter's variance that repeats every excitation period, and what a
longer run does to the std (docs/std_residuals.md, "the share that repeats").

For each capture log: ``identify`` (WLS, defaults) on the whole log and, with ``--cut S``, on
its first S seconds. Prints the shares' range (params.yaml ``repeating_residual.
variance_share`` of the whole logs) and, per parameter, the median over the logs of the
observed std ratio whole / cut against the ratio the cut fit's share predicts,
sqrt((1 - s) / r + s), r the length ratio (the white part's variance falls as 1 / r, the
repeating part's stays); 1 / sqrt(r) without a repeating part. The ratios are numpy on the
fits' std.

    python bench/bench_std_check.py --keep DIR --sets coarse2400 --first-seed 9100 --seeds 8 \\
        --capture-only
    python bench/bench_repeating_share.py --robot bench/robots/guard_coarse.yaml --cut 1200 \\
        DIR/coarse2400_*.csv
"""

from __future__ import annotations

import argparse

import numpy as np

from guardid.identify.pipeline import IdentifyOptions, identify
from guardid.identify.runs import load_run
from guardid.identify.segments import run_rows
from guardid.robot import load_robot


def first_seconds(run, seconds: float):
    """``run`` cut to its first ``seconds`` [s] (every per-row array; its times increase)."""
    return run_rows(run, 0, int(np.count_nonzero(run.t <= run.t[0] + seconds)))


def wls(run, description):
    """(names, std (b,), variance_share (b,)) of identify's WLS on ``run``."""
    result = identify([run], description, IdentifyOptions(methods=("wls",)))
    fit = result.results["wls"]
    share = fit.settings.get("repeating_residual", {}).get("variance_share")
    share = np.zeros(len(result.names)) if share is None else np.asarray(share)
    return result.names, np.asarray(fit.std), share


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("logs", nargs="+", help="guardid capture logs")
    ap.add_argument("--robot", default=None, help="robot (default: each log's)")
    ap.add_argument("--cut", type=float, default=None, help="also fit the first S seconds")
    a = ap.parse_args()
    shares, observed, predicted = [], [], []
    names = ()
    for path in a.logs:
        run = load_run(path)
        description = load_robot(a.robot or run.robot)
        names, std, share = wls(run, description)
        shares.append(share)
        line = f"{path}: shares {share.min():.2f}-{share.max():.2f}"
        if a.cut:
            _, std_cut, share_cut = wls(first_seconds(run, a.cut), description)
            r = (run.t[-1] - run.t[0]) / a.cut
            observed.append(std / std_cut)
            predicted.append(np.sqrt((1.0 - share_cut) / r + share_cut))
            line += f"; std whole / first {a.cut:g} s median {np.median(observed[-1]):.3f}"
        print(line, flush=True)
    s = np.array(shares)
    print(f"{len(s)} logs: variance_share min {s.min():.2f}, median {np.median(s):.2f}, "
          f"max {s.max():.2f}")  # fmt: skip
    if a.cut:
        print("parameter  observed std ratio  predicted by the cut fit's share (median)")
        for k, name in enumerate(names):
            print(f"{name:8s}   {np.median(np.array(observed)[:, k]):.3f}"
                  f"               {np.median(np.array(predicted)[:, k]):.3f}")  # fmt: skip
        print(f"without a repeating part: {np.sqrt(1.0 / r):.3f}")


if __name__ == "__main__":
    main()
