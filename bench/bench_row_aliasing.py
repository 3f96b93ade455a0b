"""Do the momentum form's decimated rows fold error into the regressor's band? (issue 27)

On the logs a ``bench/bench_std_check.py --keep DIR`` run kept (``DIR/SET_SEED.csv``): the
rows ``guardid identify`` builds (:func:`guardid.identify.rows.stacked_rows` on the log's
prepared runs, the momentum form at its chosen cut-off) three ways, then a weighted least
squares in numpy (weights per joint from the residual with the true parameters; no
quantisation compensation, no phase groups: the same plain fit for all three):

* ``every k``: the filtered values at every k-th tick (identify's rows; k its decimation,
  16 at the default 2 Hz cut-off on a 15 ms tick: rows at 4.17 Hz);
* ``all``: the filtered values at every tick (k = 1);
* ``mean of k``: the mean of the k filtered values up to every k-th tick (a moving average
  as the filter's last stage, on both sides: the equation stays exact).

Per base parameter over the seeds: the spread of (estimate - truth) relative to ``every
k``'s, and over the plain fit's own std (sigma^2 (A^T W A)^-1; far too small for ``all``,
whose rows share their filtered noise), both over the seeds with ddof 1. The truth is the
robot YAML the simulator ran.

    nice -n 10 python bench/bench_row_aliasing.py --keep DIR --set coarse1200
        [--first-seed 9100] [--seeds 20]
"""

from __future__ import annotations

import argparse

import numpy as np
from bench_std_check import find_set, truth_values

from guardid.conditioning.options import ConditioningOptions
from guardid.dynamics import build_model
from guardid.identify.equation import free_columns
from guardid.identify.prepare import prepared_runs, run_signals
from guardid.identify.rows import stacked_rows
from guardid.identify.runs import load_run
from guardid.robot import load_robot

NW_WINDOWS = (1, 2, 4)
"""Newey-West windows for the rows at every tick, in multiples of k [-]."""


def joint_weights(A, y, theta) -> np.ndarray:
    """Per joint 1 / rms of the residual at ``theta`` over its live rows (n,)."""
    r0 = y - A @ theta
    return np.array([1.0 / np.sqrt(np.mean(r0[A[:, j].any(1), j] ** 2)) for j in range(A.shape[1])])


def plain_wls(A, y, theta):
    """(estimate - theta, the fit's std) of WLS on rows A (M, n, p), y (M, n), weights per
    joint 1 / rms of the residual at ``theta``; all-zero rows left out."""
    w = joint_weights(A, y, theta)
    Aw = (A * w[None, :, None]).reshape(-1, A.shape[2])
    yw = (y * w[None, :]).ravel()
    keep = np.any(Aw != 0, axis=1)
    Aw, yw = Aw[keep], yw[keep]
    est = np.linalg.lstsq(Aw, yw, rcond=None)[0]
    res = yw - Aw @ est
    cov = np.linalg.inv(Aw.T @ Aw) * (res @ res) / (len(yw) - len(theta))
    return est - theta, np.sqrt(np.diag(cov))


def newey_west_std(A, y, theta, err, window: int):
    """Std of the plain WLS estimate (``theta`` + ``err``) on rows A (M, n, p), y (M, n)
    that lie on a time grid (zero rows where a joint's equation is cut), with the scores'
    autocovariance over ``window`` rows weighted by Bartlett's 1 - lag / (window + 1)."""
    w = joint_weights(A, y, theta)
    Aw = A * w[None, :, None]
    r = (y - A @ (theta + err)) * w[None, :] * np.any(A != 0, axis=2)
    g = np.einsum("mjp,mj->mp", Aw, r)  # score per row
    bread = np.linalg.inv(np.einsum("mjp,mjq->pq", Aw, Aw))
    meat = g.T @ g
    for lag in range(1, window + 1):
        c = g[lag:].T @ g[:-lag]
        meat += (1.0 - lag / (window + 1)) * (c + c.T)
    return np.sqrt(np.diag(bread @ meat @ bread))


def block_means(A, y, k):
    """Rows every k ticks from the k-th, each the mean of the k rows up to and including it
    (identify's row ticks 0, k, 2k, ... less the first); a joint's row is zero unless all k
    are valid."""
    A, y = A[1:], y[1:]  # ticks 1 .. k end at tick k
    nb = A.shape[0] // k
    ok = np.any(A != 0, axis=2)[: nb * k].reshape(nb, k, -1).all(axis=1)
    Ab = A[: nb * k].reshape(nb, k, *A.shape[1:]).mean(axis=1) * ok[:, :, None]
    yb = y[: nb * k].reshape(nb, k, -1).mean(axis=1) * ok
    return Ab, yb


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--keep", required=True, help="bench_std_check.py's --keep directory")
    ap.add_argument("--set", default="coarse1200")
    ap.add_argument("--first-seed", type=int, default=9100)
    ap.add_argument("--seeds", type=int, default=20)
    a = ap.parse_args()
    s = find_set(a.set)
    truth = truth_values(s.robot)
    desc = load_robot(s.robot)
    model = build_model(desc)
    names = [model.base.names[i] for i in free_columns(model, desc)]
    theta = np.array([truth[n] for n in names])
    out = {"every k": ([], []), "all": ([], []), "mean of k": ([], [])}
    out.update({f"all, NW {m}k": ([], []) for m in NW_WINDOWS})
    for seed in range(a.first_seed, a.first_seed + a.seeds):
        runs, _, _ = prepared_runs([load_run(f"{a.keep}/{a.set}_{seed}.csv")], desc)
        sig = [run_signals(r, runs) for r in runs]
        hh = runs[0].highest_harmonic_hz
        every = stacked_rows(sig, desc, ConditioningOptions(), highest_harmonic_hz=hh)
        k = every.cond.decimation
        each = stacked_rows(sig, desc, ConditioningOptions(decimate=1), highest_harmonic_hz=hh)
        for key, (A, y) in (("every k", (every.A, every.y)), ("all", (each.A, each.y)),
                            ("mean of k", block_means(each.A, each.y, k))):  # fmt: skip
            e, sd = plain_wls(A, y, theta)
            out[key][0].append(e)
            out[key][1].append(sd)
            if key == "all":
                for mult in NW_WINDOWS:
                    nw = newey_west_std(A, y, theta, e, mult * k)
                    out[f"all, NW {mult}k"][0].append(e)
                    out[f"all, NW {mult}k"][1].append(nw)
    base = np.array(out["every k"][0]).std(axis=0, ddof=1)
    print(f"{a.set}, seeds {a.first_seed}-{a.first_seed + a.seeds - 1}, k = {k}")
    for key, (E, S) in out.items():
        E, S = np.array(E), np.array(S).mean(axis=0)
        rel = " ".join(f"{n} {v:.2f}" for n, v in zip(names, E.std(0, ddof=1) / base, strict=True))
        own = " ".join(f"{n} {v:.2f}" for n, v in zip(names, E.std(0, ddof=1) / S, strict=True))
        print(f"{key:14s} spread / every k's: {rel}")
        print(f"{'':14s} spread / own std:    {own}")


if __name__ == "__main__":
    main()
