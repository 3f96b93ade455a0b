"""The filtered momentum form for a reproduction's model: nothing differentiated twice.

With p = M(q) q' = Y_p(q, q') theta and the rest r = C(q, q') q' + g(q) - dM/dt q' =
Y_r(q, q') theta, the torque integrated over a sample period (t_(k-1), t_k] is

    T tau_(k-1) = Y_p(q_k, v_k) theta - Y_p(q_(k-1), v_(k-1)) theta + integral of Y_r theta dt

exactly for a torque held over each period (the planar arm's zero-order-hold PID). Y_p and
Y_r come from the model's inverse-dynamics regressor alone (Y_p = Y(q, 0, v) - Y(q, 0, 0);
Y_r = Y(q, v, 0) - dY_p/dq v, the directional derivative by a central difference), so any
model with ``regressor(q, qd, qdd)`` can be used. Velocities are central differences of the
measured positions (once differentiated), the integral the fourth-order four-point rule
T/24 (-f_(k-2) + 13 f_(k-1) + 13 f_k - f_(k+1)). One causal Butterworth low-pass runs over
the impulses and every column alike: a linear filter applied to both sides keeps the
equation exact, so the filter adds no bias (the zero-phase filter of q and tau before a
nonlinear regressor does: seed001-table1's acceleration form). The guard robot's form, with
motor currents, stiction cuts and the drive's steps, is :mod:`guardid.conditioning`'s
(DESIGN.md section 5b).
"""

from __future__ import annotations

import numpy as np
from scipy.signal import butter, sosfilt

ORDER = 2
"""Order of the causal Butterworth filter (DESIGN.md 5b: a first order passes the
velocity's noise into the momentum column)."""
HARMONIC_FACTOR = 4.0
"""Cut-off = this x the excitation's highest frequency [-]."""
QUADRATURE = np.array([-1.0, 13.0, 13.0, -1.0]) / 24.0
"""Four-point rule over samples k-2 .. k+1 for the integral over (t_(k-1), t_k] [x T]."""
SETTLE = 1e-3
"""The filter's start-up is dropped until its impulse response falls below this fraction of
its peak for good [-]."""
EPS = 1e-6
"""Step of the directional derivative of Y_p along v [s] (central difference)."""


def momentum_regressor(model, q, v) -> np.ndarray:
    """Y_p (N, n, p): M(q) v = Y_p theta."""
    zero = np.zeros_like(q)
    return model.regressor(q, zero, v) - model.regressor(q, zero, zero)


def rest_regressor(model, q, v) -> np.ndarray:
    """Y_r (N, n, p): C(q, v) v + g(q) - dM/dt v = Y_r theta."""
    m_dot_v = (momentum_regressor(model, q + EPS * v, v)
               - momentum_regressor(model, q - EPS * v, v)) / (2 * EPS)  # fmt: skip
    return model.regressor(q, v, np.zeros_like(q)) - m_dot_v


def settle_samples(sos) -> int:
    """Samples until the filter's impulse response stays below :data:`SETTLE` of its peak."""
    x = np.zeros(1 << 16)
    x[0] = 1.0
    h = np.abs(sosfilt(sos, x))
    return int(np.flatnonzero(h > SETTLE * h.max())[-1]) + 1


def momentum_rows(model, q, torque_held, dt: float, cutoff_hz: float):
    """(A (M, n, p), y (M, n) [N m], notes): the filtered period equations of one run.

    ``q`` (N, n) [rad] measured at the samples, ``torque_held`` (N, n) [N m] measured, each
    held over the period that follows it; ``dt`` [s]; rows every 1 / (2 cutoff) after the
    filter has settled, divided by T (torque units)."""
    n = len(q)
    v = np.zeros_like(q, dtype=float)
    v[1:-1] = (q[2:] - q[:-2]) / (2 * dt)
    p_mom, rest = momentum_regressor(model, q, v), rest_regressor(model, q, v)
    phi = np.zeros_like(p_mom)
    phi[1:] = p_mom[1:] - p_mom[:-1]
    w = QUADRATURE * dt
    phi[2:-1] += w[0] * rest[:-3] + w[1] * rest[1:-2] + w[2] * rest[2:-1] + w[3] * rest[3:]
    impulse = np.zeros_like(q, dtype=float)
    impulse[1:] = dt * np.asarray(torque_held, dtype=float)[:-1]
    ok = slice(3, n - 2)  # the stencils reach the ends: those periods are not defined
    sos = butter(ORDER, cutoff_hz, fs=1.0 / dt, output="sos")
    f_phi, f_imp = sosfilt(sos, phi[ok], axis=0), sosfilt(sos, impulse[ok], axis=0)
    skip, step = settle_samples(sos), max(1, int(1.0 / (2.0 * cutoff_hz * dt)))
    rows = np.arange(skip, len(f_imp), step)
    notes = [
        f"momentum form: velocities by central differences of the measured q (once"
        f" differentiated), the period impulse T tau of the held torque, Y_r integrated by the"
        f" four-point rule; one causal Butterworth (order {ORDER}, {cutoff_hz:.3g} Hz ="
        f" {HARMONIC_FACTOR:g} x the highest frequency) on both sides; the first"
        f" {skip * dt:.2f} s dropped (filter start-up), rows every {step * dt * 1e3:g} ms"
        f" ({len(rows)} rows)"
    ]
    return f_phi[rows] / dt, f_imp[rows] / dt, notes
