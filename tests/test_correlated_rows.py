"""Least squares with errors shared by neighbouring samples (``row_ticks``, ``lag_ticks``):
the covariance from each output's residual autocovariance, checked against a direct double
sum and against the spread of the estimate over independent error draws."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.signal import lfilter

from guardid.estimators import ColumnNoise, LeastSquares, WeightedLeastSquares
from guardid.estimators import ls as ls_module


def _direct_cov(A3, y2, w, ticks, lag, noise=None):
    """The covariance written out: weighted solve by lstsq, then per output the residuals'
    autocovariance at each distance and the meat by a double loop over every pair of rows
    (independent of the estimator's pair search and matrix sums)."""
    N, n, p = A3.shape
    X = (A3 * w[None, :, None]).reshape(N * n, p)
    Y = (y2 * w[None, :]).reshape(-1)
    H = X.T @ X
    theta = np.linalg.lstsq(X, Y, rcond=None)[0]
    if noise is not None:  # bias-compensated normal equations, written out
        H = H - sum(w[j] ** 2 * noise.gram[j] for j in range(n))
        theta = np.linalg.solve(H, X.T @ Y - sum(w[j] ** 2 * noise.cross[j] for j in range(n)))
    r = y2 - A3 @ theta
    S = np.zeros((p, p))
    for j in range(n):
        rows = [t for t in range(N) if np.any(A3[t, j] != 0)]
        e = {t: w[j] * r[t, j] for t in rows}
        x = {t: w[j] * A3[t, j] for t in rows}
        gamma = {}
        for d in range(lag + 1):
            prods = [e[a] * e[b] for a in rows for b in rows if int(ticks[b]) - int(ticks[a]) == d]
            gamma[d] = sum(prods) / len(prods) if prods else 0.0
        for a in rows:
            for b in rows:
                d = abs(int(ticks[a]) - int(ticks[b]))
                if d <= lag:
                    S += gamma[d] * np.outer(x[a], x[b])
    live = [t for t in range(N) if np.any(A3[t] != 0)]
    weights = sum(1.0 - abs(int(ticks[a]) - int(ticks[b])) / (lag + 1.0) for a in live for b in live
                  if abs(int(ticks[a]) - int(ticks[b])) <= lag)  # fmt: skip
    m = len(live)
    Hinv = np.linalg.inv(H)
    return theta, m / (m - p * weights / m) * Hinv @ S @ Hinv


@pytest.mark.parametrize("weighted", [False, True])
@pytest.mark.parametrize("compensated", [False, True])
@pytest.mark.parametrize("layout", ["ticks", "every-3rd", "chunked"])
def test_covariance_is_the_double_sum_over_pairs(weighted, compensated, layout, monkeypatch):
    """``every-3rd``: rows 3 ticks apart (a window of 16 ticks: pairs at 3, 6, .., 15);
    ``chunked``: the tick grid in chunks of 7 points (pairs across every chunk's edge)."""
    rng = np.random.default_rng(3)
    N, n, p, lag = 60, 2, 3, 5
    A3 = rng.normal(size=(N, n, p))
    A3[7] = 0.0  # a sample whose every equation is cut: no score, not counted
    A3[20, 1] = 0.0  # one equation cut
    y2 = A3 @ np.array([1.0, -2.0, 0.5]) + rng.normal(size=(N, n))
    ticks = np.cumsum(rng.choice([1, 1, 1, 2, 9], size=N))  # gaps, one beyond the lag
    if layout == "every-3rd":
        ticks, lag = 3 * ticks + 1000, 16
    if layout == "chunked":
        monkeypatch.setattr(ls_module, "GRID_CHUNK", 7)
    noise = None
    if compensated:  # a small known column noise: the bread is the compensated matrix's
        G = rng.normal(size=(n, p, p))
        noise = ColumnNoise(0.5 * np.einsum("jab,jcb->jac", G, G), rng.normal(size=(n, p)))
    order = rng.permutation(N)  # the samples in any order: the ticks say who is near whom
    cls = WeightedLeastSquares if weighted else LeastSquares
    est = cls(column_noise=noise, row_ticks=ticks[order], lag_ticks=lag)
    est.fit(A3[order], y2[order])
    assert est.compensated_ == compensated
    w = est._w if weighted else np.ones(n)
    theta, cov = _direct_cov(A3, y2, w, ticks, lag, noise)
    assert np.allclose(est.theta_, theta, rtol=1e-9, atol=1e-12)
    assert np.allclose(est.cov_, cov, rtol=1e-9, atol=1e-14)


def test_no_lag_keeps_the_white_covariance():
    rng = np.random.default_rng(4)
    A = rng.normal(size=(80, 3))
    y = A @ np.ones(3) + rng.normal(size=80)
    plain = LeastSquares().fit(A, y)
    zero = LeastSquares(row_ticks=np.arange(80), lag_ticks=0).fit(A, y)
    assert np.allclose(zero.cov_, plain.cov_)


def test_ticks_of_another_length_are_refused():
    A = np.ones((10, 1, 1))
    with pytest.raises(ValueError, match="row_ticks"):
        LeastSquares(row_ticks=np.arange(9), lag_ticks=2).fit(A, np.ones((10, 1)))


def _smooth_design(N, p, rng):
    t = np.arange(N)
    cols = [np.ones(N)] + [np.sin(2 * np.pi * t * (k + 1) / N + rng.uniform(0, 6)) for k in
                           range(p - 1)]  # fmt: skip
    return np.column_stack(cols)


def _coverage(lag, seeds, N, p, pole):
    """(spread over error draws / mean reported std) per parameter, for errors low-passed
    white noise (a pole at ``pole``: correlated over about 1 / (1 - pole) samples)."""
    rng = np.random.default_rng(11)
    A = _smooth_design(N, p, rng)
    thetas, stds = [], []
    for s in range(seeds):
        e = lfilter([1.0 - pole], [1.0, -pole], np.random.default_rng(100 + s).normal(size=N))
        est = LeastSquares(row_ticks=np.arange(N), lag_ticks=lag).fit(A, A @ np.ones(p) + e)
        thetas.append(est.theta_)
        stds.append(est.std_)
    return np.std(thetas, axis=0, ddof=1) / np.mean(stds, axis=0)


def test_correlated_errors_are_covered_and_the_white_std_is_not():
    ratio = _coverage(lag=40, seeds=400, N=3000, p=3, pole=0.8)
    # 400 draws: a ratio's sampling error is about 4 %
    assert np.all((ratio > 0.85) & (ratio < 1.15)), ratio
    white = _coverage(lag=0, seeds=400, N=3000, p=3, pole=0.8)
    assert np.all(white > 2.0), white  # the long-run variance is 9x the white one


def test_the_fit_s_share_of_each_window_is_given_back():
    """A short run (600 samples, errors correlated over about 10) with a long window (60):
    the residuals miss what the fit takes up. With the N / (N - p k) factor the std is at
    most 1.42x too small here (0.92-1.42 over the five parameters, 400 draws), without it
    up to 1.98x (1.29-1.98). At the real logs' sizes (moderate: 1000-2000 samples, window
    30-40) the factor leaves 1.03-1.14, without it 1.07-1.23."""
    ratio = _coverage(lag=60, seeds=400, N=600, p=5, pole=0.9)
    assert np.all((ratio > 0.85) & (ratio < 1.5)), ratio
