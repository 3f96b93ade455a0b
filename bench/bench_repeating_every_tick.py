"""An error that repeats every excitation period, with rows at every tick: does least
squares' std count it? (docs/IDENTIFY.md, "An error that repeats every excitation period").

Synthetic, numpy only: a regressor of smooth periodic columns (a constant and ``--params`` - 1
sums of the period's first six harmonics), rows at every 15 ms tick over ``--periods``
periods of 667 ticks; the rows' error is a low-passed random draw repeated every period
(``share`` of the error's variance) plus low-passed white noise, both through identify's
Butterworth (order 2) at the cut-off whose spaced rows are ``--spacing`` ticks apart.
:class:`guardid.estimators.LeastSquares` with identify's window at every tick
(:func:`guardid.conditioning.momentum.correlation_ticks`: 4 spacings) and, per variant:

- ``none``: no groups (the rows' correlated noise only);
- ``tick``: identify's groups (:func:`guardid.identify.rows.period_groups`: the phases in bins
  one row spacing wide, here one tick);
- ``wide``: bins one spaced-row spacing wide (``--spacing`` ticks), centred alike.

Per variant: spread of the estimates over the draws (rms error, the truth known) over the
mean reported std, median and worst over the parameters (1: the std is right; above 1: too
small), and the share of (draw, parameter) pairs within 3 std.

    python bench/bench_repeating_every_tick.py --draws 300 --shares 0,0.2,0.5,0.8
"""

from __future__ import annotations

import argparse
from types import SimpleNamespace

import numpy as np
from scipy.signal import butter, sosfilt

from guardid.conditioning.momentum import correlation_ticks
from guardid.estimators import LeastSquares
from guardid.identify.rows import period_groups

DT = 0.015
"""[s] the guard's tick."""
PERIOD_TICKS = 667
"""[ticks] the excitation's period (about 10 s)."""


def regressor(n_rows: int, n_params: int, seed: int = 12345) -> np.ndarray:
    """(n_rows, n_params): a constant and smooth columns periodic in PERIOD_TICKS."""
    rng = np.random.default_rng(seed)
    phase = 2 * np.pi * np.arange(n_rows) / PERIOD_TICKS
    cols = [np.ones(n_rows)]
    for _ in range(n_params - 1):
        a, b = rng.normal(size=(2, 6)) / np.arange(1, 7)
        h = np.arange(1, 7)[None, :] * phase[:, None]
        cols.append(np.sin(h) @ a + np.cos(h) @ b)
    return np.column_stack(cols)


def labels(n_rows: int, width: int) -> np.ndarray:
    """The phase groups of rows at every tick, in bins ``width`` ticks wide (1: identify's)."""
    t = np.arange(n_rows) * DT
    if width == 1:
        return period_groups([SimpleNamespace(t=t, mask=np.ones(n_rows, bool))],
                             [PERIOD_TICKS * DT])  # fmt: skip
    bins = max(round(PERIOD_TICKS / width), 1)
    return np.rint(np.mod(t, PERIOD_TICKS * DT) / (PERIOD_TICKS * DT) * bins).astype(int) % bins


def check(draws: int, spacing: int, periods: int, n_params: int, share: float, seed: int):
    """{variant: (spread/std per parameter, within 3 std per parameter)}."""
    fs = 1.0 / DT
    cutoff = fs / (2.0 * spacing)
    sos = butter(2, cutoff, btype="low", fs=fs, output="sos")
    lag = correlation_ticks(fs, cutoff)
    n_rows = PERIOD_TICKS * periods
    A = regressor(n_rows, n_params)
    ticks = np.arange(n_rows)
    groups = {"none": None, "tick": labels(n_rows, 1), "wide": labels(n_rows, spacing)}
    impulse = sosfilt(sos, np.r_[1.0, np.zeros(4000)])
    scale = np.sqrt(impulse @ impulse)  # the filtered unit noise's std
    burn = 20 * spacing
    rng = np.random.default_rng(seed)
    err = {v: [] for v in groups}
    std = {v: [] for v in groups}
    for _ in range(draws):
        once = sosfilt(sos, np.tile(rng.normal(size=PERIOD_TICKS), 4))[-PERIOD_TICKS:]
        white = sosfilt(sos, rng.normal(size=n_rows + burn))[burn:]
        e = (np.sqrt(share) * np.tile(once, periods) + np.sqrt(1 - share) * white) / scale
        for v, g in groups.items():
            fit = LeastSquares(row_groups=g, row_ticks=ticks, lag_ticks=lag).fit(A, e)
            err[v].append(fit.theta_)  # the truth is 0
            std[v].append(fit.std_)
    out = {}
    for v in groups:
        E, S = np.array(err[v]), np.array(std[v])
        out[v] = (np.sqrt(np.mean(E**2, axis=0)) / np.mean(S, axis=0),
                  np.mean(np.abs(E) <= 3 * S, axis=0))  # fmt: skip
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--draws", type=int, default=300)
    ap.add_argument("--spacing", type=int, default=16, help="spaced rows' spacing [ticks]")
    ap.add_argument("--periods", type=int, default=20)
    ap.add_argument("--params", type=int, default=5)
    ap.add_argument("--shares", default="0,0.2,0.5,0.8", help="the repeating share(s)")
    ap.add_argument("--seed", type=int, default=0, help="the draws': seed + 100 x share")
    args = ap.parse_args()
    for share in (float(s) for s in args.shares.split(",")):
        # the same draws for a share whatever else is asked (the seed + 100 x the share)
        seed = args.seed + round(100 * share)
        res = check(args.draws, args.spacing, args.periods, args.params, share, seed)
        for v, (ratio, inside) in res.items():
            print(f"spacing {args.spacing:2d} periods {args.periods:2d} params {args.params:2d} "
                  f"share {share:.1f} {v:5s} spread/std median {np.median(ratio):.2f} "
                  f"worst {ratio.max():.2f}; within 3 std {inside.mean():.3f} "
                  f"(lowest {inside.min():.3f})", flush=True)  # fmt: skip


if __name__ == "__main__":
    main()
