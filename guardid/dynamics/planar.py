"""Seed 001's planar two-link arm in the paper's five parameters (DESIGN.md section 4).

Vertical plane, angles from the horizontal, g = 9.81 m/s^2:
tau1 = th1 q1'' + th2 [cos q2 (2 q1'' + q2'') - sin q2 (q2'^2 + 2 q1' q2')] + th3 (q1'' + q2'')
       + th4 g cos q1 + th5 g cos(q1 + q2)
tau2 = th2 [cos q2 q1'' + sin q2 q1'^2] + th3 (q1'' + q2'') + th5 g cos(q1 + q2)
th1 = m1 lc1^2 + m2 l1^2 + I1, th2 = m2 l1 lc2, th3 = m2 lc2^2 + I2, th4 = m1 lc1 + m2 l1,
th5 = m2 lc2 (kg m^2, kg m^2, kg m^2, kg m, kg m). The five are not independent given
l1 (th2 = l1 th5), which is why a chain model finds four base parameters.
"""

from __future__ import annotations

import math

import numpy as np

from guardid.dynamics.base import BaseParameters

TABLE1 = np.array([1.5, 0.5, 0.25, 1.5, 1.0])
"""True values of seed 001's Table 1."""


class PlanarPaperModel:
    """Closed-form 5-parameter planar arm (the paper's model), common model interface."""

    param_names = ["th1", "th2", "th3", "th4", "th5"]

    def __init__(self, params=TABLE1, g: float = 9.81, joint_names=("shoulder", "elbow")):
        self.params = np.asarray(params, dtype=float).copy()
        self.g = float(g)
        self.n_dof = 2
        self.joint_names = list(joint_names)
        eye = np.eye(5)
        self.base = BaseParameters(tuple(self.param_names), tuple(self.param_names), eye, eye)

    @classmethod
    def from_description(cls, description) -> PlanarPaperModel:
        """th from a planar2-style ChainDescription (x axes along the links, rotation about z)."""
        (j1, j2), (k1, k2) = description.joints, description.links
        l1 = j1.dh.a
        lc1, lc2 = k1.com[0] + l1, k2.com[0] + j2.dh.a
        m1, m2 = k1.mass, k2.mass
        i1, i2 = k1.inertia[2, 2], k2.inertia[2, 2]
        th = [
            m1 * lc1**2 + m2 * l1**2 + i1,
            m2 * l1 * lc2,
            m2 * lc2**2 + i2,
            m1 * lc1 + m2 * l1,
            m2 * lc2,
        ]
        g = float(np.linalg.norm(description.gravity))
        return cls(th, g, [j.name for j in description.joints])

    def _p(self, params):
        return self.params if params is None else np.asarray(params, dtype=float)

    def regressor(self, q, qd, qdd) -> np.ndarray:
        """A (N, 2, 5) with tau = A @ th."""
        q, qd, qdd = (np.atleast_2d(np.asarray(x, dtype=float)) for x in (q, qd, qdd))
        c2, s2 = np.cos(q[:, 1]), np.sin(q[:, 1])
        g1, g12 = self.g * np.cos(q[:, 0]), self.g * np.cos(q[:, 0] + q[:, 1])
        v1, v2, a1, a2 = qd[:, 0], qd[:, 1], qdd[:, 0], qdd[:, 1]
        out = np.zeros((q.shape[0], 2, 5))
        out[:, 0, 0] = a1
        out[:, 0, 1] = c2 * (2 * a1 + a2) - s2 * (v2**2 + 2 * v1 * v2)
        out[:, 0, 2] = out[:, 1, 2] = a1 + a2
        out[:, 0, 3] = g1
        out[:, 0, 4] = out[:, 1, 4] = g12
        out[:, 1, 1] = c2 * a1 + s2 * v1**2
        return out

    base_regressor = regressor

    def known_torque(self, q, qd, qdd) -> np.ndarray:
        """Zero (N, 2): everything is in the parameters."""
        return np.zeros_like(np.atleast_2d(np.asarray(q, dtype=float)))

    def inverse_dynamics(self, q, qd, qdd, params=None, friction=True) -> np.ndarray:
        """Joint torques (N, 2) [N m]."""
        return self.regressor(q, qd, qdd) @ self._p(params)

    def mass_matrix(self, q, params=None) -> np.ndarray:
        """M (N, 2, 2) [kg m^2]."""
        q = np.atleast_2d(np.asarray(q, dtype=float))
        th1, th2, th3, _, _ = self._p(params)
        c2 = np.cos(q[:, 1])
        m = np.empty((q.shape[0], 2, 2))
        m[:, 0, 0] = th1 + 2 * th2 * c2 + th3
        m[:, 0, 1] = m[:, 1, 0] = th2 * c2 + th3
        m[:, 1, 1] = th3
        return m

    def bias(self, q, qd, params=None) -> np.ndarray:
        """Coriolis, centrifugal and gravity torques (N, 2) [N m]."""
        q = np.atleast_2d(np.asarray(q, dtype=float))
        return self.inverse_dynamics(q, qd, np.zeros_like(q), params)

    def forward_dynamics(self, q, qd, tau, params=None) -> np.ndarray:
        """q'' = M^-1 (tau - bias) (N, 2)."""
        rhs = np.atleast_2d(np.asarray(tau, dtype=float)) - self.bias(q, qd, params)
        return np.linalg.solve(self.mass_matrix(q, params), rhs[..., None])[..., 0]

    def mass_matrix_1(self, q, params=None) -> np.ndarray:
        """Single-sample M (2, 2)."""
        th1, th2, th3, _, _ = self.params if params is None else params
        c2 = math.cos(q[1])
        m12 = th2 * c2 + th3
        return np.array([[th1 + 2 * th2 * c2 + th3, m12], [m12, th3]])

    def bias_1(self, q, qd, params=None) -> np.ndarray:
        """Single-sample bias (2,)."""
        _, th2, _, th4, th5 = self.params if params is None else params
        s2 = math.sin(q[1])
        g12 = self.g * math.cos(q[0] + q[1])
        v1, v2 = qd[0], qd[1]
        return np.array(
            [
                -th2 * s2 * (v2 * v2 + 2 * v1 * v2) + th4 * self.g * math.cos(q[0]) + th5 * g12,
                th2 * s2 * v1 * v1 + th5 * g12,
            ]
        )
