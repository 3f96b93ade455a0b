"""Gradient estimator (seed 000 eq. 4), the gain-tuned baseline.

dtheta/dt = -eta grad_theta(e^T e) = 2 eta A^T (y - A theta), integrated by explicit Euler
with A, y held over each sample period dt: theta += 2 eta dt A_k^T (y_k - A_k theta).
It diverges when 2 eta dt lambda_max(A_k^T A_k) is too large: divergence is detected
(non-finite or |theta| > ``blowup``) and reported in ``diverged_`` / ``diverged_at_``; the
offline run stops there and ``theta_`` keeps the last (huge) value.

``integrator="implicit"`` (an option for fair comparisons with the Hopfield network, which
is integrated that way by default): the linearly implicit (backward Euler) step of the same
ODE with A_k, y_k frozen over the sample,
    (I + 2 eta dt A_k^T A_k) dtheta = 2 eta dt A_k^T (y_k - A_k theta),
computed by Woodbury as dtheta = A_k^T (I / (2 eta dt) + A_k A_k^T)^-1 e_k (one n_out x n_out
solve). The ODE is linear in theta, so this is exactly implicit Euler: the error along an
eigenvector of A_k^T A_k with eigenvalue mu is multiplied by 1 / (1 + 2 eta dt mu), in (0, 1]
for every eta, dt > 0 (explicit Euler: 1 - 2 eta dt mu, stable only for 2 eta dt mu < 2).
"""

from __future__ import annotations

import numpy as np

from . import native_loops
from ._base import Estimator, as_blocks, as_sample

_CHECK = 64  # offline divergence check stride (samples)
INTEGRATORS = ("euler", "implicit")


class Gradient(Estimator):
    """Parameters: ``eta`` gain (1 / (unit of A^2 s)), ``dt`` sample period s, ``theta0``,
    ``history_every``, ``blowup`` divergence threshold on max |theta|, ``integrator``
    "euler" (default, eq. 4 as the paper integrates it) or "implicit" (module doc).
    Attributes: ``theta_``, ``diverged_``, ``diverged_at_`` (sample count or None),
    ``n_samples_``, ``history_``, ``history_samples_``.
    """

    def __init__(
        self, eta=1e-2, dt=1.0, theta0=None, history_every=10, blowup=1e100, integrator="euler"
    ):
        if integrator not in INTEGRATORS:
            raise ValueError(f"integrator must be one of {INTEGRATORS}, not {integrator!r}")
        self.integrator = integrator
        self.eta, self.dt, self.theta0 = float(eta), float(dt), theta0
        self.history_every, self.blowup = int(history_every), float(blowup)

    def _init_state(self, p):
        self.theta_ = np.zeros(p) if self.theta0 is None else np.array(self.theta0, dtype=float)
        self.diverged_, self.diverged_at_, self.n_samples_ = False, None, 0

    def _check(self):
        if not self.diverged_ and not np.max(np.abs(self.theta_)) < self.blowup:
            self.diverged_, self.diverged_at_ = True, self.n_samples_

    def _implicit_step(self, th, A_k, y_k):
        """Backward Euler step (module doc): th + A_k^T (I / c + A_k A_k^T)^-1 (y_k - A_k th)."""
        M = A_k @ A_k.T
        M[np.diag_indices_from(M)] += 1.0 / (2 * self.eta * self.dt)
        e = y_k - A_k @ th
        if e.shape == (2,):  # 2 x 2 by Cramer's rule (M is symmetric positive definite)
            (m00, m01), (_, m11) = M.tolist()
            e0, e1 = e.tolist()
            det = m00 * m11 - m01 * m01
            return th + A_k.T @ np.array([m11 * e0 - m01 * e1, m00 * e1 - m01 * e0]) / det
        return th + A_k.T @ np.linalg.solve(M, e)

    def update(self, A_k, y_k):
        """One step (explicit Euler or implicit) for sample A_k (n_out, p), y_k (n_out,)."""
        A_k, y_k = as_sample(A_k, y_k)
        if not hasattr(self, "theta_"):
            self._init_state(A_k.shape[1])
        with np.errstate(over="ignore", invalid="ignore"):
            if self.integrator == "implicit":
                self.theta_ = self._implicit_step(self.theta_, A_k, y_k)
            else:
                self.theta_ = self.theta_ + (2 * self.eta * self.dt) * (
                    A_k.T @ (y_k - A_k @ self.theta_)
                )
        self.n_samples_ += 1
        self._check()
        return self

    def fit(self, A, y):
        """Run from theta0 over the log; stops at detected divergence."""
        A3, y2 = as_blocks(A, y)
        N, n, p = A3.shape
        self._init_state(p)
        AT = A3.transpose(0, 2, 1)
        if self.integrator == "implicit":
            # per-sample gain A_k^T (I / c + A_k A_k^T)^-1, all samples at once
            M = A3 @ AT + np.eye(n) / (2 * self.eta * self.dt)
            gAT = AT @ np.linalg.inv(M)
        else:
            gAT = (2 * self.eta * self.dt) * AT
        every = max(self.history_every, 1)
        lib = native_loops.kernel()
        if lib is not None:  # the loop of _run_samples, in C
            th, hist, done = native_loops.gradient_samples(
                lib, A3, y2, gAT, self.theta_, every, _CHECK, self.blowup
            )
        else:
            th, hist, done = _run_samples(A3, y2, gAT, self.theta_, every, self.blowup)
        if done < N:  # stopped at a check
            self.theta_, self.n_samples_ = th, done
            self._check()
        self.theta_ = th
        self.n_samples_ = self.diverged_at_ or N
        self._check()
        self.history_ = np.array(hist).reshape(-1, p)
        self.history_samples_ = np.arange(every, done + 1, every, dtype=int)
        return self


def _run_samples(A3, y2, gAT, theta0, every: int, blowup: float):
    """theta += gAT_k (y_k - A_k theta) sample after sample from theta0, stopping at a check
    (every :data:`_CHECK` samples) where max |theta| is not below ``blowup``: (theta, theta
    after every ``every``-th sample done, samples done)."""
    th, hist = theta0, []
    with np.errstate(over="ignore", invalid="ignore"):
        for i in range(A3.shape[0]):
            th = th + gAT[i] @ (y2[i] - A3[i] @ th)
            if (i + 1) % every == 0:
                hist.append(th)
            if (i + 1) % _CHECK == 0 and not np.max(np.abs(th)) < blowup:
                return th, hist, i + 1
    return th, hist, A3.shape[0]
