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

``integrator="euler"`` (an option for fair comparisons; the paper's integrator, DESIGN.md
section 5): the explicit Euler step of the same ODE in s, per sample,
    s += (dt/beta) (1 - s^2) * S A_k^T (y_k - A_k theta),
with no fraction-to-boundary rule and no clip. Near an interior equilibrium s* it multiplies
the error along an eigenvector of D S A_k^T A_k S (D = diag(1 - s*^2)) with eigenvalue mu by
1 - (dt/beta) mu: stable only for (dt/beta) mu < 2. Once a component leaves (-1, 1), its
1 - s^2 turns negative and the step pushes it further out: the run diverges; that is
detected (non-finite or max |s| > ``blowup``) and recorded in ``diverged_`` /
``diverged_at_`` (sample count); the offline run stops there. Per sample only (``fit_block``
is ignored; offline, divergence is checked every 64 samples); not with windowed weights.

Offline ``fit`` with ``fit_block`` = K > 1 merges K consecutive samples into one step of
length K dt with G and S A^T e summed over the K samples (right-hand side time-averaged at
the frozen state): a first-order approximation of the sequential per-sample steps whose
error is O(K dt / settling time); ``fit_block=1`` is exact (same steps as ``update``).
With K > 1, ``history_`` is taken at the end of each block that reaches a multiple of
``history_every``; ``history_samples_`` holds the exact sample counts.

Windowed weights (``lam`` given; an extension for tracking, not in seed 000): the network's
weights and biases are the information of an exponentially forgetting window instead of
the current sample's,
    W_k = lam W_{k-1} + A_k^T A_k + (1 - lam) F,
    b_k = lam b_{k-1} + A_k^T y_k + (1 - lam) F theta,
W_0 = S^-2, b_0 = W_0 theta_n (a prior of one half-width per parameter), F = diag(``info_floor``)
(regularised forgetting: the information never falls below F, so unexcited directions cannot
wind up). Each sample takes one linearly implicit step of ds/dt = (1/beta)(1 - s^2) * S (b - W
theta) with the p x p system (D^-1 + h/beta S W S) ds = h/beta S (b - W theta). The energy is
then the window's squared prediction error, whose minimum is the forgetting least-squares
estimate: the network follows it (inside the box) with a lag set by beta, and with a memory
of about 1 / (1 - lam) samples, so a parameter the current sample hardly excites is still
resolved. :meth:`discard` resets the information of chosen parameters (after a detected
change). Costs one p x p solve per sample.

Online fast path (n_out = 2, float64 arrays): the same step with the work arrays kept
between samples: Dm = diag(S^2 D) (p, p) is updated through a view of its diagonal, so
M = A S D S A^T and A theta come from two small matrix products (A Dm, then A [A Dm ; theta]^T);
the 2 x 2 solve is done in Python floats. ``fit_block=1`` with 2 outputs runs this path,
in C when a compiler is at hand (:mod:`guardid.estimators.native_loops`, the same steps to
round-off; ``GUARDID_NATIVE=0``: in Python).

Measured (bench/bench_estimators.py, p = 12, n_out = 2, shared machine): online ``update``
6.3-6.7 us/sample in the quieter passes (~3x faster than padasip's FilterRLS fed the same
rows in the same run; 15-25 us/sample before the fast path); offline 240000 samples in
0.34-0.38 s with the default K = 16 (~650000 samples/s), ~1.8 s with K = 1 (~130000
samples/s; 3.1-3.5 s before) in Python; K = 1 in C 0.03 s of CPU (2026-11-27, the same
240000 random samples, p = 12, loaded machine).
"""

from __future__ import annotations

import functools
from math import sqrt as _sqrt

import numpy as np
from scipy.linalg.lapack import dposv as _dposv

from . import native_loops
from ._base import Estimator, as_blocks, as_sample, checkpoints

_SMAX = np.nextafter(1.0, 0.0)
_TAU = 0.9  # fraction-to-boundary
_VSAFE2 = (0.5 * _TAU) ** 2  # |v|_2^2 below this: all |v_i| < TAU / 2 (see _sample_step)
_F64 = np.dtype(np.float64)
_multiply = np.multiply
_subtract = np.subtract
_add = np.add
_minimum = np.minimum
_maximum = np.maximum
_SHAPE2 = (2,)


@functools.cache
def _diagonal(p: int) -> np.ndarray:
    """Indices 0..p-1: ``M[d, d]`` is the diagonal of a (p, p) matrix."""
    return np.arange(p)


def _boundary_step(s: np.ndarray, ds: np.ndarray) -> np.ndarray:
    """s + alpha ds with alpha <= 1 keeping each component within 90 % of its distance."""
    room = 1.0 - s * np.sign(ds)
    frac = float((np.abs(ds) / room).max())
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
    samples merged per offline step (see module doc); ``history_every`` history stride;
    ``integrator`` "implicit" (default, linearly implicit step) or "euler" (explicit Euler in
    s, the paper's; ``blowup`` bounds max |s| before a run counts as diverged).
    Attributes: ``theta_`` (p,), ``s_`` (p,) in (-1, 1), ``scale_`` S (p,), ``center_`` (p,),
    ``n_samples_``, ``history_``, ``history_samples_``.
    """

    _ws = None  # fast-path work arrays (see ``_make_workspace``)
    _ws_s = None
    _ws_b = 1.0  # upper bound on max |s_i| for the fast path

    def __init__(
        self,
        theta_n=None,
        bounds=None,
        half_widths=None,
        beta: float = 0.01,
        dt: float = 0.015,
        fit_block: int = 16,
        history_every: int = 10,
        lam: float | None = None,
        info_floor=None,
        integrator: str = "implicit",
        blowup: float = 1e6,
    ):
        if integrator not in ("implicit", "euler"):
            raise ValueError(f"integrator must be 'implicit' or 'euler', not {integrator!r}")
        if integrator == "euler" and lam is not None:
            raise ValueError("integrator='euler' is per sample only (no windowed weights)")
        self.integrator, self.blowup = integrator, float(blowup)
        if beta <= 0 or dt <= 0:
            raise ValueError("beta and dt must be > 0")
        if lam is not None and not 0.0 < lam <= 1.0:
            raise ValueError("lam must be in (0, 1]")
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
        self.lam = None if lam is None else float(lam)
        self.info_floor = None if info_floor is None else np.asarray(info_floor, dtype=float)
        self.reset()

    def __getstate__(self):
        """Pickle / copy without the fast-path work arrays (rebuilt on the next update)."""
        state = self.__dict__.copy()
        state.pop("_ws", None)
        return state

    def reset(self):
        """Back to the nominal estimate (s = s0)."""
        self._ws = None
        self.s_ = self._s0.copy()
        self.theta_ = self.center_ + self.scale_ * self.s_
        self.n_samples_ = 0
        self.diverged_, self.diverged_at_ = False, None
        if self.lam is not None:
            self.W_ = np.diag(1.0 / self.scale_**2)
            self.b_ = self.W_ @ self.theta_
        return self

    def discard(self, idx, theta=None):
        """Windowed weights only: forget what the data said about parameters ``idx``.

        Their information goes back to the prior (1 / half-width^2, no cross terms); the
        other parameters keep their marginal information (the Schur complement). ``theta``
        (p,) inside the box, if given, becomes the state; the biases are set so that the
        weights' minimum is the current estimate. Returns ``self``.
        """
        if self.lam is None:
            raise ValueError("discard needs windowed weights (lam)")
        idx = np.asarray(idx, dtype=int)
        keep = np.setdiff1d(np.arange(self.s_.size), idx)
        W = self.W_
        Wk = W[np.ix_(keep, keep)]
        if idx.size and keep.size:
            Wik = W[np.ix_(idx, keep)]
            Wk = Wk - Wik.T @ np.linalg.solve(W[np.ix_(idx, idx)], Wik)
        out = np.zeros_like(W)
        out[np.ix_(keep, keep)] = Wk
        out[idx, idx] = 1.0 / self.scale_[idx] ** 2
        if theta is not None:
            s = (np.asarray(theta, dtype=float) - self.center_) / self.scale_
            self.s_ = np.clip(s, -_SMAX, _SMAX)
            self.theta_ = self.center_ + self.scale_ * self.s_
        self.W_ = out
        self.b_ = out @ self.theta_
        return self

    def _update_windowed(self, A_k, y_k):
        """One sample with the windowed weights (module doc)."""
        lam = self.lam
        W, b = self.W_, self.b_
        W *= lam
        W += A_k.T @ A_k
        b *= lam
        b += A_k.T @ y_k
        diag = _diagonal(W.shape[0])
        if self.info_floor is not None and lam < 1.0:
            f = (1.0 - lam) * self.info_floor
            W[diag, diag] += f
            b += f * self.theta_
        S, s = self.scale_, self.s_
        g = self.dt / self.beta
        M = g * (S[:, None] * W * S[None, :])
        M[diag, diag] += 1.0 / (1.0 - s * s)
        rhs = g * S * (b - W @ self.theta_)
        # M = D + g S W S is symmetric positive definite (D >= I, W >= 0): Cholesky, with
        # LAPACK called directly (numpy.linalg.solve's checks cost more than the solve here)
        _, ds, info = _dposv(M, rhs, overwrite_a=1)
        if info != 0:  # not positive definite by round-off
            ds = np.linalg.solve(M, rhs)
        self.s_ = _boundary_step(s, ds)
        self.theta_ = self.center_ + S * self.s_
        self.n_samples_ += 1
        return self

    # -- online --------------------------------------------------------------------------
    def update(self, A_k, y_k):
        """One sample held over dt: A_k (n_out, p) or (p,), y_k (n_out,) or scalar.

        With n_out = 2 and float64 ndarray inputs of the state's shape this takes a fast path
        (cheap type/shape checks, preallocated work arrays, the 2 x 2 solve in Python floats;
        the same step as the general one up to round-off). ``s_`` and ``theta_`` are new
        arrays after every sample; replacing ``s_``, ``center_`` or ``scale_`` by new arrays
        is picked up at the next call; treat them as read-only otherwise.
        """
        if self.lam is not None:
            return self._update_windowed(*as_sample(A_k, y_k))
        if self.integrator == "euler":
            return self._update_euler(*as_sample(A_k, y_k))
        ws = self._ws
        if (
            ws is None
            or type(A_k) is not np.ndarray
            or type(y_k) is not np.ndarray
            or A_k.shape != ws[0]
            or y_k.shape != _SHAPE2
            or A_k.dtype is not _F64
            or y_k.dtype is not _F64
            or self.s_ is not self._ws_s
        ):
            A_k, y_k = as_sample(A_k, y_k)
            if A_k.shape[0] != 2 or A_k.shape[1] != self.s_.shape[0]:
                B = A_k * self.scale_
                self.s_ = _sample_step(self.s_, B, y_k - A_k @ self.center_, self.beta / self.dt)
                self.theta_ = self.center_ + self.scale_ * self.s_
                self.n_samples_ += 1
                return self
            if ws is None or A_k.shape != ws[0] or self.s_ is not self._ws_s:
                ws = self._make_workspace(A_k.shape)
        s = self.s_
        _, D, Dm, Dd, W, XtT, Z, wb, vt, v, Xth, tmp, S, S2, c, one, hi, lo = ws
        if self.scale_ is not S or self.center_ is not c:
            ws = self._make_workspace(A_k.shape)
            _, D, Dm, Dd, W, XtT, Z, wb, vt, v, Xth, tmp, S, S2, c, one, hi, lo = ws
        A_k.dot(Dm, out=W)  # A S^2 D, (2, p)
        A_k.dot(XtT, out=Z)  # [M | A theta], M = A S D S A^T, (2, 3)
        (q00, q01, at0), (_, q11, at1) = Z.tolist()
        y0, y1 = y_k.tolist()
        inv_c = self.beta / self.dt
        det = max(q00 * q11 - q01 * q01, 0.0) + (q00 + q11) * inv_c + inv_c * inv_c
        e0 = y0 - at0
        e1 = y1 - at1
        wb[0] = ((q11 + inv_c) * e0 - q01 * e1) / det
        wb[1] = ((q00 + inv_c) * e1 - q01 * e0) / det
        wb.dot(A_k, out=vt)  # A^T w
        _multiply(vt, S, out=v)  # v = S A^T w; ds = D v
        nv = v.dot(v)
        if nv < _VSAFE2:  # max |v| < TAU / 2: no fraction-to-boundary cut (_sample_step)
            _multiply(D, v, out=tmp)
            s = s + tmp
            # Here every s_i lies in [-1, 1] (|ds_i| < 0.9 (1 - |s_i|) up to round-off), so the
            # clip to +-_SMAX changes only entries equal to +-1. b bounds max |s_i| rigorously
            # (|ds_i| <= |v|_2, with slack for round-off); the exact max is taken only when
            # b reaches 1.
            b = (self._ws_b + _sqrt(nv)) * (1.0 + 1e-12)
            if b >= 1.0:
                sl = s.tolist()
                b = max(max(sl), -min(sl))
                if b >= 1.0:
                    _minimum(s, hi, out=s)
                    _maximum(s, lo, out=s)
                    b = _SMAX
            self._ws_b = b
        else:
            s = _boundary_step(s, D * v)
            self._ws_b = 1.0  # unknown: the next fast step takes the exact max
        self.s_ = self._ws_s = s
        _multiply(S, s, out=tmp)
        _add(c, tmp, out=Xth)
        self.theta_ = Xth.copy()
        _multiply(s, s, out=tmp)
        _subtract(one, tmp, out=D)  # D = 1 - s^2
        _multiply(S2, D, out=Dd)  # diagonal of Dm
        self.n_samples_ += 1
        return self

    def _update_euler(self, A_k, y_k):
        """One explicit Euler step in s (module doc); no boundary rule, divergence recorded."""
        S, s = self.scale_, self.s_
        with np.errstate(over="ignore", invalid="ignore"):
            e = y_k - A_k @ (self.center_ + S * s)
            s = s + (self.dt / self.beta) * (1.0 - s * s) * (S * (A_k.T @ e))
        self.s_ = s
        self.theta_ = self.center_ + S * s
        self.n_samples_ += 1
        if not self.diverged_ and not np.max(np.abs(s)) < self.blowup:
            self.diverged_, self.diverged_at_ = True, self.n_samples_
        return self

    def _make_workspace(self, shape_A):
        """Work arrays of the n_out = 2 fast path for the current ``s_``, ``scale_``, ``center_``.

        Holds D = 1 - s^2 (p,), Dm = diag(S^2 D) (p, p) with a writable view of its diagonal,
        and Xt (3, p) whose rows 0-1 receive A Dm and row 2 theta, so that one product
        A Xt^T gives M = A S D S A^T and A theta.
        """
        p = shape_A[1]
        S = self.scale_
        c = self.center_
        s = np.array(self.s_, dtype=float)
        self.s_ = self._ws_s = s
        self._ws_b = float(np.max(np.abs(s)))
        D = 1.0 - s * s
        Dm = np.zeros((p, p))
        Dd = np.lib.stride_tricks.as_strided(Dm, shape=(p,), strides=((p + 1) * Dm.itemsize,))
        S2 = S * S
        Dd[:] = S2 * D
        Xt = np.empty((3, p))
        Xt[2] = c + S * s
        self.theta_ = Xt[2].copy()
        ws = (shape_A, D, Dm, Dd, Xt[:2], Xt.T, np.empty((2, 3)), np.empty(2), np.empty(p))
        ws += (np.empty(p), Xt[2], np.empty(p), S, S2, c, np.ones(p))
        ws += (np.full(p, _SMAX), np.full(p, -_SMAX))
        self._ws = ws
        return ws

    # -- offline -------------------------------------------------------------------------
    def fit(self, A, y):
        """Run from the nominal estimate over the whole log (see ``fit_block``)."""
        A3, y2 = as_blocks(A, y)
        self.reset()
        N = A3.shape[0]
        k = max(self.history_every, 1)
        if self.integrator == "euler":
            p_ = self.s_.size
            S, c, s = self.scale_, self.center_, self.s_
            g = self.dt / self.beta
            SAT = A3.transpose(0, 2, 1) * S[:, None]  # S A_k^T (N, p, n)
            e0 = y2 - A3 @ c  # y_k - A_k c (N, n)
            B = A3 * S  # A_k S (N, n, p)
            lib = native_loops.kernel()
            if lib is not None:  # _run_euler's loop, in C
                s, hist, n_done = native_loops.gradient_samples(
                    lib, B, e0, SAT, s, k, 64, self.blowup, hop_gain=g
                )
            else:
                s, hist, n_done = _run_euler(s, B, e0, SAT, g, k, self.blowup)
            self.s_, self.theta_, self.n_samples_ = s, c + S * s, n_done
            if not np.max(np.abs(s)) < self.blowup:
                self.diverged_, self.diverged_at_ = True, n_done
            self.history_ = (
                self.center_ + self.scale_ * np.array(hist) if len(hist) else np.empty((0, p_))
            )
            self.history_samples_ = checkpoints(self.n_samples_, k)
            return self
        lib = native_loops.kernel() if self.lam is None and A3.shape[1] == 2 else None
        if lib is not None and self.fit_block <= 1:  # the fast path below, in C
            s, hist = native_loops.hopfield_samples(
                lib, A3, y2, self.scale_, self.center_, self.s_, self.beta / self.dt, _SMAX, k
            )
            self._ws, counts = None, checkpoints(N, k)
        elif self.lam is not None or (self.fit_block <= 1 and A3.shape[1] == 2):
            # windowed weights, or the online fast path: sample by sample
            hist = []
            for i in range(N):
                self.update(A3[i], y2[i])
                if (i + 1) % k == 0:
                    hist.append(self.s_)
            s, hist, counts = self.s_, np.array(hist), checkpoints(N, k)
        else:
            B = A3 * self.scale_
            c = y2 - A3 @ self.center_
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

    def settle(self, A, y, tol: float = 1e-12, max_steps: int = 500):
        """Let the network settle with the whole log's weights; return ``self``.

        The Hopfield optimisation methodology with time-invariant weights: the ODE above
        with A^T A and A^T y replaced by their means over the log, G = mean(A^T A) and
        b = mean(A^T y), integrated from the current state with the same linearly implicit
        step (step length h with h/beta * max eig(S G S) = 1e9, so each step is nearly the
        full Newton step of the batch cost even along its weakest direction). The network's
        Lyapunov function is then the log's squared prediction error, so its equilibrium is
        the least-squares estimate inside the box (the box-constrained optimum when LS lies
        outside). Stops when the largest change of s falls below ``tol`` or after
        ``max_steps``; ``settle_steps_`` records how many steps it took. The online pass
        (``fit``/``update``) is unchanged; this gives its offline end point without the
        fluctuation a fixed beta leaves.
        """
        A3, y2 = as_blocks(A, y)
        N = A3.shape[0]
        G = np.einsum("nip,niq->pq", A3, A3) / N
        b = np.einsum("nip,ni->p", A3, y2) / N
        S = self.scale_
        SGS = G * np.outer(S, S)
        lam = float(np.linalg.eigvalsh(SGS)[-1])
        if lam <= 0:
            return self
        gain = 1e9 / lam  # h / beta
        s = np.array(self.s_, dtype=float)
        self.settle_steps_ = 0
        while self.settle_steps_ < max_steps:
            self.settle_steps_ += 1
            theta = self.center_ + S * s
            rhs = gain * S * (b - G @ theta)
            M = gain * SGS + np.diag(1.0 / (1.0 - s * s))
            ds = np.linalg.solve(M, rhs)
            s = _boundary_step(s, ds)
            if float(np.max(np.abs(ds))) < tol:
                break
        self.s_ = s
        self.theta_ = self.center_ + S * s
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


def _run_euler(s, B, e0, SAT, g: float, every: int, blowup: float):
    """Explicit Euler steps s += g (1 - s^2) S A_k^T (e0_k - B_k s) from s, B = A S (N, n, p),
    e0 = y - A c (N, n), SAT = S A^T (N, p, n), g = dt / beta; stops at a check (every 64
    samples) where max |s| is not below ``blowup``: (s, s after every ``every``-th sample
    done, samples done)."""
    hist = []
    with np.errstate(over="ignore", invalid="ignore"):
        for i in range(B.shape[0]):
            s = s + g * (1.0 - s * s) * (SAT[i] @ (e0[i] - B[i] @ s))
            if (i + 1) % every == 0:
                hist.append(s)
            if (i + 1) % 64 == 0 and not np.max(np.abs(s)) < blowup:
                return s, hist, i + 1
    return s, hist, B.shape[0]


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
