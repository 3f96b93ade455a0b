"""The estimators' recursion of a replay (:func:`guardid.online.replay.replay`), a block of
used rows at a time.

Each method (RLS, the windowed Hopfield network) runs on its own: the tracker's methods
share only the rows and what is formed from the rows alone (each block's information).
While its change detector is armed (neither learning a reference nor settling after a
change) and the method takes rows, a block of up to :data:`BLOCK` rows goes through a fast
path, else rows go one by one through the estimator and detector objects
exactly as :meth:`OnlineIdentifier._use_row` feeds them (the first holdoff and reference
seconds, and the seconds after a detected change).

The fast path, per block (joint equations of absent joints as zero rows, which add nothing):

- the information W_k = lam W_{k-1} + A_k^T A_k + (1 - lam) F of both estimators (RLS's
  R = P^-1, the Hopfield network's weights) for all rows at once: the data's part (one
  ``lfilter`` from zero) once per block for every method on the fast path over it, the
  start's part lam^(k+1) W_0 per method (the methods advance block by block together);
- RLS: the gains K_k = (lam R_{k-1} + A_k^T A_k)^-1 A_k^T by one batched solve, then
  theta_k = (I - K_k A_k) theta_{k-1} + K_k y_k by running products of 32 rows at a time
  for all such runs at once (:func:`_product_scan`): the covariance-form update of
  :class:`guardid.estimators.RLS` with its floor, in information form (to round-off);
- Hopfield: :data:`HOPFIELD_ROWS_PER_STEP` rows (16) a step, like the offline network's
  ``fit_block``: per step D = diag(1 - s^2) and the weights' part of the system are held
  (M = D^-1 + g S mean(W) S), each row keeping its own force at the step's start
  g S (b_j - W_j theta_0), so the rows' linearly implicit steps, with the biases' share of
  the state (psi below), are one affine recursion z_j = H z_(j-1) + x_j in z = [s; psi]:
  one Cholesky solve and log2(16) products a step (:func:`_affine_scan_rows`); the
  fraction-to-boundary rule is applied to the step. With 1 row a step this is the live
  network's step (to round-off: the reference in tests/test_online_replay.py); with 16 the
  estimates stay within 2 % of each parameter's scale (largest |estimate|) of the live ones
  (0.3 % and 0.9 % measured on the tests' payload logs) and the change reports come at the
  same rows, their values within 0.5 % (the printed digits may differ in the last one);
- the a-priori residuals of all rows at once, then the two-sided CUSUM per joint: rows at
  which a zero CUSUM stays zero (z - kappa <= 0) are skipped in bulk, the others stepped
  with the detector's own arithmetic. At the first alarm the block is cut there: the state
  after that row goes back into the estimator object, the detector fires, and the tracker's
  restart (discard, replay of the last seconds) runs as live.

RLS's estimates agree with the row-by-row ones to round-off, the Hopfield network's to the
tolerance above (tests/test_online_replay.py).

Where a C compiler is found, a fast block's RLS and Hopfield recursions and its CUSUM run in
C instead (:mod:`guardid.online.replay_native`, built once into guardid's cache): the same
arithmetic row after row, without the (block, p, p) arrays, about 3x less CPU for the
replay; its estimates are the numpy path's to round-off and its change reports the same
(tests/test_replay_native.py, tests/test_online_replay.py). A block whose system is not
positive definite by round-off, and every block without a compiler, takes the numpy path.
"""

from __future__ import annotations

from math import sqrt

import numpy as np
from scipy.linalg.lapack import dposv
from scipy.signal import lfilter

from guardid.estimators import RLS, Hopfield
from guardid.estimators.hopfield import _SMAX, _TAU
from guardid.online import replay_native

BLOCK = 2048
"""Used rows per fast block (memory: about 4 kB per row)."""
NATIVE_BLOCKS = 4
"""Blocks of :data:`BLOCK` rows taken at once with the C kernel (memory: its per-row
arrays, under 0.5 kB a row; fewer calls). A multiple of the Hopfield step's rows, as
:data:`BLOCK` is: the steps fall on the same rows either way."""

HOPFIELD_ROWS_PER_STEP = 16
"""Rows merged into one step of the Hopfield network on the fast path (1: a step a row, as
the live tracker; the offline network's ``fit_block``)."""


class Rows:
    """The used rows' equations: t (M,) [s] and ``ok`` (M, n) for all, A (M, n, b) and
    y (M, n) [N m] (zero rows for absent joints) for the current and previous chunk."""

    def __init__(self, t, ok):
        self.t, self.ok = t, ok
        self._chunks = []
        self._info = {}

    def set_chunk(self, c0, A, y):
        self._chunks = [*self._chunks[-1:], (c0, A, y)]
        self.c0, self.A, self.y = c0, A, y
        self._info = {}

    def information(self, i0, i1, lam, f):
        """(A^T A (L, p, p), the information the rows i0 .. i1 - 1 add from zero
        sum_(i<=k) lam^(k-i) (A_i^T A_i + F') (L, p, p), lam^(k+1) (L,)) with F' = diag(f):
        what every method's information over the block is made of (W_k = that + lam^(k+1)
        W_0), formed once for all the methods on the fast path over the same block."""
        key = (i0, i1, lam, f.tobytes())
        if key not in self._info:
            A = self.A[i0 - self.c0 : i1 - self.c0]
            L, _, p = A.shape
            AtA = A.transpose(0, 2, 1) @ A
            Q = AtA.reshape(L, p * p).copy()
            Q[:, :: p + 1] += f
            data = lfilter([1.0], [1.0, -lam], Q, axis=0)
            powers = lam ** np.arange(1, L + 1, dtype=float)
            self._info = {key: (AtA, data.reshape(L, p, p), powers)}
        return self._info[key]

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
        self.rows_per_step = HOPFIELD_ROWS_PER_STEP
        p = len(tk.names)
        lam = tk.lam
        floor = tk.info_floor if tk.info_floor is not None and lam < 1.0 else np.zeros(p)
        self.f = (1.0 - lam) * floor  # the information added per row by the floor (p,)

    # -- driving ----------------------------------------------------------------------------
    def advance(self, rows: Rows, i: int, i1: int) -> int:
        """Row ``i`` on the slow path or a fast block from it (up to :data:`BLOCK` rows, or
        :data:`NATIVE_BLOCKS` times that with the C kernel, not past ``i1``); returns the
        next row."""
        if self._fast_ok(float(rows.t[i])):
            if self.fast is None:
                self._load()
            span = BLOCK * (NATIVE_BLOCKS if replay_native.kernel() is not None else 1)
            return self._block(rows, i, min(i + span, i1))
        if self.fast is not None:
            self._store()
        self._slow(rows, i)
        return i + 1

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
        c0 = rows.c0
        A = rows.A[i0 - c0 : i1 - c0]
        y = rows.y[i0 - c0 : i1 - c0]
        L = len(A)
        lib = replay_native.kernel()
        done = self._native(lib, A, y) if lib is not None else None
        if done is None:
            done = self._numpy(rows, i0, i1, A, y)
        prior, post, e, commit = done
        t = rows.t[i0:i1]
        ok = rows.ok[i0:i1]
        alarm_row = None
        if self.det is not None:
            z = e / np.asarray(self.det.sigma)[None, :]
            if lib is not None:
                alarm_row = replay_native.cusum_rows(lib, self.det, t, z, ok)
            else:
                alarm_row = _cusum_block(self.det, t, z, ok)
        end = L if alarm_row is None else alarm_row + 1
        commit(end)
        self.fast["n"] += end
        if self.det is not None:
            rec = self.det._recent
            oldest = float(t[end - 1]) - self.det._keep_s
            j0 = int(np.searchsorted(t[:end], oldest, side="left"))  # older rows: dropped
            if j0 > 0:
                rec.clear()
            rec.extend(zip(t[j0:end].tolist(), list(prior[j0:end]), strict=True))
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

    def _numpy(self, rows, i0, i1, A, y):
        """The block by numpy: (a-priori estimates (L, p), a-posteriori ones (L, p), a-priori
        residuals (L, n), commit(end): the fast state as after block row end - 1)."""
        st, lam = self.fast, self.tk.lam
        AT = A.transpose(0, 2, 1)
        AtA, data, powers = rows.information(i0, i1, lam, self.f)
        W0 = st["W"]
        W = data + powers[:, None, None] * W0
        if self.kind == "rls":
            prior, post = self._rls(W, W0, AtA, A, AT, y)
        else:
            prior, post = self._hopfield(W, A, AT, y)
        e = y - (A @ prior[:, :, None])[:, :, 0]

        def commit(end):
            st["W"] = W[end - 1].copy()
            if self.kind == "rls":
                st["theta"] = post[end - 1].copy()
            else:
                st["s"] = self._s[end - 1].copy()
                st["b"] = self._b(end - 1)

        return prior, post, e, commit

    def _native(self, lib, A, y):
        """The block by the C kernel (:mod:`guardid.online.replay_native`), as
        :meth:`_numpy`; None when a system is not positive definite by round-off (the numpy
        path takes the block)."""
        st, lam, f = self.fast, self.tk.lam, self.f
        W0 = st["W"]
        W = W0.copy()
        if self.kind == "rls":
            theta0 = st["theta"]
            theta = theta0.copy()
            out = replay_native.rls_rows(lib, A, y, lam, f, W, theta)
            if out is None:
                return None
            post, e = out
            prior = np.concatenate([theta0[None], post[:-1]])
            states = None
        else:
            est = self.est
            S, c = est.scale_, est.center_
            b, s0 = st["b"].copy(), st["s"]
            s = s0.copy()
            K = max(1, int(self.rows_per_step))
            out = replay_native.hopfield_rows(
                lib, A, y, lam, f, S, c, est.dt / est.beta, K, _TAU, _SMAX, W, b, s
            )
            if out is None:
                return None
            states, e = out
            post = c + S * states
            prior = np.concatenate([(c + S * s0)[None], post[:-1]])

        def commit(end):
            if end == len(A):  # the state the kernel left
                st["W"] = W
                if states is None:
                    st["theta"] = theta
                else:
                    st["s"], st["b"] = s, b
                return
            Wend = W0.copy()  # after an alarm inside the block: the state at its row
            replay_native.information_rows(lib, A[:end], lam, f, Wend)
            st["W"] = Wend
            if states is None:
                st["theta"] = post[end - 1].copy()
                return
            st["s"] = states[end - 1].copy()
            # b_k = lam b_(k-1) + A_k^T y_k + f theta_(k-1), the live network's biases
            drive = np.einsum("kri,kr->ki", A[:end], y[:end]) + f * prior[:end]
            st["b"] = lfilter([1.0], [1.0, -lam], drive, axis=0, zi=(lam * st["b"])[None])[0][-1]

        return prior, post, e, commit

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
        post = _product_scan(T, np.append(st["theta"], 1.0))[:, :p]
        prior = np.concatenate([st["theta"][None], post[:-1]])
        return prior, post

    def _hopfield(self, W, A, AT, y):
        """The windowed Hopfield network over the block, :data:`HOPFIELD_ROWS_PER_STEP` rows
        a step (module docstring): a-priori and a-posteriori estimates (L, p); keeps what
        :meth:`_b` needs."""
        est, st, lam = self.est, self.fast, self.tk.lam
        L, n, p = A.shape
        S, c = est.scale_, est.center_
        g = est.dt / est.beta
        f = self.f
        K = max(1, int(self.rows_per_step))
        # biases b_k = Bd_k + f (phc_k + psi_k): the data part Bd (from the block's start
        # value), the centre's part phc_k = lam phc_{k-1} + c and the state's part psi_k =
        # lam psi_{k-1} + S s_{k-1}
        Aty = (AT @ y[:, :, None])[:, :, 0]
        Bd = lfilter([1.0], [1.0, -lam], Aty, axis=0, zi=(lam * st["b"])[None])[0]
        phc = lfilter([1.0], [1.0, -lam], np.broadcast_to(c, (L, p)), axis=0)
        starts = np.arange(0, L, K)
        counts = np.diff(np.append(starts, L))
        gS = g * S
        GW = gS[None, :, None] * W * S[None, None, :]  # g S W_j S per row
        Gs = np.add.reduceat(GW, starts, axis=0)
        Gs /= counts[:, None, None]  # g S mean(W) S per step
        # each row's own force at the step's start, g S (b_j - W_j theta_0), and the mean
        # weights' response to the state's change since: r_j = g S (b_j - W_j c)
        # + (g S mean(W) S - g S W_j S) s_0
        dev = np.repeat(Gs, counts, axis=0)
        dev -= GW
        del GW
        r = gS * (Bd + f * phc - W @ c)  # the biases' known part (L, p)
        gSf = gS * f
        gSfS, lam_gSf = gSf * S, lam * gSf
        eye = np.eye(p)
        # per row j of a step, z = [s; psi]: psi_j = lam psi_(j-1) + S s_(j-1) and
        # M s_j = D^-1 s_(j-1) + r_j + g S f psi_j (the linearly implicit step), so
        # z_j = H z_(j-1) + [M^-1 r_j; 0] with the H below
        H = np.zeros((2 * p, 2 * p))
        H[p:, :p] = np.diag(S)
        H[p:, p:] = lam * eye
        z = np.concatenate([st["s"], np.zeros(p)])
        post = np.empty((L, 2 * p))  # z after each row
        U = np.zeros((K + 1, 2 * p))  # the affine scan's [z_0; x_1 .. x_cnt], rows
        bound = float(np.abs(z[:p]).max())
        k0 = 0
        for m, cnt in enumerate(counts.tolist()):
            s = z[:p]
            M = Gs[m]
            Bt = np.empty((cnt + p, p))  # [r_j ..; I] as rows: B = Bt.T, Fortran order
            np.matmul(dev[k0 : k0 + cnt], s, out=Bt[:cnt])
            Bt[:cnt] += r[k0 : k0 + cnt]
            Bt[cnt:] = eye
            Dinv = 1.0 / (1.0 - s * s)
            M.reshape(-1)[:: p + 1] += Dinv
            _, B, info = dposv(M, Bt.T, overwrite_a=1, overwrite_b=1)
            if info != 0:  # not positive definite by round-off (as the estimator does)
                M = Gs[m].copy()  # D^-1 already added
                B = np.linalg.solve(M, np.concatenate([Bt[:cnt].T, eye], axis=1))
            Minv = B[:, cnt:]
            np.multiply(Minv, Dinv + gSfS, out=H[:p, :p])
            np.multiply(Minv, lam_gSf, out=H[:p, p:])
            part = post[k0 : k0 + cnt]
            Um = U[: cnt + 1]
            Um[0] = z
            Um[1:, :p] = B[:, :cnt].T
            Um[1:, p:] = 0.0
            part[:] = _affine_scan_rows(H, Um)
            ds = part[-1, :p] - s
            step = sqrt(ds.dot(ds))
            if bound < 0.99 and step < _TAU * (1.0 - bound):
                bound = (bound + step) * (1.0 + 1e-12)  # inside the fraction-to-boundary limit
            else:  # the step cut short: the rows' states scaled alike, psi after them
                room = 1.0 - s * np.sign(ds)
                frac = float((np.abs(ds) / room).max())
                states = part[:, :p]
                if frac > _TAU:
                    states -= s
                    states *= _TAU / frac
                    states += s
                np.clip(states, -_SMAX, _SMAX, out=states)
                psi = z[p:]
                prev = s
                for j in range(cnt):
                    psi = lam * psi + S * prev
                    part[j, p:] = psi
                    prev = states[j]
                bound = float(np.abs(states[-1]).max())
            z = part[-1].copy()
            k0 += cnt
        self._s, self._Bd, self._phc, self._psi = post[:, :p], Bd, phc, post[:, p:]
        theta = c + S * post[:, :p]
        prior = np.concatenate([(c + S * st["s"])[None], theta[:-1]])
        return prior, theta

    def _b(self, i):
        """The Hopfield biases after block row ``i``."""
        return self._Bd[i] + self.f * (self._phc[i] + self._psi[i])


def run_together(methods, rows: Rows, i0: int, i1: int) -> None:
    """Rows i0 .. i1 - 1 through every method, the one furthest behind advanced first
    (:meth:`MethodReplay.advance`): each method takes the same blocks as on its own, and
    methods on the fast path over the same block share its information
    (:meth:`Rows.information`)."""
    at = [i0] * len(methods)
    while True:
        k = min(range(len(methods)), key=at.__getitem__)
        if at[k] >= i1:
            return
        at[k] = methods[k].advance(rows, at[k], i1)


def _affine_scan_rows(R, U):
    """(m, q): the states x_j = R x_(j-1) + u_j, j = 1 .. m, from U (m + 1, q) = [x_0; u_1;
    .. u_m] as rows (U is overwritten), by recursive doubling (log2(m + 1) products instead
    of m)."""
    m = len(U) - 1
    PT = R.T
    shift = 1
    while shift <= m:
        U[shift:] += U[: m + 1 - shift] @ PT
        shift *= 2
        if shift <= m:
            PT = PT @ PT
    return U[1:]


SCAN_ROWS = 32
"""Rows whose products :func:`_product_scan` forms in one batched step."""


def _product_scan(T, z0):
    """(L, q): z_k = T_k z_(k-1) from z0 (q,) for T (L, q, q): the running products of
    :data:`SCAN_ROWS` rows at a time for all such runs at once, then one product a run."""
    L, q, _ = T.shape
    m = min(SCAN_ROWS, L)
    nb = -(-L // m)
    Tp = np.empty((nb * m, q, q))
    Tp[:L] = T
    Tp[L:] = np.eye(q)
    Tp = Tp.reshape(nb, m, q, q)
    C = np.empty_like(Tp)
    C[:, 0] = Tp[:, 0]
    for j in range(1, m):
        np.matmul(Tp[:, j], C[:, j - 1], out=C[:, j])
    out = np.empty((nb, m, q))
    z = z0
    for b in range(nb):
        np.matmul(C[b], z, out=out[b])
        z = out[b, -1]
    return out.reshape(nb * m, q)[:L]


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
