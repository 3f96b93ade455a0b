"""Finite Fourier series excitation (seed 001 eqs. 34-36), starting and ending at rest.

Per joint j, with w_f = 2 pi f [rad/s] and H harmonics l = 1..H:

    q_j(t)   = q0_j + sum_l a_jl/(w_f l) sin(w_f l t) - b_jl/(w_f l) cos(w_f l t)   [rad]
    qd_j(t)  = sum_l a_jl cos(w_f l t) + b_jl sin(w_f l t)                            [rad/s]
    qdd_j(t) = sum_l -a_jl w_f l sin(w_f l t) + b_jl w_f l cos(w_f l t)               [rad/s^2]

(a, b in rad/s.) Rest at t = 0 at the start pose q_s is three linear equalities per joint:
q(0) = q_s fixes q0_j = q_s_j + sum_l b_jl/(w_f l); qd(0) = 0 is sum_l a_jl = 0; qdd(0) = 0
is sum_l l b_jl = 0. :func:`rest_basis` spans the coefficients that satisfy the last two,
so an optimiser works in the 2(H - 1) free dimensions per joint. The series is periodic
with 1/f, so the motion is at rest at the start pose again after every whole period.
"""

from __future__ import annotations

import numpy as np

from guardid.excitation.trajectory import Fields, Trajectory, floats, time_array


class FourierTrajectory(Trajectory):
    """Seed 001 eqs. 34-36; a, b (n, H) [rad/s], q0 (n,) [rad], base_freq f [Hz]."""

    kind = "fourier"

    def __init__(self, base_freq: float, q0, a, b, periods: int = 1, joint_names=None):
        self.base_freq = float(base_freq)
        self.q0 = np.array(q0, dtype=float).reshape(-1)
        self.a = np.atleast_2d(np.array(a, dtype=float))
        self.b = np.atleast_2d(np.array(b, dtype=float))
        if self.a.shape != self.b.shape or self.a.shape[0] != self.q0.size:
            raise ValueError(
                f"shapes differ: q0 {self.q0.shape}, a {self.a.shape}, b {self.b.shape}"
            )
        self.periods = int(periods)
        self.joint_names = list(joint_names) if joint_names is not None else None

    @property
    def harmonics(self) -> int:
        """Number of harmonics H."""
        return self.a.shape[1]

    @property
    def n_joints(self) -> int:
        return self.q0.size

    @property
    def period(self) -> float:
        return 1.0 / self.base_freq

    def _phases(self, t):
        wl = 2 * np.pi * self.base_freq * np.arange(1, self.harmonics + 1)
        phase = np.outer(time_array(t), wl)
        return wl, np.sin(phase), np.cos(phase)

    def positions(self, t) -> np.ndarray:
        wl, s, c = self._phases(t)
        return self.q0 + s @ (self.a / wl).T - c @ (self.b / wl).T

    def velocities(self, t) -> np.ndarray:
        _, s, c = self._phases(t)
        return c @ self.a.T + s @ self.b.T

    def accelerations(self, t) -> np.ndarray:
        wl, s, c = self._phases(t)
        return -s @ (self.a * wl).T + c @ (self.b * wl).T

    @property
    def centre(self) -> np.ndarray:
        """Pose q(0) (n,) [rad] that :meth:`scaled` scales the motion about."""
        return self.positions(0.0)[0]

    def scaled(self, factors) -> FourierTrajectory:
        """Copy with each joint's motion about q(0) scaled by factors (n,) (q(0) kept)."""
        s = np.broadcast_to(np.asarray(factors, dtype=float), self.q0.shape)
        q_s = self.centre
        return FourierTrajectory(
            self.base_freq,
            q_s + s * (self.q0 - q_s),
            self.a * s[:, None],
            self.b * s[:, None],
            self.periods,
            self.joint_names,
        )

    # ---------------------------------------------------------------- free subspace
    @classmethod
    def from_free(cls, z, base_freq: float, harmonics: int, start, **kwargs):
        """Trajectory at rest at ``start`` (n,) [rad] from free coordinates z (n*2(H-1),)."""
        start = np.asarray(start, dtype=float).reshape(-1)
        coef = np.asarray(z, dtype=float).reshape(start.size, -1) @ rest_basis(harmonics).T
        a, b = coef[:, :harmonics], coef[:, harmonics:]
        wl = 2 * np.pi * base_freq * np.arange(1, harmonics + 1)
        q0 = start + (b / wl).sum(axis=1)
        return cls(base_freq, q0, a, b, **kwargs)

    # ---------------------------------------------------------------- YAML
    def to_dict(self) -> dict:
        data = {"kind": self.kind}
        if self.joint_names is not None:
            data["joints"] = list(self.joint_names)
        data.update(
            base_freq=float(self.base_freq),
            harmonics=int(self.harmonics),
            periods=int(self.periods),
            q0=floats(self.q0),
            a=floats(self.a),
            b=floats(self.b),
        )
        return data

    @classmethod
    def from_dict(cls, data: dict, source: str = "<trajectory>") -> FourierTrajectory:
        f = Fields(data, source, ("joints", "base_freq", "harmonics", "periods", "q0", "a", "b"))
        base_freq = f.number("base_freq", positive=True)
        q0 = f.vector("q0")
        n = q0.size
        a = f.rows("a", n)
        h = f.integer("harmonics") if f.has("harmonics") else a[0].size
        a = f.rows("a", n, [h] * n)
        b = f.rows("b", n, [h] * n)
        periods = f.integer("periods", default=1)
        names = f.names(n)
        return cls(base_freq, q0, np.array(a), np.array(b), periods=periods, joint_names=names)


def rest_basis(harmonics: int) -> np.ndarray:
    """Orthonormal basis (2H, 2H-2) of [a_1..a_H, b_1..b_H] with sum a = 0, sum l b_l = 0."""
    h = harmonics
    if h < 2:
        raise ValueError("a Fourier trajectory that starts at rest needs at least 2 harmonics")
    rows = np.zeros((2, 2 * h))
    rows[0, :h] = 1.0
    rows[1, h:] = np.arange(1, h + 1)
    from scipy.linalg import null_space  # here: reading a trajectory does not need scipy

    return null_space(rows)


def design_matrices(t, base_freq: float, harmonics: int):
    """Linear maps (N, 2H) from a joint's [a, b] to q - q_s, qd, qdd at times t (N,) [s].

    q - q_s uses q0 = q_s + sum b/(w l) (rest at t = 0), so it is linear in [a, b] alone.
    """
    wl = 2 * np.pi * base_freq * np.arange(1, harmonics + 1)
    phase = np.outer(time_array(t), wl)
    s, c = np.sin(phase), np.cos(phase)
    dq = np.hstack([s / wl, (1.0 - c) / wl])
    dqd = np.hstack([c, s])
    dqdd = np.hstack([-s * wl, c * wl])
    return dq, dqd, dqdd
