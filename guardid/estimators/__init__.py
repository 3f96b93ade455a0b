"""Linear-in-the-parameters estimators: LS, WLS, RLS, Hopfield, gradient, and metrics.

All share ``fit(A, y)`` (A (N, n_out, p) with y (N, n_out), or stacked A (M, p) with y (M,))
and ``update(A_k, y_k)``; learned state in ``theta_`` and friends (see each class).
"""

from .gradient import Gradient
from .hopfield import Hopfield
from .ls import ColumnNoise, LeastSquares, WeightedLeastSquares
from .metrics import d_tau, d_theta
from .mlp import MLP
from .rls import RLS

__all__ = [
    "ColumnNoise",
    "MLP",
    "RLS",
    "Gradient",
    "Hopfield",
    "LeastSquares",
    "WeightedLeastSquares",
    "d_tau",
    "d_theta",
]
