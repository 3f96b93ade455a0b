"""Synthetic logs of the DFKI double pendulum from its closed-form model (independent of
guardid.dynamics): sums of sines in a frequency band, encoder quantisation, torque noise."""

from __future__ import annotations

import numpy as np

# the lab's published values (tests/data/dfki-double-pendulum/README.md), friction with a
# smooth Coulomb term cf tanh(qd / 0.01 rad/s) as in guardid's dfki_double_pendulum.yaml
P = {
    "m1": 0.5593806151425046, "m2": 0.6043459469186889, "r1": 0.3, "r2": 0.18377686083653508,
    "I1": 0.053470810264216295, "I2": 0.02392374528789766, "Ir": 7.659297952841183e-05,
    "g": 9.81, "gr": 6.0, "l1": 0.3, "b1": 0.05, "b2": 0.02, "cf1": 0.093, "cf2": 0.078,
}  # fmt: skip
V_SCALE = 0.05  # rad/s
QUANTUM = 2 * np.pi / 2**15  # rad, a 15-bit absolute encoder
TORQUE_NOISE = 0.005  # N m (1-sigma; 0.1-0.5 % of the torque)


def truth() -> dict:
    """Base parameters of guardid's dfki_double_pendulum robot for :data:`P`."""
    p = P
    ia = p["gr"] ** 2 * p["Ir"]
    return {
        "ZZ1R": p["I1"] + p["m2"] * p["l1"] ** 2 + ia,
        "MX1R": p["m1"] * p["r1"] + p["m2"] * p["l1"],
        "ZZ2R": p["I2"],
        "MX2R": p["m2"] * p["r2"],
        "Ia2": ia,
        "Fv1": p["b1"], "Fc1": p["cf1"], "Fv2": p["b2"], "Fc2": p["cf2"],
    }  # fmt: skip


NAMES = ("ZZ1R", "MX1R", "ZZ2R", "MX2R", "Ia2", "Fv1", "Fc1", "Fv2", "Fc2")
"""The base parameters of :func:`truth` in guardid's order."""


def regressor(q, qd, qdd) -> np.ndarray:
    """(N, 2, 9) with torque(q, qd, qdd) = regressor @ [truth()[n] for n in NAMES] [N m],
    worked out by hand from :func:`torque` (the rotor's Ir = Ia2 / gr^2 terms included)."""
    l1, g, gr = P["l1"], P["g"], P["gr"]
    c2, s2 = np.cos(q[:, 1]), np.sin(q[:, 1])
    a1, a2, v1, v2 = qdd[:, 0], qdd[:, 1], qd[:, 0], qd[:, 1]
    grav12 = g * np.sin(q[:, 0] + q[:, 1])
    Y = np.zeros((len(q), 2, 9))
    Y[:, 0, 0] = a1
    Y[:, 0, 1] = g * np.sin(q[:, 0])
    Y[:, :, 2] = (a1 + a2)[:, None]
    Y[:, 0, 3] = l1 * (c2 * (2 * a1 + a2) - s2 * (2 * v1 * v2 + v2**2)) + grav12
    Y[:, 1, 3] = l1 * (c2 * a1 + s2 * v1**2) + grav12
    Y[:, 0, 4] = a1 / gr**2 - a2 / gr
    Y[:, 1, 4] = a2 - a1 / gr
    Y[:, 0, 5], Y[:, 0, 6] = v1, np.tanh(v1 / V_SCALE)
    Y[:, 1, 7], Y[:, 1, 8] = v2, np.tanh(v2 / V_SCALE)
    return Y


def torque(q, qd, qdd) -> np.ndarray:
    """The lab's closed-form inverse dynamics (N, 2) [N m] with tanh Coulomb friction."""
    p = P
    m2, l1, r2, g, gr, ir = p["m2"], p["l1"], p["r2"], p["g"], p["gr"], p["Ir"]
    c2, s2 = np.cos(q[:, 1]), np.sin(q[:, 1])
    m11 = p["I1"] + p["I2"] + m2 * l1**2 + 2 * m2 * l1 * r2 * c2 + (gr**2 + 1) * ir
    m12 = p["I2"] + m2 * l1 * r2 * c2 - gr * ir
    m22 = p["I2"] + gr**2 * ir
    h1 = -m2 * l1 * r2 * s2 * (2 * qd[:, 0] * qd[:, 1] + qd[:, 1] ** 2)
    h2 = m2 * l1 * r2 * s2 * qd[:, 0] ** 2
    g12 = m2 * r2 * g * np.sin(q[:, 0] + q[:, 1])
    g1 = (p["m1"] * p["r1"] + m2 * l1) * g * np.sin(q[:, 0]) + g12
    f1 = p["b1"] * qd[:, 0] + p["cf1"] * np.tanh(qd[:, 0] / V_SCALE)
    f2 = p["b2"] * qd[:, 1] + p["cf2"] * np.tanh(qd[:, 1] / V_SCALE)
    t1 = m11 * qdd[:, 0] + m12 * qdd[:, 1] + h1 + g1 + f1
    t2 = m12 * qdd[:, 0] + m22 * qdd[:, 1] + h2 + g12 + f2
    return np.column_stack([t1, t2])


def motion(t, f_lo, f_hi, seed, n_sines=6, acc=30.0, max_amp=0.8):
    """Sums of ``n_sines`` sines per joint, log-spaced in [f_lo, f_hi] Hz, each with
    acceleration amplitude ``acc`` [rad/s^2] (position amplitude capped at ``max_amp`` rad),
    random phases: (q, qd, qdd) exact, each (N, 2)."""
    rng = np.random.default_rng(seed)
    q = np.zeros((len(t), 2))
    qd, qdd = np.zeros_like(q), np.zeros_like(q)
    for j in range(2):
        freqs = np.geomspace(f_lo, f_hi, n_sines) * (1.0 + 0.07 * j)
        for f in freqs:
            w = 2 * np.pi * f
            a = min(acc / w**2, max_amp / n_sines)
            ph = rng.uniform(0, 2 * np.pi)
            q[:, j] += a * np.sin(w * t + ph)
            qd[:, j] += a * w * np.cos(w * t + ph)
            qdd[:, j] -= a * w**2 * np.sin(w * t + ph)
    return q, qd, qdd


def log(fs_hz, f_lo, f_hi, seed, duration_s=None):
    """(t [s], measured q [rad] (quantised), measured torque [N m] (noisy))."""
    duration_s = duration_s or max(20.0, 4.0 / f_lo)
    t = np.arange(0.0, duration_s, 1.0 / fs_hz)
    q, qd, qdd = motion(t, f_lo, f_hi, seed)
    rng = np.random.default_rng(seed + 1000)
    tau = torque(q, qd, qdd) + rng.normal(0.0, TORQUE_NOISE, (len(t), 2))
    return t, np.round(q / QUANTUM) * QUANTUM, tau
