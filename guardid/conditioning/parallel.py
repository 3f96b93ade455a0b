"""Parallel filtering of the regressor and the torque (Gautier's decimate procedure).

:func:`condition` low-passes positions and efforts with the same filter, which is exact
for the terms of tau = Y(q, qd, qdd) theta that are linear in the signals. The regressor
is nonlinear in q, qd (sin q, qd^2, ...), so the filtered torque and the regressor of the
filtered motion still differ slightly near the cut-off, and noise left on qdd biases LS
toward zero (errors in variables). The remedy: compute the regressor on the conditioned
samples (cut-off high enough for clean derivatives), then low-pass *the regressor columns
and the torque* with one and the same filter and decimate both: noise above the
excitation band is removed from both sides after the nonlinear map, so the filter drops
out of the equation. On the DFKI runs this makes the estimates nearly independent of the
position cut-off (a 20 Hz position filter no longer collapses them).
"""

from __future__ import annotations

import numpy as np

from guardid.conditioning.filters import DEFAULT_ORDER, decimation_factor, zero_phase_lowpass


def parallel_filter(fs_hz: float, cutoff_hz: float, *signals, decimate=None, order=DEFAULT_ORDER):
    """Zero-phase low-pass every signal along axis 0 with one filter, then decimate.

    Parameters
    ----------
    fs_hz : float
        Sample rate [Hz] of the (uniform) signals.
    cutoff_hz : float
        Cut-off [Hz] of the parallel filter (at most the excitation band's upper edge
        times a small factor; lower than the position filter's).
    *signals : array_like (N, ...)
        E.g. the regressor (N, n, p), the torque (N, n); boolean arrays (masks) are not
        filtered, only decimated.
    decimate : int, optional
        Keep every k-th sample; default: new Nyquist >= 2 x cutoff.

    Returns
    -------
    (k, [filtered and decimated signals in the given order])
    """
    k = decimation_factor(fs_hz, cutoff_hz) if decimate is None else int(decimate)
    out = []
    for s in signals:
        s = np.asarray(s)
        if s.dtype == bool:
            out.append(s[::k])
            continue
        flat = s.reshape(s.shape[0], -1).astype(float)
        out.append(zero_phase_lowpass(flat, fs_hz, cutoff_hz, order).reshape(s.shape)[::k])
    return k, out
