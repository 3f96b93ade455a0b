"""The estimators' recursion of a replay (:func:`guardid.online.replay.replay`), a block of
used rows at a time.

Each method (RLS, the windowed Hopfield network) runs on its own: the tracker's methods
share only the rows. While its change detector is armed (neither learning a reference nor
settling after a change) and the method takes rows, a block of up to :data:`BLOCK` rows goes
through a fast path, else rows go one by one through the estimator and detector objects
exactly as :meth:`OnlineIdentifier._use_row` feeds them (the first holdoff and reference
seconds, and the seconds after a detected change).

The fast path, per block (joint equations of absent joints as zero rows, which add nothing):

- the information W_k = lam W_{k-1} + A_k^T A_k + (1 - lam) F of both estimators (RLS's
  R = P^-1, the Hopfield network's weights) for all rows at once (one ``lfilter``);
- RLS: the gains K_k = (lam R_{k-1} + A_k^T A_k)^-1 A_k^T by one batched solve, then
  theta_k = (I - K_k A_k) theta_{k-1} + K_k y_k row by row (one small product a row): the
  covariance-form update of :class:`guardid.estimators.RLS` with its floor, in
  information form;
- Hopfield: g S W_k S, its diagonal and the data part of the biases for all rows; per row
  only the state-dependent diagonal 1 / (1 - s^2), one Cholesky solve and the
  fraction-to-boundary rule (skipped, with the same result, when a bound on |ds| shows the
  step stays inside it);
- the a-priori residuals of all rows at once, then the two-sided CUSUM per joint: rows at
  which a zero CUSUM stays zero (z - kappa <= 0) are skipped in bulk, the others stepped
  with the detector's own arithmetic. At the first alarm the block is cut there: the state
  after that row goes back into the estimator object, the detector fires, and the tracker's
  restart (discard, replay of the last seconds) runs as live.

The estimates agree with the row-by-row ones to round-off (tests/test_online_replay.py).
"""

from __future__ import annotations

from math import sqrt

import numpy as np
from scipy.linalg.lapack import dposv
from scipy.signal import lfilter

from guardid.estimators import RLS, Hopfield
from guardid.estimators.hopfield import _TAU, _boundary_step

BLOCK = 2048
"""Used rows per fast block (memory: about 4 kB per row)."""


class Rows:
    """The used rows' equations: t (M,) [s] and ``ok`` (M, n) for all, A (M, n, b) and
    y (M, n) [N m] (zero rows for absent joints) for the current and previous chunk."""

    def __init__(self, t, ok):
        self.t, self.ok = t, ok
        self._chunks = []

    def set_chunk(self, c0, A, y):
        self._chunks = [*self._chunks[-1:], (c0, A, y)]
        self.c0, self.A, self.y = c0, A, y

    def row(self, i):
        """(A (m, b), y (m,)) of row ``i`` as the live tracker forms them (present joints)."""
        for c0, A, y in reversed(self._chunks):
            if i >= c0:
                ok = self.ok[i]
                if ok.all():
                    return A[i - c0], y[i - c0]
                return np.ascontiguousarray(A[i - c0][ok]), np.ascontiguousarray(y[i - c0][ok])
        raise IndexError(i)

    def buffer(self, i, span_s):
        """The tracker's row buffer at row ``i``: (t, A, y) of rows <= i within ``span_s``."""
        t = self.t
        j0 = int(np.searchsorted(t[: i + 1], t[i] - span_s, side="left"))
        return [(float(t[j]), *self.row(j)) for j in range(j0, i + 1)]


class MethodReplay:
    """One method's estimator and detector over the rows (module docstring)."""

    def __init__(self, tk, method, order):
        self.tk, self.m, self.order = tk, method, order
        self.est = tk.estimators[method]
        self.det = tk.detectors.get(method)
        est = self.est
        if isinstance(est, RLS):
            self.kind = "rls"
        elif isinstance(est, Hopfield) and est.lam is not None and est.integrator == "implicit":
            self.kind = "hopfield"
        else:
            self.kind = None
        self.hist = tk._hist[method] if tk.keep_history else None
        self.reports = []  # (row, method order, report)
        self.fast = None  # the fast path's state while it runs
        p = len(tk.names)
        lam = tk.lam
        floor = tk.info_floor if tk.info_floor is not None and lam < 1.0 else np.zeros(p)
        self.f = (1.0 - lam) * floor  # the information added per row by the floor (p,)

    # -- driving ----------------------------------------------------------------------------
    def run(self, rows: Rows, i0: int, i1: int) -> None:
        """Rows i0 .. i1 - 1 (within the current chunk of ``rows``)."""
        i = i0
        while i < i1:
            if self._fast_ok(float(rows.t[i])):
                if self.fast is None:
                    self._load()
                i = self._block(rows, i, min(i + BLOCK, i1))
            else:
                if self.fast is not None:
                    self._store()
                self._slow(rows, i)
                i += 1

    def finish(self) -> None:
        if self.fast is not None:
            self._store()

    def _fast_ok(self, t: float) -> bool:
        if self.kind is None or t < self.tk._hold_until[self.m]:
            return False
        det = self.det
        return det is None or (det.state == "armed" and not det._refreshing)

    def _slow(self, rows: Rows, i: int) -> None:
        """Row ``i`` as :meth:`OnlineIdentifier._use_row` gives it to this method."""
        tk, m, est, det = self.tk, self.m, self.est, self.det
        t = float(rows.t[i])
        A, y = rows.row(i)
        ok = rows.ok[i]
        theta = tk.estimate(m)
        alarm = det.update(t, ok, y - A @ theta, theta) if det is not None else None
        if t >= tk._hold_until[m]:
            est.update(A, y)
        if alarm is not None:
            self._restart(rows, i, alarm)
        self._after(rows, i, est.theta_)

    def _restart(self, rows, i, alarm):
        from collections import deque

        self.tk._rows_buf = deque(rows.buffer(i, self.tk._replay_s))
        self.tk._restart_at(self.m, self.est, alarm)

    def _after(self, rows, i, theta):
        if self.hist is not None:
            self.hist.append(theta)
        rep = self.det.settled(float(rows.t[i]), theta) if self.det is not None else None
        if rep is not None:
            self.reports.append((i, self.order, rep))

    # -- the fast path's state ----------------------------------------------------------------
    def _load(self) -> None:
        est = self.est
        p = len(self.tk.names)
        if self.kind == "rls":
            if not hasattr(est, "P_"):
                est._init_state(p)
            self.fast = {"W": np.linalg.inv(est.P_), "theta": np.array(est.theta_, float)}
        else:
            self.fast = {"W": est.W_.copy(), "b": est.b_.copy(), "s": est.s_.copy()}
        self.fast["n"] = 0

    def _store(self) -> None:
        est, st = self.est, self.fast
        if self.kind == "rls":
            P = np.linalg.inv(st["W"])
            est.P_ = 0.5 * (P + P.T)
            est.theta_ = st["theta"].copy()
        else:
            est.W_, est.b_ = st["W"].copy(), st["b"].copy()
            est.s_ = st["s"].copy()
            est.theta_ = est.center_ + est.scale_ * est.s_
        est.n_samples_ += st["n"]
        self.fast = None

    # -- a fast block -------------------------------------------------------------------------
    def _block(self, rows: Rows, i0: int, i1: int) -> int:
        """Rows i0 .. i1 - 1 on the fast path; returns the next row (after an alarm: the row
        after it)."""
        st, lam = self.fast, self.tk.lam
        c0 = rows.c0
        A = rows.A[i0 - c0 : i1 - c0]
        y = rows.y[i0 - c0 : i1 - c0]
        L, n, p = A.shape
        AT = A.transpose(0, 2, 1)
        AtA = AT @ A
        Q = AtA.reshape(L, p * p).copy()
        Q[:, :: p + 1] += self.f
        W0 = st["W"]
        Wf = lfilter([1.0], [1.0, -lam], Q, axis=0, zi=(lam * W0).reshape(1, p * p))[0]
        W = Wf.reshape(L, p, p)
        if self.kind == "rls":
            prior, post = self._rls(W, W0, AtA, A, AT, y)
        else:
            prior, post = self._hopfield(W, A, AT, y)
        t = rows.t[i0:i1]
        ok = rows.ok[i0:i1]
        alarm_row = None
        if self.det is not None:
            e = y - (A @ prior[:, :, None])[:, :, 0]
            z = e / np.asarray(self.det.sigma)[None, :]
            alarm_row = _cusum_block(self.det, t, z, ok)
        end = L if alarm_row is None else alarm_row + 1
        self._commit(W, post, end)
        if self.det is not None:
            rec = self.det._recent
            rec.extend(zip(t[:end].tolist(), list(prior[:end]), strict=True))
            oldest = float(t[end - 1]) - self.det._keep_s
            while rec[0][0] < oldest:
                rec.popleft()
        if alarm_row is None:
            if self.hist is not None:
                self.hist.extend(post)
            return i1
        if self.hist is not None:
            self.hist.extend(post[:alarm_row])
        i = i0 + alarm_row
        self._store()
        alarm = self.det._fire(float(rows.t[i]))
        self._restart(rows, i, alarm)
        self._after(rows, i, self.est.theta_)
        return i + 1

    def _commit(self, W, post, end):
        st = self.fast
        st["W"] = W[end - 1].copy()
        st["n"] += end
        if self.kind == "rls":
            st["theta"] = post[end - 1].copy()
        else:
            st["s"] = self._s[end - 1].copy()
            st["b"] = self._b(end - 1)

    def _rls(self, W, W0, AtA, A, AT, y):
        """RLS over the block: a-priori and a-posteriori estimates (L, p)."""
        st, lam = self.fast, self.tk.lam
        L, n, p = A.shape
        Wprev = np.concatenate([W0[None], W[:-1]])
        K = np.linalg.solve(lam * Wprev + AtA, AT)  # (L, p, n)
        # theta_k = (I - K_k A_k) theta_{k-1} + K_k y_k as one (p + 1)-square product a row
        T = np.zeros((L, p + 1, p + 1))
        T[:, :p, :p] = np.eye(p)[None] - K @ A
        T[:, :p, p] = (K @ y[:, :, None])[:, :, 0]
        T[:, p, p] = 1.0
        z = np.append(st["theta"], 1.0)
        out = []
        for Ti in T:
            z = Ti.dot(z)
            out.append(z)
        post = np.array(out)[:, :p]
        prior = np.concatenate([st["theta"][None], post[:-1]])
        return prior, post

    def _hopfield(self, W, A, AT, y):
        """The windowed Hopfield network over the block: a-priori and a-posteriori
        estimates (L, p); keeps the states s (L, p) and what the biases need."""
        est, st, lam = self.est, self.fast, self.tk.lam
        L, n, p = A.shape
        S, c = est.scale_, est.center_
        g = est.dt / est.beta
        f = self.f
        # biases b_k = Bd_k + f (phc_k + psi_k): the data part Bd (from the block's start
        # value), the centre's part phc_k = lam phc_{k-1} + c, and psi_k = lam psi_{k-1} +
        # S s_{k-1} (w = g S f psi is kept in the loop)
        Aty = (AT @ y[:, :, None])[:, :, 0]
        Bd = lfilter([1.0], [1.0, -lam], Aty, axis=0, zi=(lam * st["b"])[None])[0]
        phc = lfilter([1.0], [1.0, -lam], np.broadcast_to(c, (L, p)), axis=0)
        gS = g * S
        Gm = gS[None, :, None] * W * S[None, None, :]  # g S W S (L, p, p)
        Gd = Gm.reshape(L, p * p)[:, :: p + 1].copy()
        r0 = gS * (Bd + f * phc) - gS * (W @ c)
        gSfS = gS * f * S
        # per row, z = [s; w] -> H_k z + h_k = [rhs; w_k] with rhs = r0_k - Gm_k s + w_k,
        # w_k = lam w_{k-1} + g S f S s_{k-1}
        H = np.zeros((L, 2 * p, 2 * p))
        H[:, :p, :p] = -Gm
        H[:, :p, :p][:, np.arange(p), np.arange(p)] += gSfS
        H[:, p:, :p][:, np.arange(p), np.arange(p)] = gSfS
        H[:, :p, p:][:, np.arange(p), np.arange(p)] = lam
        H[:, p:, p:][:, np.arange(p), np.arange(p)] = lam
        h = np.zeros((L, 2 * p))
        h[:, :p] = r0
        Gdiag = Gm.reshape(L, p * p)[:, :: p + 1]  # written per row: Gm_k + D^-1, then factorised
        z = np.concatenate([st["s"], np.zeros(p)])
        s = z[:p]
        zs = np.empty((L, 2 * p))
        bound = float(np.abs(s).max())
        for i in range(L):
            v = H[i].dot(z)
            v += h[i]
            rhs = v[:p]
            np.add(Gd[i], 1.0 / (1.0 - s * s), out=Gdiag[i])
            _, ds, info = dposv(Gm[i].T, rhs, overwrite_a=1)
            if info != 0:  # not positive definite by round-off (as the estimator does)
                M = gS[:, None] * W[i] * S[None, :]
                M[np.arange(p), np.arange(p)] += 1.0 / (1.0 - s * s)
                ds = np.linalg.solve(M, rhs)
            step = sqrt(ds.dot(ds))
            if bound < 0.99 and step < _TAU * (1.0 - bound):
                np.add(s, ds, out=rhs)  # inside the fraction-to-boundary limit: no cut
                bound = (bound + step) * (1.0 + 1e-12)
            else:
                rhs[:] = _boundary_step(s, ds)
                bound = float(np.abs(rhs).max())
            z = v
            s = z[:p]
            zs[i] = z
        ss, ws = zs[:, :p], zs[:, p:]
        self._s, self._ws, self._Bd, self._phc, self._gS = ss, ws, Bd, phc, gS
        post = c + S * ss
        prior = np.concatenate([(c + S * st["s"])[None], post[:-1]])
        return prior, post

    def _b(self, i):
        """The Hopfield biases after block row ``i``."""
        return self._Bd[i] + self.f * self._phc[i] + self._ws[i] / self._gS


def _cusum_block(det, t, z, ok):
    """The detector's two-sided CUSUM (:meth:`ChangeDetector._cusum`) over a block: t (L,)
    [s], z (L, n) residuals in sigma, ok (L, n) present joint equations. Returns the block
    row of the first alarm (the state then as after that row) or None (as after the block)."""
    kappa, h = det.settings.kappa, det.settings.h
    n = z.shape[1]
    sides = []
    for j in range(n):
        idx = np.flatnonzero(ok[:, j])
        zj = z[idx, j]
        for side, x in ((0, zj), (1, -zj)):
            sides.append((side, j, idx, x))
    first = None
    for side, j, idx, x in sides:
        fire = _side(det, side, j, idx, x, t, kappa, h, len(t), dry=True)
        if fire is not None and (first is None or fire < first):
            first = fire
    limit = len(t) if first is None else first + 1
    for side, j, idx, x in sides:
        _side(det, side, j, idx, x, t, kappa, h, limit, dry=False)
    return first


def _side(det, side, j, idx, x, t, kappa, h, limit, dry):
    """One joint's side of the CUSUM over block rows ``idx`` < ``limit`` (values x = +-z).
    ``dry``: only find the first row over ``h`` (state untouched); else advance the state."""
    g = det._g[side][j]
    zero_t = det._zero_t[side][j]
    rise_t = det._rise_t[side][j]
    K = int(np.searchsorted(idx, limit))
    cand = np.flatnonzero((x[:K] - kappa) > 0.0).tolist()
    xl = x.tolist()
    k, ci = 0, 0
    fire = None
    while k < K:
        if g <= 0.0:  # a zero CUSUM stays zero until x - kappa > 0
            while ci < len(cand) and cand[ci] < k:
                ci += 1
            nxt = cand[ci] if ci < len(cand) else K
            if nxt > k:
                zero_t = float(t[idx[nxt - 1]])
                g = 0.0
                k = nxt
                if k >= K:
                    break
        was_zero = g <= 0.0
        v = (g + xl[k]) - kappa
        if not v > 0.0:
            v = 0.0
        g = v
        tk = float(t[idx[k]])
        if v <= 0.0:
            zero_t = tk
        elif was_zero:
            rise_t = tk
        if v > h and fire is None:
            fire = int(idx[k])
            if dry:
                return fire
        k += 1
    if not dry:
        det._g[side][j] = g
        det._zero_t[side][j] = zero_t
        det._rise_t[side][j] = rise_t
    return fire
