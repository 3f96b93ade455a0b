"""Shared shape handling and base class for the linear-in-the-parameters estimators.

Model: y = A theta, one row block per sample.

Shapes accepted by every ``fit(A, y)``:

* ``A`` (N, n_out, p) and ``y`` (N, n_out): N samples, n_out outputs per sample (e.g. the
  2 joint torques, N m), p parameters (SI units of the regressor columns);
* ``A`` (M, p) and ``y`` (M,): M stacked rows, each treated as a 1-output sample.

``update(A_k, y_k)`` takes one sample: ``A_k`` (n_out, p) or (p,), ``y_k`` (n_out,) or scalar.
"""

from __future__ import annotations

import numpy as np


def as_blocks(A, y) -> tuple[np.ndarray, np.ndarray]:
    """Return ``(A3, y2)`` with shapes (N, n_out, p) and (N, n_out), float64."""
    A = np.asarray(A, dtype=float)
    y = np.asarray(y, dtype=float)
    if A.ndim == 2:
        A = A[:, None, :]
        y = y.reshape(-1, 1)
    if A.ndim != 3 or y.shape != A.shape[:2]:
        raise ValueError(f"A {A.shape} and y {y.shape}: expected (N,n,p)/(N,n) or (M,p)/(M,)")
    return A, y


def as_sample(A_k, y_k) -> tuple[np.ndarray, np.ndarray]:
    """Return one sample as ``(A_k, y_k)`` with shapes (n_out, p) and (n_out,)."""
    if (
        type(A_k) is np.ndarray
        and type(y_k) is np.ndarray
        and A_k.ndim == 2
        and A_k.dtype == np.float64
        and y_k.shape == (A_k.shape[0],)
    ):
        return A_k, y_k  # fast path for the online loops
    A_k = np.atleast_2d(np.asarray(A_k, dtype=float))
    y_k = np.atleast_1d(np.asarray(y_k, dtype=float))
    if y_k.shape != (A_k.shape[0],):
        raise ValueError(f"A_k {A_k.shape} and y_k {y_k.shape} do not match")
    return A_k, y_k


def checkpoints(n: int, every: int) -> np.ndarray:
    """Sample counts (1-based) at which ``history_`` is recorded: every, 2 every, ... <= n."""
    return np.arange(every, n + 1, every)


class Estimator:
    """Common interface: ``fit(A, y)`` (batch / offline), ``update(A_k, y_k)`` (online).

    Learned state lives in attributes ending with ``_`` (``theta_``, ...). ``history_``
    (n_hist, p) holds the estimate after ``history_samples_`` samples of the last ``fit``
    (every ``history_every``-th sample), or None for batch-only estimators.
    """

    theta_: np.ndarray
    history_: np.ndarray | None = None
    history_samples_: np.ndarray | None = None

    def predict(self, A) -> np.ndarray:
        """Model output A theta_, shape (N, n_out) or (M,) like the ``y`` of ``fit``."""
        return np.asarray(A, dtype=float) @ self.theta_
