"""Identification path, acceleration form: the cut-off candidates scored.

Takes the runs, the options and the candidate cut-offs [Hz] that
:func:`guardid.identify.cutoff.choose_cutoff_cv` proposes; gives per candidate the
held-out relative rms error [-] of the measured effort by K-fold cross-validation over
contiguous time blocks (:mod:`guardid.identify.cutoff` says why), the full-data least
squares estimate and whether the Coulomb columns were low-passed like the effort. The
K-fold and the least-squares covariance's volume serve the parallel filter's choice too
(:mod:`guardid.identify.parallel_rows`).
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from guardid.dynamics import build_model
from guardid.identify.acceleration_run import condition_kwargs, condition_run
from guardid.identify.equation import free_columns, friction_columns

MIN_ROWS_PER_PARAMETER = 10
"""A cut-off candidate is eligible only if its conditioning keeps more rows than this many
per identified parameter (at its own decimation) [-]."""


def cutoff_scores(runs, description, options, cands, blocks, in_current_units, effort_is_torque):
    """Per candidate cut-off [Hz]: (held-out relative rms error of the measured effort,
    full-data LS estimate) by K-fold cross-validation over ``blocks`` contiguous time blocks
    per run (:mod:`guardid.identify.cutoff`)."""
    model = build_model(description)
    free = free_columns(model, description)
    t0 = np.asarray(runs[0][0], dtype=float)
    fs = 1.0 / float(np.median(np.diff(t0)))
    common = options.with_(parallel_filter_hz=None)
    k = condition_kwargs(common, fs, max(cands), effort_is_torque, description)["decimate"]
    common = replace(common, decimate=k, parallel_filter_hz=None)
    flags = (in_current_units, effort_is_torque, model, free)
    middle = cands[len(cands) // 2]  # evaluation rows: those usable under the middle one
    # only their masks are kept (a long log's conditioned signals need not stay in memory)
    ref = [condition_run(r, description, common, middle, *flags)[0].mask for r in runs]
    variants = [options.friction_filter]
    if options.friction_filter is None:
        variants = [False, True] if friction_columns(model, free) else [False]
    scores, thetas, chosen = [], [], []
    for fc in cands:
        best = (np.inf, None, False)
        # rows the final fit would keep at this candidate's own decimation
        k_own = condition_kwargs(options.with_(parallel_filter_hz=None), fs, fc, effort_is_torque,
                                 description)["decimate"]  # fmt: skip
        for ff in variants:
            parts = []  # (block id, A_fit, y_fit, A_eval, y_raw_eval)
            for r_i, (run, rc) in enumerate(zip(runs, ref, strict=True)):
                c, A, y, raw, plain = condition_run(run, description, common, fc, *flags, ff,
                                                     fallback=False)  # fmt: skip
                n, fit = len(c.t), c.mask
                del c  # only its mask is needed here
                block = np.minimum((np.arange(n) * blocks) // max(n, 1), blocks - 1)
                evaluate = rc[:n] if len(rc) >= n else np.zeros(n, bool)
                for b in range(blocks):
                    sel = block == b
                    parts.append(((r_i, b), A[sel & fit], y[sel & fit],
                                  plain[sel & evaluate], raw[sel & evaluate]))  # fmt: skip
                del A, y, raw, plain  # before the next candidate's are made
            score, theta = kfold_error(parts, min_rows=3 * len(free))
            if sum(len(p[1]) for p in parts) * k / max(k_own, 1) <= MIN_ROWS_PER_PARAMETER * len(
                free
            ):  # too few rows left at its own decimation: not eligible
                score = np.nan
            if not score >= best[0]:  # NaN never wins
                best = (score, theta, bool(ff))
        scores.append(best[0] if np.isfinite(best[0]) else np.nan)
        thetas.append(best[1])
        chosen.append(best[2])
    return scores, thetas, chosen


def kfold_error(parts, min_rows: int):
    """Held-out relative rms error over all parts (each left out once) and the full fit;
    NaN when a fold keeps ``min_rows`` fitting rows or fewer."""
    p = parts[0][1].shape[2]
    total = sum(len(A) for _, A, _, _, _ in parts)
    normals = []
    for _, A, y, _, _ in parts:
        a = A.reshape(-1, p)
        normals.append((a.T @ a, a.T @ y.reshape(-1)))
    G = sum(n[0] for n in normals)
    h = sum(n[1] for n in normals)
    theta_full = _solve(G, h)
    res2 = ref2 = 0.0
    for (_, A, _, Ae, ye), (g, v) in zip(parts, normals, strict=True):
        if len(ye) == 0:
            continue
        theta = _solve(G - g, h - v) if total - len(A) > min_rows else None
        if theta is None:
            return np.nan, theta_full
        r = ye - Ae @ theta
        res2 += float(np.sum(r**2))
        ref2 += float(np.sum(ye**2))
    return (np.sqrt(res2 / ref2) if ref2 > 0 else np.nan), theta_full


def _solve(G, h):
    """Solution of G theta = h with column scaling; None if singular."""
    d = np.sqrt(np.clip(np.diag(G), 1e-300, None))
    try:
        x = np.linalg.solve(G / np.outer(d, d), h / d)
    except np.linalg.LinAlgError:
        return None
    return x / d


def covariance_log_volume(A, y) -> float:
    """log det(s^2 (A^T A)^-1) / p for the rows A (M, n, p), y (M, n): the log of the
    geometric mean of the least-squares estimate's variances (the covariance's volume per
    parameter) [-]; NaN when rank-deficient or with at most 3 p rows."""
    p = A.shape[-1]
    a, b = A.reshape(-1, p), y.reshape(-1)
    if len(b) <= 3 * p:
        return np.nan
    d = np.sqrt(np.sum(a * a, axis=0))
    if np.any(d == 0):
        return np.nan
    x, *_ = np.linalg.lstsq(a / d, b, rcond=None)
    r = b - (a / d) @ x
    s2 = float(r @ r) / (len(b) - p)
    sign, logdet = np.linalg.slogdet((a / d).T @ (a / d))
    if sign <= 0 or s2 <= 0:
        return np.nan
    return float(np.log(s2) - (logdet + 2.0 * np.sum(np.log(d))) / p)
