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
