"""Choice of the low-pass cut-off from the trajectory's bandwidth.

Rule (documented defaults, every number settable):

* If the excitation's harmonics are known (e.g. a finite Fourier series with fundamental
  f0 and H harmonics, highest = H f0), fc = ``harmonic_factor`` (:data:`HARMONIC_FACTOR`,
  8) x the highest one.
* Otherwise, from the spectrum of the positions: each joint's position is resampled to a
  uniform grid, linearly detrended, Hann-windowed; f_E is the frequency below which the
  fraction ``energy`` (99.5 %) of its energy lies; fc = ``spectrum_factor`` (2) x the
  largest f_E over the joints. The factor leaves room for the acceleration, whose spectrum
  is the position's weighted by f^4.
* Either way fc is clipped to [0.5 Hz, 0.4 x Nyquist].

On the DFKI double-pendulum runs the spectrum rule gives about 5-6 Hz, in line with the
lab's 5 Hz.
"""

from __future__ import annotations

import numpy as np

from guardid.conditioning.filters import is_uniform, resample, uniform_grid

MIN_CUTOFF_HZ = 0.5
HARMONIC_FACTOR = 8.0
"""Cut-off = this x the excitation's highest harmonic when it is known [-] (measured on guard
captures: 5x leaves the PID-tracked stick/slip transients under-resolved, 8x was best)."""
MAX_NYQUIST_FRACTION = 0.4


def clip_cutoff(cutoff_hz: float, fs_hz: float) -> float:
    """``cutoff_hz`` clipped to [0.5 Hz, 0.4 * fs / 2]."""
    return float(np.clip(cutoff_hz, MIN_CUTOFF_HZ, MAX_NYQUIST_FRACTION * 0.5 * fs_hz))


def energy_bandwidth(t_s, q, energy: float = 0.995) -> np.ndarray:
    """Per joint (n,) [Hz]: frequency below which ``energy`` of the detrended q's energy lies."""
    t = np.asarray(t_s, dtype=float)
    q = np.asarray(q, dtype=float).reshape(len(t), -1)
    if not is_uniform(t):
        grid, dt = uniform_grid(t)
        q = resample(t, q, grid)
    else:
        dt = float(np.median(np.diff(t)))
    from scipy.signal import detrend  # here: scipy.signal is 0.6 s of imports

    x = detrend(q, axis=0) * np.hanning(q.shape[0])[:, None]
    power = np.abs(np.fft.rfft(x, axis=0)) ** 2
    freq = np.fft.rfftfreq(q.shape[0], dt)
    cum = np.cumsum(power, axis=0)
    cum /= np.maximum(cum[-1], np.finfo(float).tiny)
    idx = np.array([np.searchsorted(cum[:, j], energy) for j in range(q.shape[1])])
    return freq[np.minimum(idx, len(freq) - 1)]


def choose_cutoff(
    t_s,
    q,
    *,
    highest_harmonic_hz: float | None = None,
    harmonic_factor: float = HARMONIC_FACTOR,
    energy: float = 0.995,
    spectrum_factor: float = 2.0,
) -> float:
    """Low-pass cut-off [Hz] for positions ``q`` (N, n) sampled at ``t_s`` (N,) [s].

    See the module docstring for the rule; the result is clipped to [0.5, 0.4 Nyquist].
    """
    fs = 1.0 / float(np.median(np.diff(np.asarray(t_s, dtype=float))))
    if highest_harmonic_hz is not None:
        return clip_cutoff(harmonic_factor * highest_harmonic_hz, fs)
    return clip_cutoff(spectrum_factor * float(energy_bandwidth(t_s, q, energy).max()), fs)
