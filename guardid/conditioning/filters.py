"""Offline filtering: resampling, zero-phase Butterworth low-pass, derivatives, decimation.

Design (DESIGN.md sections 2 and 5):

* Uneven time stamps are handled by **resampling to a uniform grid first** (cubic spline
  through the samples, grid step = median step). A fixed-step grid is what the IIR filter
  and the difference stencils assume; differentiating on jittery stamps would turn the
  stamp jitter into derivative noise.
* Low-pass: Butterworth in second-order sections applied forward and backward
  (``scipy.signal.sosfiltfilt``): zero phase, magnitude |H(f)|^2 = 1 / (1 + (f/fc)^(2 order)),
  i.e. -6 dB at the cut-off fc.
* Derivatives: **eighth-order central differences** of the *filtered* signal (nine-point
  stencils). They add no phase and, after the low-pass, their error is tiny even for motion
  near the Nyquist frequency ((w T)^8 / 630 relative for the first derivative, about
  (w T)^8 / 3150 for the second: 0.1 % for a 20 Hz motion sampled at 100 Hz, where the
  five-point stencils were 3 % off). A
  Savitzky-Golay derivative would add a second, different smoothing that the torque side
  would not see, breaking the parallel filtering of positions and torques; the low-pass
  is the one place where smoothing happens.
* Decimation keeps every k-th sample of the filtered signals (the zero-phase low-pass is
  the anti-alias filter); the default k keeps the new Nyquist frequency >= 2 fc.
"""

from __future__ import annotations

import numpy as np

DEFAULT_ORDER = 4
"""Butterworth order (sosfiltfilt doubles the attenuation slope)."""


def lowpass_sos(cutoff_hz: float, fs_hz: float, order: int = DEFAULT_ORDER) -> np.ndarray:
    """Butterworth low-pass as second-order sections, cut-off [Hz] at sample rate fs [Hz]."""
    if not 0.0 < cutoff_hz < 0.5 * fs_hz:
        raise ValueError(f"cut-off {cutoff_hz} Hz must lie in (0, fs/2 = {0.5 * fs_hz}) Hz")
    from scipy.signal import butter  # here: the constants need no scipy

    return butter(order, cutoff_hz, btype="low", fs=fs_hz, output="sos")


def zero_phase_lowpass(x, fs_hz: float, cutoff_hz: float, order: int = DEFAULT_ORDER):
    """Zero-phase low-pass of ``x`` (N, ...) along axis 0 (sosfiltfilt).

    The ends are padded by odd extension over three periods of the cut-off (or the whole
    signal if shorter), so the start-up transient stays small; still, treat about one
    cut-off period at each end as less reliable.
    """
    x = np.asarray(x, dtype=float)
    sos = lowpass_sos(cutoff_hz, fs_hz, order)
    padlen = min(int(np.ceil(3.0 * fs_hz / cutoff_hz)), x.shape[0] - 1)
    from scipy.signal import sosfiltfilt

    return sosfiltfilt(sos, x, axis=0, padlen=padlen)


def uniform_grid(t_s) -> tuple[np.ndarray, float]:
    """Uniform grid (M,) from t[0] with step = median step of ``t_s`` [s]; returns (grid, dt)."""
    t = np.asarray(t_s, dtype=float)
    steps = np.diff(t)
    if steps.size == 0 or np.any(steps <= 0):
        raise ValueError("time stamps must be strictly increasing (at least two samples)")
    dt = float(np.median(steps))
    m = int(np.floor((t[-1] - t[0]) / dt + 1e-9)) + 1
    return t[0] + dt * np.arange(m), dt


def is_uniform(t_s, rtol: float = 1e-6) -> bool:
    """True if the steps of ``t_s`` are equal to within ``rtol`` of the median step."""
    steps = np.diff(np.asarray(t_s, dtype=float))
    med = np.median(steps)
    return bool(np.all(np.abs(steps - med) <= rtol * med))


def resample(t_s, x, grid) -> np.ndarray:
    """Values of ``x`` (N, ...) sampled at ``t_s`` evaluated at ``grid`` (cubic spline)."""
    from scipy.interpolate import CubicSpline

    return CubicSpline(np.asarray(t_s, float), np.asarray(x, float), axis=0)(grid)


D1_STENCIL = np.array([1 / 280, -4 / 105, 1 / 5, -4 / 5, 0.0, 4 / 5, -1 / 5, 4 / 105, -1 / 280])
D2_STENCIL = np.array(
    [-1 / 560, 8 / 315, -1 / 5, 8 / 5, -205 / 72, 8 / 5, -1 / 5, 8 / 315, -1 / 560]
)


def central_derivatives(x, dt: float) -> tuple[np.ndarray, np.ndarray]:
    """First and second derivatives of ``x`` (N, ...) on a uniform step dt [s].

    Eighth-order nine-point central stencils inside, second-order stencils at the four
    samples nearest each end (those are masked out by :func:`condition` anyway).
    """
    x = np.asarray(x, dtype=float)
    if x.shape[0] < 9:
        raise ValueError("need at least 9 samples to differentiate")
    d1 = np.gradient(x, dt, axis=0, edge_order=2)
    d2 = np.gradient(d1, dt, axis=0, edge_order=2)
    n = x.shape[0]
    d1[4:-4] = sum(c * x[k : n - 8 + k] for k, c in enumerate(D1_STENCIL) if c) / dt
    d2[4:-4] = sum(c * x[k : n - 8 + k] for k, c in enumerate(D2_STENCIL)) / (dt * dt)
    return d1, d2


def decimation_factor(fs_hz: float, cutoff_hz: float, nyquist_margin: float = 2.0) -> int:
    """Largest k with new Nyquist fs / (2 k) >= nyquist_margin * cutoff (at least 1)."""
    return max(1, int(np.floor(fs_hz / (2.0 * nyquist_margin * cutoff_hz))))


def decimate(x, k: int, start: int = 0) -> np.ndarray:
    """Keep every k-th sample of ``x`` (N, ...) starting at index ``start`` (no filtering)."""
    if k < 1:
        raise ValueError("decimation factor must be >= 1")
    return np.asarray(x)[start::k]
