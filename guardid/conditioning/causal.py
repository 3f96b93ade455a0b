"""Causal (online) conditioning: streaming low-pass + backward differences.

:class:`CausalConditioner` filters positions and efforts with the same Butterworth
low-pass as the offline path (``scipy.signal.sosfilt`` with carried state, initialised at
steady state on the first sample like ``lfilter_zi``), then differentiates with
backward differences over the last three filtered samples:

    q   = qf[k-1]
    qd  = (qf[k] - qf[k-2]) / (2 T)
    qdd = (qf[k] - 2 qf[k-1] + qf[k-2]) / T^2

All three are centred on sample k-1, so they refer to the same instant.

Delay: every output of update k describes the motion at t_k - delay_s with

    delay_s = (D + 1) T,   D = the low-pass's group delay at 0 Hz [samples]

(for a 4th-order Butterworth D T ~ 2.613 / (2 pi fc): about 0.083 s at fc = 5 Hz). For
frequencies well below fc the delay is flat; it grows toward fc (Butterworth group delay
peaks near the cut-off).

Effort: with ``period_mean=True`` effort[k] is the mean over (t_{k-1}, t_k] (the guard
firmware's current), i.e. it belongs to t_k - T/2; the mean of the last two filtered
efforts then belongs to t_k - T - D T, the same instant as q. With ``period_mean=False``
(instantaneous effort samples) the filtered effort of sample k-1 is used.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.signal import sosfilt, sosfilt_zi

from guardid.conditioning.filters import DEFAULT_ORDER, lowpass_sos


def dc_group_delay(sos: np.ndarray) -> float:
    """Group delay at 0 Hz [samples] of a filter in second-order sections."""
    k = np.arange(3)
    total = 0.0
    for b, a in zip(sos[:, :3], sos[:, 3:], strict=True):
        total += (k @ b) / b.sum() - (k @ a) / a.sum()
    return float(total)


@dataclass(frozen=True)
class StreamOutput:
    """One chunk of causal output, (M, n) each, at instants t_k - delay_s.

    q [rad], qd [rad/s], qdd [rad/s^2], tau [N m, or effort unit if no gain], slow (M, n)
    bool (True = that joint below its threshold), stiction (M,) bool (True = some joint
    below its threshold); all False if no threshold was given.
    """

    q: np.ndarray
    qd: np.ndarray
    qdd: np.ndarray
    tau: np.ndarray
    stiction: np.ndarray
    slow: np.ndarray


class CausalConditioner:
    """Streaming low-pass + differentiation for online identification (module docstring).

    Parameters
    ----------
    n_joints : int
    sample_period_s : float
        Fixed sample period T [s] (the tick period; online data are on ticks).
    cutoff_hz : float
        Low-pass cut-off [Hz] (same meaning as offline).
    order : int
        Butterworth order (default 4).
    period_mean : bool
        True if effort[k] is the mean over the period ending at tick k.
    gain : scalar or (n,) [N m per effort unit], optional
        tau = gain * effort; None keeps the effort unit (identification in current units).
    stiction_threshold : scalar or (n,) [rad/s], optional
        Flag outputs with |qd_j| below it.
    """

    def __init__(
        self,
        n_joints: int,
        sample_period_s: float,
        cutoff_hz: float,
        *,
        order: int = DEFAULT_ORDER,
        period_mean: bool = True,
        gain=None,
        stiction_threshold=None,
    ):
        self.n = int(n_joints)
        self.dt = float(sample_period_s)
        self.cutoff_hz = float(cutoff_hz)
        self.sos = lowpass_sos(cutoff_hz, 1.0 / self.dt, order)
        self.period_mean = period_mean
        self.gain = None if gain is None else np.asarray(gain, dtype=float)
        self.threshold = None if stiction_threshold is None else np.asarray(stiction_threshold)
        self.delay_samples = dc_group_delay(self.sos) + 1.0
        self._zi = None
        self._hist = None  # filtered [q, effort] at k-2, k-1: (2, 2n)

    @property
    def delay_s(self) -> float:
        """Delay [s] of every output relative to the tick of the update: (D + 1) T."""
        return self.delay_samples * self.dt

    def reset(self) -> None:
        """Forget the filter state (the next update re-initialises at steady state)."""
        self._zi = None
        self._hist = None

    def update(self, q_rad, effort) -> StreamOutput:
        """Feed one sample (n,) or a chunk (M, n) of positions [rad] and efforts.

        Returns a :class:`StreamOutput` with M rows, row i describing t_{k_i} - delay_s.
        """
        q = np.atleast_2d(np.asarray(q_rad, dtype=float))
        e = np.atleast_2d(np.asarray(effort, dtype=float))
        x = np.concatenate([q, e], axis=1)
        if self._zi is None:
            self._zi = sosfilt_zi(self.sos)[:, :, None] * x[0][None, None, :]
            self._hist = np.repeat(x[:1], 2, axis=0)
        y, self._zi = sosfilt(self.sos, x, axis=0, zi=self._zi)
        full = np.concatenate([self._hist, y], axis=0)
        self._hist = full[-2:]
        y0, y1, y2 = full[2:], full[1:-1], full[:-2]  # k, k-1, k-2
        n, dt = self.n, self.dt
        qd = (y0[:, :n] - y2[:, :n]) / (2.0 * dt)
        qdd = (y0[:, :n] - 2.0 * y1[:, :n] + y2[:, :n]) / (dt * dt)
        tau = 0.5 * (y0[:, n:] + y1[:, n:]) if self.period_mean else y1[:, n:]
        if self.gain is not None:
            tau = tau * self.gain
        if self.threshold is None:
            slow = np.zeros(qd.shape, dtype=bool)
        else:
            slow = np.abs(qd) < self.threshold
        return StreamOutput(y1[:, :n].copy(), qd, qdd, tau, slow.any(axis=1), slow)
