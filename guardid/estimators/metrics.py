"""Identification quality metrics (DESIGN.md section 5, as in the BIRDy benchmark)."""

from __future__ import annotations

import numpy as np

from ._base import as_blocks


def d_theta(theta_hat, theta) -> float:
    """Relative parameter error (2/p) sum |th_hat - th| / (|th| + |th_hat|), dimensionless.

    A parameter with th = th_hat = 0 contributes 0.
    """
    th_hat = np.asarray(theta_hat, dtype=float)
    th = np.asarray(theta, dtype=float)
    den = np.abs(th) + np.abs(th_hat)
    num = np.abs(th_hat - th)
    ratio = np.divide(num, den, out=np.zeros_like(num), where=den > 0)
    return float(2.0 * ratio.sum() / th.size)


def d_tau(A, tau, theta_hat, per_joint: bool = False):
    """Relative torque error ||tau_j - (A th_hat)_j|| / ||tau_j|| (dimensionless).

    Norms run over all samples of output (joint) j; ``A`` (N, n_out, p) and ``tau``
    (N, n_out), or stacked (M, p) / (M,) (one output). Returns the mean over joints, or the
    per-joint array (n_out,) if ``per_joint``.
    """
    A3, y2 = as_blocks(A, tau)
    r = y2 - A3 @ np.asarray(theta_hat, dtype=float)
    with np.errstate(divide="ignore", invalid="ignore"):  # a joint without rows: NaN
        per = np.linalg.norm(r, axis=0) / np.linalg.norm(y2, axis=0)
    return per if per_joint else float(per.mean())


def settle_time(t_s, x, target: float, t_change_s: float, rel: float = 0.05) -> float:
    """Settle time [s] of an estimate track x(t) after ``t_change_s``: from then on to the
    end of the track, |x - target| <= ``rel`` |target| (0 if it never leaves the band)."""
    t_s, x = np.asarray(t_s, dtype=float), np.asarray(x, dtype=float)
    bad = (t_s > t_change_s) & (np.abs(x - target) > rel * abs(target))
    return float(t_s[bad].max() - t_change_s) if bad.any() else 0.0
