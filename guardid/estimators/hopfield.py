"""Hopfield-network estimator (seed 000 eqs. 5-12, DESIGN.md section 5).

theta = c + S s, s in (-1, 1)^p, S = diag(half-widths), c = centre of the bounds, and
    ds/dt = (1/beta) (1 - s^2) * S A^T (y - A theta),
with A and y held over each sample period dt (equivalently du/dt = (1/beta) S A^T (y - A
theta) in the potential u = atanh(s)). beta (unit of y^2 times s) is the only gain.

Integrator: linearly implicit (Rosenbrock-W / backward-Euler-linearised) step in s with the
Jacobian approximated by J = -(1/beta) D S G S, D = diag(1 - s^2), G = A^T A:
    (D^-1 + h/beta S G S) ds = h/beta S A^T (y - A theta),    h = dt.
Dropping the d(D)/ds part of the Jacobian keeps the system matrix symmetric positive definite
for every beta > 0, dt > 0 and s, so the step always exists; for frozen D the step is the
L-stable implicit Euler step (error amplification (D^-1 + cSGS)^-1 D^-1, eigenvalues in
(0, 1]); for small dt/beta it reduces to the explicit Euler step of the ODE. Per sample, G
has rank n_out, so Woodbury gives ds = D B^T (beta/dt I + B D B^T)^-1 e with B = A S and e the
a-priori error: one n_out x n_out solve, no p x p algebra. For h/beta -> inf it becomes the
minimum-D^-1-norm step that zeroes the sample's error (a Kaczmarz projection).
A fraction-to-boundary rule (each step covers at most 90 % of the distance to the box face)
and a final clip to the largest double below 1 keep s strictly inside (-1, 1). Not
integrated in u = atanh(s) directly: a large implicit step in u overshoots through tanh and
can bounce between the bounds.

Offline ``fit`` with ``fit_block`` = K > 1 merges K consecutive samples into one step of
length K dt with G and S A^T e summed over the K samples (right-hand side time-averaged at
the frozen state): a first-order approximation of the sequential per-sample steps whose
error is O(K dt / settling time); ``fit_block=1`` is exact (same steps as ``update``).
With K > 1, ``history_`` is taken at the end of each block that reaches a multiple of
``history_every``; ``history_samples_`` holds the exact sample counts.

Measured (bench/bench_estimators.py, p = 12, n_out = 2, shared machine): online ``update``
15-25 us/sample; offline 240000 samples in 0.34-0.38 s with the default K = 16 (~650000
samples/s), 3.1-3.5 s with K = 1 (~70000-78000 samples/s).
"""

from __future__ import annotations

import numpy as np

from ._base import Estimator, as_blocks, as_sample, checkpoints

_SMAX = np.nextafter(1.0, 0.0)
_TAU = 0.9  # fraction-to-boundary


def _boundary_step(s: np.ndarray, ds: np.ndarray) -> np.ndarray:
    """s + alpha ds with alpha <= 1 keeping each component within 90 % of its distance."""
    room = 1.0 - s * np.sign(ds)
    frac = float(np.max(np.abs(ds) / room))
    if frac > _TAU:
        ds = ds * (_TAU / frac)
    s = s + ds
    np.minimum(s, _SMAX, out=s)
    np.maximum(s, -_SMAX, out=s)
    return s


class Hopfield(Estimator):
    """Hopfield estimator with bounded parameters.

    Parameters: ``theta_n`` nominal / initial estimate (p,) (default: centre of the box);
    ``bounds`` (lo, hi) arrays (p,), or ``half_widths`` (p,) around ``theta_n``; ``beta`` > 0
    gain (unit of y^2 times s; smaller = faster); ``dt`` sample period in s; ``fit_block``
    samples merged per offline step (see module doc); ``history_every`` history stride.
    Attributes: ``theta_`` (p,), ``s_`` (p,) in (-1, 1), ``scale_`` S (p,), ``center_`` (p,),
    ``n_samples_``, ``history_``, ``history_samples_``.
    """

    def __init__(
        self,
        theta_n=None,
        bounds=None,
        half_widths=None,
        beta: float = 0.01,
        dt: float = 0.015,
        fit_block: int = 16,
        history_every: int = 10,
    ):
        if beta <= 0 or dt <= 0:
            raise ValueError("beta and dt must be > 0")
        if bounds is not None:
            lo, hi = (np.asarray(b, dtype=float) for b in bounds)
            center, scale = 0.5 * (lo + hi), 0.5 * (hi - lo)
        elif half_widths is not None and theta_n is not None:
            center = np.asarray(theta_n, dtype=float)
            scale = np.asarray(half_widths, dtype=float) * np.ones_like(center)
        else:
            raise ValueError("give bounds=(lo, hi) or theta_n and half_widths")
        if np.any(scale <= 0):
            raise ValueError("bounds must have hi > lo (half-widths > 0)")
        th_n = center if theta_n is None else np.asarray(theta_n, dtype=float)
        s0 = (th_n - center) / scale
        if np.any(np.abs(s0) >= 1):
            raise ValueError("theta_n must lie strictly inside the bounds")
        self.center_, self.scale_, self._s0 = center, scale, s0
        self.theta_n = th_n
        self.beta, self.dt = float(beta), float(dt)
        self.fit_block = int(fit_block)
        self.history_every = int(history_every)
        self.reset()

    def reset(self):
        """Back to the nominal estimate (s = s0)."""
        self.s_ = self._s0.copy()
        self.theta_ = self.center_ + self.scale_ * self.s_
        self.n_samples_ = 0
        return self

    # -- online --------------------------------------------------------------------------
    def update(self, A_k, y_k):
        """One sample held over dt: A_k (n_out, p) or (p,), y_k (n_out,) or scalar."""
        A_k, y_k = as_sample(A_k, y_k)
        B = A_k * self.scale_
        self.s_ = _sample_step(self.s_, B, y_k - A_k @ self.center_, self.beta / self.dt)
        self.theta_ = self.center_ + self.scale_ * self.s_
        self.n_samples_ += 1
        return self

    # -- offline -------------------------------------------------------------------------
    def fit(self, A, y):
        """Run from the nominal estimate over the whole log (see ``fit_block``)."""
        A3, y2 = as_blocks(A, y)
        self.reset()
        N = A3.shape[0]
        B = A3 * self.scale_
        c = y2 - A3 @ self.center_
        k = max(self.history_every, 1)
        if self.fit_block <= 1:
            s, hist, _ = _run_samples(self.s_, B, c, self.beta / self.dt, k)
            counts = checkpoints(N, k)
        else:
            s, hist, counts = _run_blocks(self.s_, B, c, self.dt / self.beta, self.fit_block, k)
        self.s_ = s
        self.theta_ = self.center_ + self.scale_ * s
        self.history_ = self.center_ + self.scale_ * hist if len(hist) else np.empty((0, s.size))
        self.history_samples_ = counts
        self.n_samples_ = N
        return self


def _sample_step(s, B, e0, inv_c):
    """One exact per-sample step; B = A S (n, p), e0 = y - A c, inv_c = beta / dt."""
    D = 1.0 - s * s
    e = e0 - B @ s
    M = (B * D) @ B.T
    n = e.size
    if n == 2:
        q00, q01, q11 = M[0, 0], M[0, 1], M[1, 1]
        det = max(q00 * q11 - q01 * q01, 0.0) + (q00 + q11) * inv_c + inv_c * inv_c
        e0_, e1_ = e[0], e[1]
        w0 = ((q11 + inv_c) * e0_ - q01 * e1_) / det
        w1 = ((q00 + inv_c) * e1_ - q01 * e0_) / det
        v = w0 * B[0] + w1 * B[1]
    else:
        v = np.linalg.solve(M + inv_c * np.eye(n), e) @ B
    # ds = D v: |ds_i| / (1 - |s_i|) <= (1 + |s_i|) |v_i| < 2 |v_i|, so |v| < TAU / 2 is safe.
    if np.max(np.abs(v)) < 0.5 * _TAU:
        s = s + D * v
        np.minimum(s, _SMAX, out=s)
        np.maximum(s, -_SMAX, out=s)
        return s
    return _boundary_step(s, D * v)


def _run_samples(s, B, c, inv_c, every):
    """Exact sequential per-sample steps; returns final s and s at every ``every`` samples."""
    hist = []
    for i in range(B.shape[0]):
        s = _sample_step(s, B[i], c[i], inv_c)
        if (i + 1) % every == 0:
            hist.append(s)
    return s, np.array(hist), None


def _run_blocks(s, B, c, h_beta, K, every):
    """Steps over blocks of K samples with summed S G S and S A^T (y - A c)."""
    N, n, p = B.shape
    nb = -(-N // K)
    pad = nb * K - N
    if pad:
        B = np.concatenate([B, np.zeros((pad, n, p))])
        c = np.concatenate([c, np.zeros((pad, n))])
    Bb = B.reshape(nb, K * n, p)
    BT = Bb.transpose(0, 2, 1)
    G = BT @ Bb  # (nb, p, p)
    g = (BT @ c.reshape(nb, K * n, 1))[:, :, 0]
    ends = np.minimum(np.arange(1, nb + 1) * K, N)
    rec = (ends // every) > ((ends - K) // every)
    eye = np.eye(p)
    hist, counts = [], []
    for j in range(nb):
        d = np.sqrt(1.0 - s * s)
        Gj = G[j]
        r = g[j] - Gj @ s
        Mj = eye + h_beta * (np.multiply.outer(d, d) * Gj)
        ds = d * np.linalg.solve(Mj, h_beta * d * r)
        s = _boundary_step(s, ds)
        if rec[j]:
            hist.append(s)
            counts.append(ends[j])
    return s, np.array(hist), np.array(counts, dtype=int)
