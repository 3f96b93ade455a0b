"""guardid.identify.untrusted on regressors whose rank and conditioning are known by construction.

Two columns of norm L at an angle phi: after scaling to unit norm the singular values are
sqrt(1 + cos phi) and sqrt(1 - cos phi) (the Gram matrix is [[1, c], [c, 1]]), so the
least-determined direction has standard deviation sigma / sqrt(1 - cos phi), to be compared
with ||L theta|| worked out by hand.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from guardid.estimators import LeastSquares
from guardid.identify.pipeline import MethodResult
from guardid.identify.untrusted import regressor_problems, trust_problems

NAMES = ("a", "b")


def _r_of(columns: np.ndarray) -> np.ndarray:
    return np.linalg.qr(columns, mode="r")


def _two_columns(length: float, cos_phi: float, rows: int = 50) -> np.ndarray:
    a = np.zeros((rows, 2))
    a[0, 0] = length
    a[0, 1] = length * cos_phi
    a[1, 1] = length * math.sqrt(1.0 - cos_phi**2)
    return a


def test_orthogonal_columns_are_trusted():
    r = _r_of(_two_columns(3.0, 0.0))
    assert regressor_problems(r, 50, sigma=0.1, theta=[1.0, 1.0], names=NAMES) == []


def test_zero_column_is_named():
    a = _two_columns(3.0, 0.0)
    a[:, 1] = 0.0
    (problem,) = regressor_problems(_r_of(a), 50, sigma=0.1, theta=[1.0, 0.0], names=NAMES)
    assert problem.startswith("b: regressor column zero")


def test_identical_columns_are_rank_deficient():
    a = _two_columns(3.0, 1.0)  # cos phi = 1: the same column twice
    (problem,) = regressor_problems(_r_of(a), 50, sigma=0.1, theta=[1.0, 1.0], names=NAMES)
    assert "rank 1 of 2" in problem and "a" in problem and "b" in problem


@pytest.mark.parametrize(
    ("sigma", "flagged"),
    # 1 - cos phi = 0.01: s_min = 0.1; ||L theta|| = 2 sqrt(2) = 2.83 for L = 2, theta = (1, 1)
    # worst std sigma / 0.1: 0.25 -> 2.5 (trusted), 0.3 -> 3.0 (not trusted)
    [(0.25, False), (0.3, True)],
)
def test_nearly_collinear_columns_against_the_hand_worked_threshold(sigma, flagged):
    r = _r_of(_two_columns(2.0, 0.99))
    problems = regressor_problems(r, 50, sigma=sigma, theta=[1.0, 1.0], names=NAMES)
    assert bool(problems) is flagged
    if flagged:
        assert "nearly unexcited" in problems[0]
        assert f"{100 * sigma / 0.1 / (2 * math.sqrt(2)):.0f} %" in problems[0]  # 106 %


def test_non_finite_estimates_are_named():
    rng = np.random.default_rng(0)
    a = rng.standard_normal((40, 2))
    ls = LeastSquares().fit(a, a @ np.array([1.0, 2.0]) + 0.01 * rng.standard_normal(40))
    results = {
        "ls": MethodResult("ls", ls.theta_, ls.std_),
        "hopfield": MethodResult("hopfield", np.array([np.nan, 2.0])),
    }
    problems = trust_problems(ls, NAMES, results)
    assert problems == ["HOPFIELD estimate not finite for a"]
