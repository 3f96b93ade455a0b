"""The live uncertainty of capture --until-std against an independent numpy fit."""

from __future__ import annotations

import numpy as np
import pytest

from guardid.online.information import DecimatedLS, assess


def test_decimated_ls_equals_numpy_on_the_rows_it_takes():
    rng = np.random.default_rng(7)
    p, n_rows, every = 4, 300, 3
    theta = np.array([1.0, -2.0, 0.5, 3.0])
    A = rng.standard_normal((n_rows, 2, p))
    y = A @ theta + 0.1 * rng.standard_normal((n_rows, 2))
    est = DecimatedLS(every)
    for k in range(n_rows):
        # one joint's equation only, now and then (a stuck joint's is held back)
        rows = slice(0, 1) if k % 7 == 0 else slice(0, 2)
        est.update(A[k, rows], y[k, rows])
    taken = [k for k in range(n_rows) if k % every == 0]
    As = np.vstack([A[k, :1] if k % 7 == 0 else A[k] for k in taken])
    ys = np.concatenate([y[k, :1] if k % 7 == 0 else y[k] for k in taken])
    ref, rss, *_ = np.linalg.lstsq(As, ys, rcond=None)
    sigma2 = rss[0] / (len(ys) - p)
    ref_std = np.sqrt(np.diag(sigma2 * np.linalg.inv(As.T @ As)))
    assert est.rows_ == len(taken)
    np.testing.assert_allclose(est.theta_, ref, rtol=1e-10)
    np.testing.assert_allclose(est.std_, ref_std, rtol=1e-8)


def test_decimation_is_one_row_per_half_cutoff_period():
    assert DecimatedLS.every_for(4.0, 0.015) == 8  # 1 / (0.015 s x 8 Hz) = 8.3
    assert DecimatedLS.every_for(100.0, 0.001) == 5
    assert DecimatedLS.every_for(40.0, 0.015) == 1


@pytest.mark.parametrize(
    ("theta", "std", "resolved", "zero_like"),
    [
        # MY2's 0.07 is below a tenth of its kind's scale (MX2R 0.77): judged against 0.077
        ([0.77, 0.07], [0.0077, 0.0007], [True, True], [False, False]),  # 1 %, 0.91 %
        ([0.77, 0.07], [0.0077, 0.0021], [True, False], [False, False]),  # MY2 2.7 %
        ([0.77, 0.07], [0.0154, 0.0007], [True, True], [False, False]),  # MX2R 2.0 %
        ([0.77, 0.07], [0.0155, 0.0007], [False, True], [False, False]),  # MX2R 2.01 %
        # MY2 0.001 +- 0.001: zero-like; 0.001 / 0.077 = 1.3 %
        ([0.77, 0.001], [0.0077, 0.001], [True, True], [False, True]),
        # MY2 0.02 +- 0.1: zero-like and 130 %: not excited
        ([0.77, 0.02], [0.0077, 0.1], [True, False], [False, True]),
    ],
)
def test_assess_by_hand(theta, std, resolved, zero_like):
    a = assess(theta, std, ("MX2R", "MY2"), (0.77, 0.07), 2.0)
    assert a.resolved.tolist() == resolved
    assert a.zero_like.tolist() == zero_like
