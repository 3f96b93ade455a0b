"""Are identify's residuals white, and is what the std misses visible inside a run? (issue 27)

On the logs a ``bench/bench_std_check.py --keep DIR`` run kept (``DIR/SET_SEED.csv``), per
set: the rows ``guardid identify`` fits by default (:func:`guardid.identify.rows.stacked_rows`
on the log's prepared runs) and WLS on them; then, with numpy only:

* per joint, the autocorrelation of the normalised residual at 1, 2, 3 row periods (pairs
  of rows that are both valid and that many periods apart on the rows' time grid), pooled
  over the seeds, and the residuals' correlation between the joints at the same row;
* per parameter, over the seeds: the spread of (estimate - truth) over the mean std with the
  std as reported (sigma^2 (A^T W A)^-1), with a Bartlett (Newey-West) sandwich over the
  rows whose lag window is the last lag at which the pooled autocorrelation exceeds
  2 / sqrt(pairs) (at least 1), and with White's HC2 sandwich (heteroscedasticity);
* per parameter, the correlation over the seeds of the errors of the run's first and
  second halves fitted separately: an error that persists through a run (the same in both
  halves) but differs between runs shows here and in no within-run statistic.

    nice -n 10 python bench/bench_residual_whiteness.py --keep /tmp/mc_std/keep
        [--sets schroeder60,default1200] [--seeds 40] [--first-seed 5000]
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np
from bench_std_check import EXTRA_SETS, SETS, truth_values

from guardid.dynamics import build_model
from guardid.estimators import WeightedLeastSquares
from guardid.identify.equation import free_columns
from guardid.identify.prepare import prepared_runs, run_signals
from guardid.identify.rows import stacked_rows
from guardid.identify.runs import load_run
from guardid.robot import load_robot

LAGS = (1, 2, 3)


def log_rows(log: Path, robot: str):
    """(A (M, n, p), y (M, n), row times (M,) [s], identified parameter names (p,)) that
    ``guardid identify LOG`` fits."""
    description = load_robot(robot)
    model = build_model(description)
    names = [model.base.names[i] for i in free_columns(model, description)]
    runs, _, _ = prepared_runs([load_run(str(log))], description)
    rows = stacked_rows([run_signals(r, runs) for r in runs], description, None,
                        highest_harmonic_hz=runs[0].highest_harmonic_hz)  # fmt: skip
    c = rows.cond
    return rows.A, rows.y, c.t[c.mask], names


def grid(t):
    """Row index on the rows' time grid (the smallest row step) [-]."""
    step = float(np.min(np.diff(t)))
    return np.round((t - t[0]) / step).astype(int)


def acf_terms(r, valid, k, lags):
    """(sum r_i r_(i+lag) over valid pairs, pair count) per lag, r on the grid ``k``."""
    R = np.zeros(k.max() + 1)
    V = np.zeros(k.max() + 1, bool)
    R[k[valid]], V[k[valid]] = r[valid], True
    out = []
    for lag in lags:
        ok = V[lag:] & V[:-lag]
        out.append((float(np.sum(R[lag:][ok] * R[:-lag][ok])), int(ok.sum())))
    return out


def sandwich_std(A, r, w, k, window: int, hc2: bool = False):
    """Std of the WLS estimate from a sandwich over the rows: Bartlett window ``window``
    rows on the time grid ``k`` (0: White's), HC2 leverage correction with ``hc2``, else the
    meat scaled by M / (M - p) (HC1; M the valid joint rows)."""
    Aw = A * (w**2)[None, :, None]
    bread = np.linalg.inv(np.einsum("kjp,kjq->pq", A * w[None, :, None], A * w[None, :, None]))
    e = r.copy()
    if hc2:
        h = np.einsum("kjp,pq,kjq->kj", A * w[None, :, None], bread, A * w[None, :, None])
        e = r / np.sqrt(np.clip(1.0 - h, 1e-6, None))
    g = np.zeros((k.max() + 1, A.shape[2]))
    g[k] = np.einsum("kjp,kj->kp", Aw, e)  # score per row on the grid
    meat = g.T @ g
    for lag in range(1, window + 1):
        c = g[lag:].T @ g[:-lag]
        meat += (1.0 - lag / (window + 1)) * (c + c.T)
    if not hc2:
        m_rows = int(np.count_nonzero(np.any(A != 0, axis=2)))
        meat *= m_rows / (m_rows - A.shape[2])
    return np.sqrt(np.diag(bread @ meat @ bread))


def check_set(name: str, keep: Path, seeds) -> None:
    s = {**SETS, **EXTRA_SETS}[name]
    truth = truth_values(s.robot)
    data = []
    for seed in seeds:
        log = keep / f"{name}_{seed}.csv"
        if log.exists():
            data.append(log_rows(log, s.robot))
    if len(data) < 3:
        print(f"=== {name}: {len(data)} logs in {keep}: skipped")
        return
    n = data[0][0].shape[1]
    names = data[0][3]
    sums = np.zeros((n, len(LAGS), 2))
    var, cross = np.zeros((n, 2)), []
    fits = []
    for A, y, t, _ in data:
        wls = WeightedLeastSquares().fit(A, y)
        r = (y - A @ wls.theta_) / wls.sigma_per_output_
        k = grid(t)
        for j in range(n):
            valid = np.any(A[:, j] != 0, axis=1)
            var[j] += (np.sum(r[valid, j] ** 2), valid.sum())
            sums[j] += acf_terms(r[:, j], valid, k, LAGS)
        both = np.all(np.any(A != 0, axis=2), axis=1)
        cross.append(np.mean(r[both, 0] * r[both, 1]) if n > 1 and both.any() else 0.0)
        fits.append((A, y, k, wls))
    with np.errstate(divide="ignore", invalid="ignore"):  # a lag without pairs: nan
        acf = sums[:, :, 0] / sums[:, :, 1] / (var[:, 0] / var[:, 1])[:, None]
        limit = 2.0 / np.sqrt(sums[:, :, 1])
    above = [lag for i, lag in enumerate(LAGS) if np.any(np.abs(acf[:, i]) > limit[:, i])]
    window = max(above, default=1)
    print(f"\n=== {name}: {len(data)} logs; residual autocorrelation per joint at "
          f"{', '.join(map(str, LAGS))} row periods (2/sqrt(pairs) in brackets)")  # fmt: skip
    for j in range(n):
        cells = "  ".join(f"{a:+.3f} ({lim:.3f})" for a, lim in zip(acf[j], limit[j], strict=True))
        print(f"  joint {j}: {cells}")
    print(f"  between the joints at one row: {np.mean(cross):+.3f}; Bartlett window {window}")
    theta = np.array([f[3].theta_ for f in fits])
    tv = np.array([truth[nm] for nm in names])
    stds = {
        "reported": np.array([f[3].std_ for f in fits]),
        f"Bartlett {window}": np.array([
            sandwich_std(A, y - A @ w.theta_, w.weights_, k, window) for A, y, k, w in fits]),
        "HC2": np.array([
            sandwich_std(A, y - A @ w.theta_, w.weights_, k, 0, True) for A, y, k, w in fits]),
    }  # fmt: skip
    halves = []
    for A, y, _, _ in fits:
        h = len(y) // 2
        halves.append([WeightedLeastSquares().fit(A[a:b], y[a:b]).theta_ - tv
                       for a, b in ((0, h), (h, len(y)))])  # fmt: skip
    halves = np.array(halves)
    print(f"  {'param':6s} " + " ".join(f"{k:>12s}" for k in stds) + "   half/half corr")
    for i, nm in enumerate(names):
        spread = theta[:, i].std(ddof=1)
        cells = " ".join(f"{spread / v[:, i].mean():12.2f}" for v in stds.values())
        corr = np.corrcoef(halves[:, 0, i], halves[:, 1, i])[0, 1]
        print(f"  {nm:6s} {cells}   {corr:+.2f}")
    inside = {k: float(np.mean(np.abs(theta - tv) <= 3 * v)) for k, v in stds.items()}
    print("  truth within 3 std: " + ", ".join(f"{k} {100 * v:.1f} %" for k, v in inside.items()))
    print(f"  (spread/std columns: 1 = honest; half/half corr: about +-{2 / np.sqrt(len(data)):.2f}"
          " by chance)")  # fmt: skip


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--keep", required=True, help="bench_std_check.py's --keep directory")
    ap.add_argument("--sets", default="schroeder60,default1200", help="comma-separated")
    ap.add_argument("--seeds", type=int, default=40)
    ap.add_argument("--first-seed", type=int, default=5000)
    a = ap.parse_args()
    seeds = range(a.first_seed, a.first_seed + a.seeds)
    for name in a.sets.split(","):
        check_set(name, Path(a.keep), seeds)


if __name__ == "__main__":
    main()
