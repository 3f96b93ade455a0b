"""Samples near zero joint velocity (stiction), to be dropped from identification.

When a joint reverses or barely moves, friction is whatever balances the drive, not
Fv q' + Fc sign(q') (DESIGN.md section 5); such samples must not enter the fit. A sample
is flagged when |qd_j| < threshold_j for *any* joint, so whole samples (all joints' rows)
are dropped.

Default threshold per joint, the larger of
* ``counts`` (3) encoder quanta per original sample period, in rad/s, when the position
  resolution is known: below that the velocity is not resolved anyway, and
* ``fraction`` (5 %) of the joint's peak speed in the run (99th percentile of |qd|, robust
  to spikes): the Coulomb transition region scales with the motion.
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np

DEFAULT_COUNTS = 3.0
DEFAULT_FRACTION = 0.05


def default_stiction_threshold(
    qd,
    *,
    resolution_rad=None,
    sample_period_s: float | None = None,
    counts: float = DEFAULT_COUNTS,
    fraction: float = DEFAULT_FRACTION,
) -> np.ndarray:
    """Per-joint threshold (n,) [rad/s] (module docstring).

    Parameters
    ----------
    qd : array_like (N, n)
        Joint velocities [rad/s].
    resolution_rad : scalar or (n,), optional
        Position quantum [rad] (2 pi / counts per joint revolution).
    sample_period_s : float, optional
        Original sample period [s]; required with ``resolution_rad``.
    """
    qd = np.asarray(qd, dtype=float)
    thr = fraction * np.percentile(np.abs(qd), 99.0, axis=0)
    if resolution_rad is not None:
        if sample_period_s is None:
            raise ValueError("resolution_rad needs sample_period_s")
        thr = np.maximum(thr, counts * np.asarray(resolution_rad, float) / sample_period_s)
    return np.broadcast_to(thr, qd.shape[1:]).astype(float)


def stiction_mask(qd, threshold) -> np.ndarray:
    """Boolean (N,): True where |qd_j| < threshold_j [rad/s] for any joint (drop these)."""
    qd = np.asarray(qd, dtype=float)
    return np.any(np.abs(qd) < np.asarray(threshold, dtype=float), axis=1)


@lru_cache(maxsize=16)
def guard_periods(order: int, share: float) -> float:
    """Half-width [cut-off periods] of the span around an impulse that holds ``share`` of the
    zero-phase Butterworth low-pass's impulse response (absolute value; the filter applied
    forward and backward, order ``order``), worked out numerically from the filter itself.

    Rows that close to a sample the model cannot explain (a stuck joint's holding torque, a
    hard stop's contact force) carry that sample through the filter. Order 4: 0.95 -> about
    1.0 period, 0.99 -> about 1.75 periods.
    """
    from scipy.signal import butter, sosfiltfilt

    fs_per_fc = 200.0  # samples per cut-off period: fine enough for 3 digits
    n = int(40 * fs_per_fc)
    x = np.zeros(2 * n + 1)
    x[n] = 1.0
    h = np.abs(sosfiltfilt(butter(order, 1.0, fs=fs_per_fc, output="sos"), x))
    mass = h[n] + 2.0 * np.cumsum(h[n + 1 :])
    k = int(np.searchsorted(mass / mass[-1], share))
    return (k + 1) / fs_per_fc


def at_position_limit(q, limits, resolution=None) -> np.ndarray:
    """Boolean (N,): True where some joint's raw position lies at (within two position quanta
    of, or beyond) one of its limits ``limits`` (n, 2) [rad | m], NaN = no limit.

    There the joint rests against a hard stop, whose contact force the rigid-body model does
    not have. Without a known ``resolution`` (n,) the tolerance is 0.1 % of the travel.
    """
    q = np.asarray(q, dtype=float)
    lim = np.asarray(limits, dtype=float).reshape(q.shape[1], 2)
    travel = lim[:, 1] - lim[:, 0]
    tol = 1e-3 * np.where(np.isfinite(travel), travel, 0.0)
    if resolution is not None:
        tol = np.maximum(tol, 2.0 * np.broadcast_to(np.asarray(resolution, float), tol.shape))
    with np.errstate(invalid="ignore"):
        low = q <= lim[:, 0] + tol
        high = q >= lim[:, 1] - tol
    return np.any(low | high, axis=1)
