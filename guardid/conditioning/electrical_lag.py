"""The motor current's lag behind each voltage step, in the momentum form's stencil error.

The momentum form's kink correction (:func:`guardid.conditioning.momentum.kink_correction`)
takes the drive torque to step at each tick, where the PWM voltage changes. A motor's
current follows its voltage with the electrical time constant tau_e = L / R, so each step
rises as 1 - exp(-s / tau_e) into the period instead. The period-mean current (what the
telemetry reports) holds the lag; the positions inside the period do not see it as a step,
and the velocity stencil errs by a further amount the kink correction does not count.

Per period i the drive torque's deviation from the stepped model is -J_i exp(-s / tau_e),
J_i the step at its start (s from the period's start). Its acceleration's first moment
about the period's start, less the part the period mean holds, is

    m1_i = J_i / M x T^2 (r / 2 - r^2 + exp(-1 / r) (r^2 + r / 2)),   r = tau_e / T,

and a period between tick k and tick k + m adds -m1 (m > 0; +m1 for m < 0) to
q_(k+m) - q_k - m T v_k, as the back-EMF slope's term does
(:func:`~guardid.conditioning.momentum.slope_weights`). The stencil's momentum error at
tick k is then T f(r) sum_i V_i J_i, V_i -c_m summed over the stencil's points beyond k
whose span holds period i (+c_m before k), f(r) the bracket above. The step J_i is the
change of the drive's period-mean torque plus the back-EMF's continuous change over the
tick, J_i = tau_i - tau_(i-1) + D (w_i - w_(i-1)) (D the drive's electrical damping,
w_i = (q_i - q_(i-1)) / T the period's mean speed), since the back-EMF does not jump.

On the guard (tau_e 0.25 ms against a 15 ms tick: r = 0.017) the lag is 1.7 % of the tick.
Uncorrected, it left the pan's friction biased by about 0.22 std (Fv1) on a 1 h Schroeder
capture with the plant's exact angles and currents, and 0.00 with the inductance set to
zero (docs/std_residuals.md, 2026-11-29).
"""

from __future__ import annotations

import numpy as np


def electrical_time_constants(description) -> np.ndarray:
    """(n,) tau_e = L / R per joint [s] (0 without a drive, a resistance or an inductance)."""
    out = np.zeros(len(description.joints))
    for j, joint in enumerate(description.joints):
        d = joint.drive
        if d is not None and d.resistance > 0 and d.inductance > 0:
            out[j] = d.inductance / d.resistance
    return out


def lag_factor(tau_e, dt: float) -> np.ndarray:
    """f(r) = r / 2 - r^2 + exp(-1 / r) (r^2 + r / 2), r = ``tau_e`` / ``dt`` (module
    docstring) [-]; 0 where tau_e is 0."""
    r = np.asarray(tau_e, dtype=float) / float(dt)
    with np.errstate(divide="ignore", over="ignore"):
        tail = np.where(r > 0, np.exp(-1.0 / np.where(r > 0, r, 1.0)), 0.0)
    return r / 2.0 - r**2 + tail * (r**2 + r / 2.0)


def lag_weights(coef, reach: int) -> tuple[np.ndarray, int]:
    """(V, first): the stencil's velocity error per unit of each period's first moment,
    v_hat_k - v_k = (1 / T) sum_i V[i] m1(period ending at tick k + first + i) x ..., for the
    central stencil ``coef`` (coefficients x 1 / T at offsets -reach .. reach) [-]."""
    first = -int(reach) + 1
    V = np.zeros(2 * int(reach))
    for m_idx, c in enumerate(np.asarray(coef, dtype=float)):
        m = m_idx - int(reach)
        for i in range(1, m + 1):  # m > 0: the periods from tick k to k + m
            V[i - first] -= c
        for i in range(m + 1, 1):  # m < 0: from tick k + m to k
            V[i - first] += c
    return V, first


def lag_correction(torque_mean, q, dt: float, coef, reach: int, tau_e, damping,
                   broken=None) -> np.ndarray:  # fmt: skip
    """(N, n) to add to the period impulses [torque x s], as the kink correction is: e_k -
    e_(k-1), e_k = T f(r) sum_i V_i J_i the momentum error the current's lag makes the
    stencil's velocity carry at tick k (module docstring). ``torque_mean`` (N, n): the
    drive's period-mean torque (period k ends at tick k); ``q`` (N, n) the positions;
    ``tau_e``, ``damping`` (n,): L / R [s] and D (:func:`~guardid.conditioning.momentum.
    electrical_damping`); ``broken`` (N,) True where the step into tick k is not one tick
    (no step is taken across it). Zero where the stencil leaves the log, and everywhere
    for joints with tau_e = 0."""
    tau = np.asarray(torque_mean, dtype=float)
    q = np.asarray(q, dtype=float).reshape(tau.shape)
    n = len(tau)
    jump = np.zeros_like(tau)
    if n > 2:
        w = np.zeros_like(q)
        w[1:] = (q[1:] - q[:-1]) / dt  # period mean speeds
        jump[2:] = (tau[2:] - tau[1:-1]) + np.asarray(damping, float) * (w[2:] - w[1:-1])
    if broken is not None:
        bad = np.asarray(broken, dtype=bool).copy()
        bad[1:] |= bad[:-1]  # the step into tick i or into tick i - 1
        jump[bad] = 0.0
    jump *= lag_factor(tau_e, dt)
    V, first = lag_weights(coef, reach)
    return error_steps(jump, V, first, dt)


def error_steps(x, W, first: int, dt: float) -> np.ndarray:
    """(N, n) e_k - e_(k-1), e_k = T sum_i W[i] x[k + first + i] (the stencil's momentum
    error at tick k from a per-period quantity ``x`` (N, n)); zero where the weights leave
    the log."""
    x = np.asarray(x, dtype=float)
    n = len(x)
    e = np.zeros_like(x)
    lo, hi = max(0, -first), n - (first + len(W) - 1)
    for i, w in enumerate(W):
        e[lo:hi] += w * x[lo + first + i : hi + first + i]
    e *= dt
    out = np.zeros_like(e)
    out[1:] = e[1:] - e[:-1]
    return out
