"""Ordinary (LS) and weighted (WLS, Gautier's IDIM-WLS) least squares.

Batch solve by Householder QR of the stacked regressor (never the normal equations).
``update`` keeps the square-root information form: the triangular factor R and z = Q^T y are
updated by a QR of [R; A_k] (p + n_out rows), so the online path is as well conditioned as
the batch one and costs O(p^3) per sample.

Errors in the regressor (``column_noise=``, :class:`ColumnNoise` of the rows to be fitted): when the
columns carry a measurement noise dA of known second moments (e.g. an encoder's rounding
differentiated into them), least squares is biased by E[dA^T dA] theta, a bias that does
not shrink with the rows. Bias-compensated least squares removes the expected Gram from the
normal equations: theta = (A^T W^2 A - sum_j w_j^2 S_j)^-1 (A^T W^2 y - sum_j w_j^2 c_j)
(S_j = E[dA_j^T dA_j], c_j = E[dA_j^T dy_j] over output j's rows; Stoica & Soderstrom's
bias-eliminating least squares with the noise moments given).

Errors that repeat (``row_groups=``, (M,) labels, one per sample): rows that share a label
share part of their error, e.g. the rows at the same phase of a periodic excitation, where
an error that follows the motion (an encoder's rounding through the closed loop) comes back
every period and no longer averages out over the log. Per output j, the weighted
residuals are split as in a one-way random-effects ANOVA into a white part and a part
common to a group, of variance tau_j^2: the between- and within-group sums of squares are
matched to their expectations with the fit's own projection taken into account (Henderson's
method III; with a constant column alone it is the classical (MSB - MSW) / n0), since the
fit takes up part of a common error that repeats with the regressor, more so with few
groups and many columns; clipped at 0. The covariance then adds
H^-1 [sum_j tau_j^2 (sum_g s_gj s_gj^T - A_j^T W^2 A_j)] H^-1, s_gj the sum of output j's
weighted rows in group g (the rows of one group counted together instead of apart). With no
common part (tau_j^2 = 0, or one row per group) it adds nothing.

Errors shared by neighbouring samples (``row_ticks=``, (N,) each sample's tick, and
``lag_ticks=`` L > 0): rows taken from a low-passed signal closer than its impulse response
share their noise, which the white-residual covariance does not count. Per output j the
residuals' autocovariance gamma_j(d) at each distance d = 0..L ticks is pooled over the
run (the products of the rows exactly d ticks apart, over their number), and the covariance
is H^-1 S H^-1 N / (N - p k), S = sum_j sum over the pairs of output j's rows at most L
ticks apart (both orders, each row with itself) of gamma_j(d) w_j^2 a_tj a_t'j^T, clipped to
a positive semi-definite matrix; N the samples that are not all zero and k the mean over
them of their pairs' Bartlett weights 1 - d / (L + 1) (L + 1 without cuts). Pooled, not
Newey and West's local products r_t r_t' a_t a_t'^T: where the regressor's information sits
in a few stretches (the gravity columns on a multisine), the fit takes up the error there
and the local products miss it (the std of the tilt's first moments 1.3-1.6x too small on
a Schroeder multisine; pooled: in the band). The factor gives back what the fit takes up
in every window (about p k / N of S with a smooth regressor, not p / N; measured to work,
not derived): with Newey and West's meat on white current noise through a 60 s log the std
came out 1.12-1.32x too small without it, 0.97-1.14 with it; with the pooled meat on a
600-sample synthetic run, up to 1.98x without, 1.42x with. The outputs' errors are taken
as independent of each other (separate joints' current sensors). The groups' common part
(``row_groups``) is added as above, as independent from one group to the next.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.linalg import get_lapack_funcs, qr, solve_triangular
from scipy.signal import lfilter

from ._base import Estimator, as_blocks, as_sample


@dataclass(frozen=True)
class ColumnNoise:
    """Expected second moments of the regressor's measurement noise over the fitted rows:
    ``gram`` (n_out, p, p) S_j = E[dA_j^T dA_j] and ``cross`` (n_out, p) c_j = E[dA_j^T dy_j]
    (the noise's part in y correlated with it), summed over output j's rows, in the units of
    A^T A and A^T y. ``what`` says where it comes from (for the notes)."""

    gram: np.ndarray
    cross: np.ndarray
    what: str = ""


def _split_rows(x: np.ndarray, shape) -> np.ndarray:
    """A view of ``x`` (M, ...) with its first axis split into ``shape``'s first two (no
    copy: writes through it land in ``x``)."""
    view = x.reshape(shape)
    if not np.shares_memory(view, x):
        raise AssertionError("a reshape that copies")  # numpy splits a strided axis in place
    return view


def _r_factor(aug: np.ndarray) -> np.ndarray:
    """R of the QR of ``aug`` (M, k), Fortran-ordered, overwritten: LAPACK's geqrf called as
    ``scipy.linalg.qr(aug, mode="r", overwrite_a=True)`` calls it, but only R's top
    min(M, k) rows copied out (scipy's triu copies all M: 12 MiB per fit of a 4 h log)."""
    if aug.size == 0:
        return qr(aug, mode="r", check_finite=False)[0]
    (geqrf,) = get_lapack_funcs(("geqrf",), (aug,))
    lwork = geqrf(aug, lwork=-1, overwrite_a=True)[-2][0].real.astype(np.int_)
    factored, _, _, info = geqrf(aug, lwork=lwork, overwrite_a=True)
    if info < 0:
        raise ValueError(f"illegal value in {-info}th argument of internal geqrf")
    return np.triu(factored[: min(aug.shape)])


class LeastSquares(Estimator):
    """Ordinary least squares with parameter statistics.

    Attributes after ``fit``: ``theta_`` (p,); ``std_`` (p,) standard deviations from
    sigma^2 (A^T A)^-1 with sigma^2 = ||r||^2 / (M - p) (same unit as theta); ``rel_std_``
    (p,) 100 std / |theta| in %; ``cov_`` (p, p); ``cond_`` condition number of the
    (weighted) stacked A; ``residual_rms_`` rms of the residual over all rows (unit of y);
    ``residual_rms_per_output_`` (n_out,); ``n_rows_`` M; ``n_samples_`` N;
    ``compensated_``: the ``column_noise`` (:class:`ColumnNoise` of the rows ``fit`` is given,
    or None) was removed (module docstring;
    False when none was given or when removing it would leave the normal matrix
    indefinite: then the plain estimate), and then ``cov_`` is the sandwich
    sigma^2 H^-1 A^T W^2 A H^-1 with H the compensated normal matrix.
    With ``row_groups`` ((N,) labels of the samples ``fit`` is given; module docstring),
    ``cov_`` also holds the groups' common error and ``repeating_std_per_output_`` (n_out,)
    is that common part's std per output (tau_j / w_j, unit of y; 0 where there is none),
    ``repeating_share_`` (p,) the share of each parameter's variance that common part makes,
    tau_j^2 H^-1 sum_g s_gj s_gj^T H^-1 over the covariance [0-1]: the part that more
    periods of the same excitation do not reduce (twice the run leaves the variance at
    (1 - s) / 2 + s of itself).
    With ``row_ticks`` and ``lag_ticks`` > 0 (module docstring), ``cov_`` counts the errors
    of samples at most ``lag_ticks`` ticks apart as correlated, by each output's residual
    autocovariance.
    ``update`` ignores the groups and the ticks, and drops ``repeating_std_per_output_`` and
    ``repeating_share_`` (they describe the grouped fit's rows only; ``cov_`` after an
    update is the white-residual one).
    """

    def __init__(self, column_noise: ColumnNoise | None = None, row_groups=None,
                 row_ticks=None, lag_ticks: int = 0):  # fmt: skip
        self.column_noise = column_noise
        self.row_groups = row_groups
        self.row_ticks = row_ticks
        self.lag_ticks = int(lag_ticks)
        self._w = None  # per-output row weights (1 for OLS)

    # -- core on the weighted stacked system -------------------------------------------
    def _solve_augmented(self, aug: np.ndarray) -> None:
        """QR of the weighted augmented [A y] (M, p + 1), Fortran-ordered (overwritten):
        R_aug = [[R, z], [0, rho]], ||r|| = |rho|."""
        p = aug.shape[1] - 1
        # an all-zero row (a joint whose equation is cut there) carries no information and
        # is no degree of freedom
        self.n_rows_ = int(np.count_nonzero(np.any(aug != 0, axis=1)))
        Raug = _r_factor(aug)
        self.R_ = Raug[:p, :p]
        self.z_ = Raug[:p, p]
        self._finish()
        self.rss_ = float(Raug[p, p] ** 2) if Raug.shape[0] > p else 0.0
        H = self._compensate()
        self._stats(H)

    def _compensate(self):
        """With a column noise: theta from the compensated normal equations, rss_ from it
        (||z - R theta||^2 + the QR's residual); the compensated normal matrix H, else None."""
        self.compensated_ = False
        noise = self.column_noise
        if noise is None:
            return None
        w2 = np.asarray(self._w, dtype=float) ** 2
        R, z = self.R_, self.z_
        G = R.T @ R
        H = G - np.einsum("j,jab->ab", w2, np.asarray(noise.gram, dtype=float))
        h = R.T @ z - w2 @ np.asarray(noise.cross, dtype=float)
        try:
            np.linalg.cholesky(H)
        except np.linalg.LinAlgError:
            return None  # the noise would take more than the rows hold: plain estimate
        self.theta_ = np.linalg.solve(H, h)
        self.rss_ += float(np.sum((z - R @ self.theta_) ** 2))
        self.compensated_ = True
        return H

    def _finish(self) -> None:
        R = self.R_
        d = np.abs(np.diag(R))
        if d.size and d.min() > 1e-14 * max(d.max(), 1e-300):
            self.theta_ = solve_triangular(R, self.z_)
        else:
            self.theta_ = np.linalg.lstsq(R, self.z_, rcond=None)[0]

    def _stats(self, H=None) -> None:
        p = self.R_.shape[1]
        dof = self.n_rows_ - p
        self.sigma2_ = self.rss_ / dof if dof > 0 else np.nan
        sv = np.linalg.svd(self.R_, compute_uv=False)
        self.cond_ = float(sv[0] / sv[-1]) if sv[-1] > 0 else np.inf
        try:
            Rinv = solve_triangular(self.R_, np.eye(p))
        except np.linalg.LinAlgError:
            Rinv = np.full((p, p), np.nan)
        self._bread = Rinv @ Rinv.T
        self.cov_ = self.sigma2_ * self._bread
        if H is not None:  # the sandwich of the compensated estimate
            self._bread = np.linalg.inv(H)
            self.cov_ = self.sigma2_ * (self._bread @ (self.R_.T @ self.R_) @ self._bread)
            self.cov_ = 0.5 * (self.cov_ + self.cov_.T)
        self._set_std()

    def _set_std(self) -> None:
        self.std_ = np.sqrt(np.diag(self.cov_))
        with np.errstate(divide="ignore", invalid="ignore"):
            self.rel_std_ = 100.0 * self.std_ / np.abs(self.theta_)

    def _lagged(self) -> bool:
        return self.row_ticks is not None and self.lag_ticks > 0

    def _add_correlated(self, A3: np.ndarray, raw: np.ndarray) -> None:
        """``cov_`` from each output's error autocovariance over ``row_ticks`` (module
        docstring)."""
        ticks = np.rint(np.asarray(self.row_ticks, dtype=float)).astype(np.int64)
        if ticks.shape != raw.shape[:1]:
            raise ValueError(f"row_ticks has shape {ticks.shape}, the rows {raw.shape[:1]}")
        p, lag = A3.shape[2], self.lag_ticks
        meat = np.zeros((p, p))
        for j, w in enumerate(self._w):
            live = np.flatnonzero(np.any(A3[:, j, :] != 0, axis=1))  # cut: carry nothing
            if live.size:
                meat += w**4 * _lagged_meat(A3[:, j, :], raw[:, j], ticks, live, lag)
        vals, vecs = np.linalg.eigh(0.5 * (meat + meat.T))  # the autocovariances estimated
        meat = (vecs * np.clip(vals, 0.0, None)) @ vecs.T  # lag by lag: no negative variance
        live = np.any(A3 != 0, axis=(1, 2))
        n = int(np.count_nonzero(live))
        grid = _TickGrid(ticks, lag, np.flatnonzero(live))
        pairs = grid.pair_sums(np.ones(ticks.size))[1]  # (lag' + 1,) pairs at each grid distance
        bartlett = 1.0 - grid.step * np.arange(pairs.size) / (lag + 1.0)
        weight = (n + 2.0 * float(bartlett[1:] @ pairs[1:])) / max(n, 1)  # per sample
        dof = n - p * weight  # the fit takes up p directions of each window's error
        self.cov_ = (n / dof if dof > 0 else np.nan) * (self._bread @ meat @ self._bread)
        self.cov_ = 0.5 * (self.cov_ + self.cov_.T)
        self._set_std()

    def _add_repeating(self, A3: np.ndarray, raw: np.ndarray) -> None:
        """Add the error common to the rows of a group to ``cov_`` (module docstring)."""
        groups = np.asarray(self.row_groups)
        if groups.shape != raw.shape[:1]:
            raise ValueError(f"row_groups has shape {groups.shape}, the rows {raw.shape[:1]}")
        _, label = np.unique(groups, return_inverse=True)
        blocks = []
        for j, w in enumerate(self._w):
            live = np.any(A3[:, j, :] != 0, axis=1)  # a cut equation's rows carry nothing
            _, lab = np.unique(label[live], return_inverse=True)
            blocks.append((w * A3[live, j, :], w * raw[live, j], lab))
        parts = _block_parts(blocks)  # the groups' sums, once for tau and for the covariance
        tau2 = _common_variances(blocks, self._bread, parts)
        p = A3.shape[2]
        meat, common = np.zeros((p, p)), np.zeros((p, p))
        for part, t2 in zip(parts, tau2, strict=True):
            if t2 > 0.0:
                sums, xtx = part[3], part[7]
                between_rows = sums.T @ sums
                common += t2 * between_rows  # the whole common part: what a longer run keeps
                meat += t2 * (between_rows - xtx)  # beyond what sigma^2 counts
        self.repeating_std_per_output_ = np.sqrt(tau2) / np.asarray(self._w, dtype=float)
        self.repeating_share_ = np.zeros(p)
        if np.any(tau2 > 0.0):
            extra = self._bread @ meat @ self._bread
            self.cov_ = self.cov_ + 0.5 * (extra + extra.T)
            self._set_std()
            with np.errstate(divide="ignore", invalid="ignore"):
                share = np.diag(self._bread @ common @ self._bread) / np.diag(self.cov_)
            self.repeating_share_ = np.clip(np.nan_to_num(share), 0.0, 1.0)

    def fit(self, A, y):
        """Fit on A (N, n_out, p) / y (N, n_out) or stacked A (M, p) / y (M,)."""
        A3, y2 = as_blocks(A, y)
        raw = self._fit_pass(A3, y2)
        self._add_error_structure(A3, raw)
        return self

    def effect_of(self, A, d) -> np.ndarray:
        """(p, k): how ``theta_`` moves per unit of each of k changes ``d`` (N, n_out, k) of
        the y it was fitted on (on rows ``A`` (N, n_out, p), those of the fit), this fit's
        row weights and column-noise compensation held: for them theta_ is linear in y
        (WLS's weights, estimated from y, move too, which this leaves out)."""
        A3 = np.asarray(A, dtype=float)
        d3 = np.asarray(d, dtype=float)
        w2 = np.asarray(self._w if self._w is not None else np.ones(A3.shape[1])) ** 2
        return self._bread @ np.einsum("mjp,j,mjk->pk", A3, w2, d3)

    def _add_error_structure(self, A3: np.ndarray, raw: np.ndarray) -> None:
        """The final fit's ``cov_`` with the neighbours' and the groups' shared errors; a
        fit whose white covariance or residuals are not finite (a column the rows never
        excite, values near the float range) keeps that covariance (``std_`` not finite:
        what the trust checks report) instead of failing in the decompositions."""
        if not (np.all(np.isfinite(self.cov_)) and np.all(np.isfinite(raw))):
            return
        try:
            if self._lagged():
                self._add_correlated(A3, raw)
            if self.row_groups is not None:
                self._add_repeating(A3, raw)
        except np.linalg.LinAlgError:  # overflow inside: no covariance to trust
            self.cov_ = np.full_like(self.cov_, np.nan)
            self._set_std()

    def _fit_pass(self, A3: np.ndarray, y2: np.ndarray) -> np.ndarray:
        """One weighted solve on the blocks (the groups' part not added); the residuals
        y2 - A3 theta_ (N, n_out)."""
        N, n, p = A3.shape
        self.n_samples_ = N
        w = np.ones(n) if self._w is None or self._w.shape != (n,) else self._w
        self._w = w
        # the weighted rows straight into LAPACK's layout (no weighted copy: long runs)
        aug = np.empty((N * n, p + 1), order="F")
        rows = _split_rows(aug[:, :p], (N, n, p))  # row i * n + j: sample i, joint j
        np.multiply(A3, w[None, :, None], out=rows)  # (A3 need not be C-ordered: no copy)
        np.multiply(y2, w[None, :], out=_split_rows(aug[:, p], (N, n)))
        self._solve_augmented(aug)
        del aug  # overwritten by the QR
        raw = y2 - A3 @ self.theta_
        self.residual_rms_per_output_ = np.sqrt(np.mean(raw**2, axis=0))
        self.residual_rms_ = float(np.sqrt(np.mean(raw**2)))
        return raw

    def update(self, A_k, y_k):
        """Add one sample (n_out rows) by a QR update of the square-root information."""
        A_k, y_k = as_sample(A_k, y_k)
        n, p = A_k.shape
        if not hasattr(self, "R_"):
            self.R_, self.z_ = np.zeros((p, p)), np.zeros(p)
            self.rss_, self.n_rows_, self.n_samples_ = 0.0, 0, 0
        w = np.ones(n) if self._w is None or self._w.shape != (n,) else self._w
        self._w = w
        new = np.column_stack([A_k, y_k]) * w[:, None]
        stack = np.vstack([np.column_stack([self.R_, self.z_]), new])
        Rfull = np.linalg.qr(stack, mode="r")
        self.R_ = Rfull[:p, :p]
        self.z_ = Rfull[:p, p]
        # Rows below p of the last column carry the new residual energy.
        if Rfull.shape[0] > p:
            self.rss_ += float(np.sum(Rfull[p:, p] ** 2))
        self.n_rows_ += n
        self.n_samples_ += 1
        self.compensated_ = False  # a column noise covers the rows of its fit only
        for stale in ("repeating_std_per_output_", "repeating_share_"):  # the groups' fit's
            self.__dict__.pop(stale, None)
        self._finish()
        self._stats()
        # Exact for OLS; for WLS this is the rms of the weighted residual.
        self.residual_rms_ = float(np.sqrt(self.rss_ / self.n_rows_))
        return self


GRID_CHUNK = 16384
"""Grid points per chunk of :class:`_TickGrid` [-]: its arrays stay about 2 MB whatever
the log's length."""


class _TickGrid:
    """The samples ``ticks[rows]`` (distinct integers, any order; ``rows`` None: all) on the
    grid of their common step (their greatest common divisor: a row every m-th tick gives
    m), by chunks of :data:`GRID_CHUNK` points: a pair of samples d ticks apart is then two
    views of one chunk d / step points apart, whatever lies between them. ``lag`` [ticks]:
    the largest distance asked for (``self.lag`` grid points)."""

    def __init__(self, ticks, lag: int, rows=None):
        ticks = np.asarray(ticks, dtype=np.int64)
        rows = np.arange(ticks.size) if rows is None else np.asarray(rows)
        order = np.argsort(ticks[rows], kind="stable")
        self.rows = rows[order]  # the samples in tick order
        at = ticks[self.rows] - (ticks[self.rows[0]] if rows.size else 0)
        if rows.size > 1 and np.any(np.diff(at) == 0):
            raise ValueError("row_ticks: two rows at the same tick")
        self.step = max(int(np.gcd.reduce(np.diff(at))) if rows.size > 1 else 1, 1)
        self.pos = at // self.step
        self.lag = int(lag) // self.step

    def chunks(self, *columns):
        """Yield (B, [each of ``columns`` (N, ...) (all samples, indexed like ``ticks``) on
        the chunk's grid of B + lag points, zero where no sample is]) for the chunks that
        hold a sample."""
        pos, L = self.pos, self.lag
        top = int(pos[-1]) + 1 if pos.size else 0
        for a in range(0, top, GRID_CHUNK):
            lo, mid, hi = np.searchsorted(pos, [a, a + GRID_CHUNK, a + GRID_CHUNK + L])
            if mid == lo:
                continue
            B = min(GRID_CHUNK, top - a)
            out = []
            for c in columns:
                g = np.zeros((B + L, *np.shape(c)[1:]))
                g[pos[lo:hi] - a] = c[self.rows[lo:hi]]
                out.append(g)
            yield B, out

    def pair_sums(self, e):
        """(sum over pairs of e_t e_(t+d), number of pairs), each (lag + 1,) for grid
        distances d = 0..lag (d = 0: each sample with itself); ``e`` (N,) all samples."""
        L = self.lag
        sums, count = np.zeros(L + 1), np.zeros(L + 1)
        for B, (eg, on) in self.chunks(e, np.ones(len(e))):
            for d in range(L + 1):  # each sample t of the chunk with its partner t + d
                sums[d] += float(eg[:B] @ eg[d : B + d])
                count[d] += float(on[:B] @ on[d : B + d])
        return sums, count


def _lagged_meat(X, e, ticks, rows, lag: int) -> np.ndarray:
    """(p, p) sum over every pair of the samples ``rows`` at most ``lag`` ticks apart of
    gamma_d x_t x_t'^T, gamma_d the residuals' autocovariance at their distance d (pooled:
    the sum of e_t e_t' over the pairs at d / their number); ``X`` (N, p), ``e`` (N,),
    ``ticks`` (N,) distinct integers over all samples."""
    grid = _TickGrid(ticks, lag, rows)
    sums, count = grid.pair_sums(e)
    gamma = np.divide(sums, count, out=np.zeros_like(sums), where=count > 0)
    ahead = np.concatenate([[0.0], gamma[1:]])  # Z_t = sum_(d >= 1) gamma_d x_(t+d)
    p = X.shape[1]
    xx, xz = np.zeros((p, p)), np.zeros((p, p))
    for B, (Xg,) in grid.chunks(X):
        # one FIR filter run backwards over the chunk and its lag: not one product per lag
        Z = lfilter(ahead, [1.0], Xg[::-1], axis=0)[::-1][:B]
        xx += Xg[:B].T @ Xg[:B]
        xz += Xg[:B].T @ Z
    return gamma[0] * xx + xz + xz.T


def _anova_sums(e: np.ndarray, label: np.ndarray):
    """(between-group sum of squares about the mean, within-group sum of squares, rows per
    group (G,)) of ``e`` (N,) in groups ``label`` (N,) numbered 0..G-1, each occupied."""
    n = np.bincount(label).astype(float)
    sums = np.bincount(label, weights=e)
    means = sums / n
    ssb = float(n @ (means - e.mean()) ** 2) if e.size else 0.0
    return ssb, float(e @ e) - float(sums @ means), n


def _block_parts(blocks) -> list:
    """Per output of ``blocks`` (see :func:`_common_variances`): None for fewer than two
    rows, else (between-group SS, within-group SS, rows per group (G,), the groups' sums of
    rows (G, p), the rows' sum (p,), X^T Q_B X, X^T Q_W X, X^T X)."""
    parts = []
    for X, r, lab in blocks:
        if r.size < 2:
            parts.append(None)
            continue
        ssb, ssw, n = _anova_sums(r, lab)
        sums = np.zeros((n.size, X.shape[1]))
        np.add.at(sums, lab, X)
        total = X.sum(axis=0)
        xtx = X.T @ X
        between = sums.T @ (sums / n[:, None]) - np.outer(total, total) / r.size  # X^T Q_B X
        within = xtx - sums.T @ (sums / n[:, None])  # X^T Q_W X
        parts.append((ssb, ssw, n, sums, total, between, within, xtx))
    return parts


def _common_variances(blocks, bread: np.ndarray, parts=None) -> np.ndarray:
    """tau_j^2 (n_out,) of the model e_j = c_j[group] + white_j per output, from the
    between- and within-group sums of squares of the residuals (:func:`_anova_sums`),
    matched to their expectations with the fit's own projection taken into account
    (Henderson's method III, moments): the residual r_j = e_j - X_j H^-1 sum_k X_k^T e_k
    loses the parts of the common errors that the regressor can take up, which a plain
    ANOVA would miss (tau biased low with few groups). ``blocks``: per output (X_j (N_j, p)
    weighted rows, r_j (N_j,) weighted residuals, group labels (N_j,) 0..G_j-1);
    ``bread`` H^-1 (p, p). Clipped at 0; 0 for an output without two groups or without a
    group of two rows. ``parts``: :func:`_block_parts` of ``blocks`` when already made."""
    n_out = len(blocks)
    moments, rhs, used = [], [], []
    parts = _block_parts(blocks) if parts is None else parts
    for j, part in enumerate(parts):
        if part is None:
            continue
        ssb, ssw, n, sums, total, between, within, _ = part
        N, G = float(n.sum()), n.size
        row_b, row_w = np.zeros(2 * n_out), np.zeros(2 * n_out)
        # own terms: E[e^T Q e] and the cross term -2 E[e^T Q X H^-1 X^T e]
        own_tau_b = N - float(n @ n) / N
        own_tau_b -= 2.0 * np.trace(bread @ (sums.T @ (sums - np.outer(n, total) / N)))
        row_b[j] += own_tau_b
        row_b[n_out + j] += (G - 1) - 2.0 * np.trace(bread @ between)
        row_w[n_out + j] += (N - G) - 2.0 * np.trace(bread @ within)
        # the estimate's own error seen through output j's rows, from every output k
        for k, other in enumerate(parts):
            if other is None:
                continue
            k_sums, k_xtx = other[3], other[7]
            common = bread @ (k_sums.T @ k_sums) @ bread
            white = bread @ k_xtx @ bread
            row_b[k] += np.sum(between * common)
            row_b[n_out + k] += np.sum(between * white)
            row_w[k] += np.sum(within * common)
            row_w[n_out + k] += np.sum(within * white)
        moments += [row_b, row_w]
        rhs += [ssb, ssw]
        used.append(j)
    tau2 = np.zeros(n_out)
    if not moments:
        return tau2
    M, b = np.array(moments), np.array(rhs)
    keep = np.flatnonzero(np.any(M != 0, axis=0))
    sol = np.linalg.lstsq(M[:, keep], b, rcond=None)[0]
    full = np.zeros(2 * n_out)
    full[keep] = sol
    for j in used:
        n = parts[j][2]
        if n.size >= 2 and n.sum() > n.size:  # two groups, one of two rows or more
            tau2[j] = max(full[j], 0.0)
    return tau2


class WeightedLeastSquares(LeastSquares):
    """Gautier's IDIM-WLS: each output (joint) row group weighted by 1 / sigma_j.

    A first OLS pass gives per-output residual variances sigma_j^2 = ||r_j||^2 / (N_j - p_j),
    N_j output j's rows that are not all zero (a cut equation), p_j the number of parameters
    whose column is not identically zero in output j's rows.
    The weighted system (rows of output j divided by sigma_j) is then solved by QR;
    ``std_`` comes from s^2 ((W A)^T W A)^-1 with s^2 = ||W r||^2 / (M - p) (about 1 when the
    noise model holds). ``sigma_per_output_`` (n_out,) holds sigma_j (unit of y), ``weights_``
    their inverses. ``update`` keeps the weights of the last ``fit`` (1 before any fit).
    ``n_iter`` > 1 re-estimates sigma_j from the weighted fit's residuals (iterated WLS); the
    default 1 is Gautier's single pass, whose sigma_j of the quieter outputs is inflated by
    the OLS pass.
    """

    def __init__(self, n_iter: int = 1, column_noise: ColumnNoise | None = None,
                 row_groups=None, row_ticks=None, lag_ticks: int = 0):  # fmt: skip
        super().__init__(column_noise, row_groups, row_ticks, lag_ticks)
        self.n_iter = int(n_iter)

    def fit(self, A, y):
        A3, y2 = as_blocks(A, y)
        N, n, p = A3.shape
        self._w = np.ones(n)
        r = self._fit_pass(A3, y2)
        p_j = np.count_nonzero(np.any(A3 != 0, axis=0), axis=1)
        rows_j = np.count_nonzero(np.any(A3 != 0, axis=2) | (y2 != 0), axis=0)  # not all-zero
        dof = np.maximum(rows_j - p_j, 1)
        for _ in range(max(self.n_iter, 1)):
            sig = np.sqrt(np.sum(r**2, axis=0) / dof)
            sig = np.where(sig > 0, sig, max(float(sig.max()), 1e-300))
            self.sigma_per_output_ = sig
            self.weights_ = self._w = 1.0 / sig
            r = self._fit_pass(A3, y2)
        self._add_error_structure(A3, r)  # once, on the final weights' residuals
        return self
