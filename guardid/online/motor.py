"""The motor equation as a low-noise current sensor for online identification.

Over one sample period T the period-mean motor current of a DC motor is

    i = (V - Ke N (q_k - q_k-1) / T) / R

(V the period-mean voltage [V], N the gear ratio, q the joint angle [rad]; the inductance
adds - L/R di/dt, a 0.25 ms lead on the guard robot, negligible). On the guard robot's
sensors this is far less noisy in the identification band than the current sensor: 13 mV
of voltage noise is 1.6 mA at R = 8 ohm against the current sensor's 8 mA, and the encoder
quantisation enters as a difference, whose noise sits at high frequency where the
conditioning low-pass removes it. R and Ke are not taken on trust: :class:`MotorCurrent`
fits a = 1/R and c = Ke N / R per joint by recursive least squares to the measured current
(i = a V - c dq/T, a long memory, the YAML values as the prior), so the scale stays that of
the current sensor and follows a slow drift of R (winding temperature).
"""

from __future__ import annotations

import numpy as np

MEMORY_S = 600.0
"""Memory of the a, c fit [s] (forgetting 1 - T / MEMORY_S per row)."""
PRIOR_REL = 3.0
"""Prior standard deviation of a and c, relative to the YAML values (a rough guide: V and
Ke N dq/T nearly cancel, so a tight prior would bias a and c along that direction) [-]."""

REPLAY_CHUNK = 65536
"""Rows :meth:`MotorCurrent.replay` runs at a time (peak memory of long logs)."""


class MotorCurrent:
    """Period-mean motor currents [A] from voltages and encoder angles (module docstring).

    ``description``: the robot; every joint needs a drive. Attributes: ``a_`` (n,) 1/R
    [1/ohm], ``c_`` (n,) Ke N / R [A s/rad].
    """

    def __init__(self, description):
        drives = [j.drive for j in description.joints]
        if any(d is None for d in drives):
            raise ValueError("the motor-equation current needs a drive on every joint")
        self.dt = float(description.sample_period)
        a = np.array([1.0 / d.resistance for d in drives])
        c = np.array([d.ke * d.gear_ratio / d.resistance for d in drives])
        self._theta = np.stack([a, c], axis=1)  # (n, 2)
        prior = (PRIOR_REL * self._theta) ** 2
        self._P = np.zeros((len(drives), 2, 2))
        self._P[:, 0, 0], self._P[:, 1, 1] = prior[:, 0], prior[:, 1]
        self.lam = 1.0 - self.dt / MEMORY_S
        self._q_prev = None

    @property
    def a_(self) -> np.ndarray:
        return self._theta[:, 0].copy()

    @property
    def c_(self) -> np.ndarray:
        return self._theta[:, 1].copy()

    def reset(self) -> None:
        """After a gap: no previous angle (the fit is kept)."""
        self._q_prev = None

    def update(self, volts, q_rad, current_a) -> np.ndarray:
        """One row: voltages (n,) [V], angles (n,) [rad], measured currents (n,) [A].

        Returns the motor-equation currents (n,) [A] (the measured ones on the first row
        after a start or gap, which has no previous angle)."""
        v = np.asarray(volts, dtype=float)
        q = np.asarray(q_rad, dtype=float)
        cur = np.asarray(current_a, dtype=float)
        q_prev, self._q_prev = self._q_prev, q
        if q_prev is None:
            return cur
        phi = np.stack([v, -(q - q_prev) / self.dt], axis=1)  # (n, 2)
        P, th = self._P, self._theta
        Pphi = np.einsum("nij,nj->ni", P, phi)
        denom = self.lam + np.einsum("ni,ni->n", phi, Pphi)
        gain = Pphi / denom[:, None]
        th += gain * (cur - np.einsum("ni,ni->n", phi, th))[:, None]
        P -= gain[:, :, None] * Pphi[:, None, :]
        P /= self.lam
        return np.einsum("ni,ni->n", phi, th)

    def replay(self, volts, q_rad, current_a, first) -> np.ndarray:
        """Many rows at once: voltages, angles, measured currents (N, n) and ``first`` (N,)
        bool, True on a row after a start or gap (no previous angle: its measured current is
        returned and the fit is not updated). Returns the motor-equation currents (N, n) [A],
        the values :meth:`update` gives row by row (to round-off), and leaves the fit where
        the last row left it.

        The same recursion in its information form, R_k = lam R_k-1 + phi phi^T and
        b_k = lam b_k-1 + phi i_k with theta_k = R_k^-1 b_k (R_0 = P_0^-1, b_0 = R_0
        theta_0), which is linear in R and b: one ``lfilter`` per entry over the rows."""
        from scipy.signal import lfilter

        v = np.asarray(volts, dtype=float)
        q = np.asarray(q_rad, dtype=float)
        out = np.array(current_a, dtype=float)
        first = np.asarray(first, dtype=bool).copy()
        if self._q_prev is not None or len(q) == 0:
            raise ValueError("replay needs a fresh MotorCurrent (no previous angle)")
        first[0] = True
        upd = np.flatnonzero(~first)
        if upd.size == 0:
            return out
        lam = self.lam
        R0 = np.linalg.inv(self._P)  # (n, 2, 2)
        b0 = np.einsum("nij,nj->ni", R0, self._theta)
        # the five running sums' filter states, s_k = lam s_k-1 + x_k from s_0 = init
        state = [(lam * x)[None, :] for x in (R0[:, 0, 0], R0[:, 0, 1], R0[:, 1, 1], b0[:, 0],
                                              b0[:, 1])]  # fmt: skip

        def run(x, which):  # per joint column, the state carried from the previous chunk
            y, state[which] = lfilter([1.0], [1.0, -lam], x, axis=0, zi=state[which])
            return y

        for c0 in range(0, len(upd), REPLAY_CHUNK):  # bounded memory, the same numbers
            u = upd[c0 : c0 + REPLAY_CHUNK]
            phi_v = v[u]
            phi_w = -(q[u] - q[u - 1]) / self.dt
            cur = out[u]
            r00 = run(phi_v * phi_v, 0)
            r01 = run(phi_v * phi_w, 1)
            r11 = run(phi_w * phi_w, 2)
            b0_ = run(phi_v * cur, 3)
            b1_ = run(phi_w * cur, 4)
            det = r00 * r11 - r01 * r01
            a = (r11 * b0_ - r01 * b1_) / det
            c = (r00 * b1_ - r01 * b0_) / det
            out[u] = phi_v * a + phi_w * c
        self._theta = np.stack([a[-1], c[-1]], axis=1)
        R = np.stack([np.stack([r00[-1], r01[-1]], -1), np.stack([r01[-1], r11[-1]], -1)], -2)
        self._P = np.linalg.inv(R)
        self._q_prev = q[-1]
        return out
