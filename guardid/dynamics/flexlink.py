"""Seed 000's flexible link (eqs. 24-25) with a known hub inertia J_h (DESIGN.md section 4).

State x1 (hub angle) and x2 (flex angle) [rad]; parameters alpha = m l2^2, gamma = m l1 l2
[kg m^2] and k [N m/rad]. Model: M(x2) x'' + h(x, x') = (u, 0) with
M = [[J_h + alpha + gamma cos x2, alpha + gamma/2 cos x2], [alpha + gamma/2 cos x2, alpha]],
h = (-gamma sin x2 (x1' x2' + x2'^2/2), gamma/2 sin x2 x1'^2 + k x2).
The spring is restoring (+k x2); the paper prints -k x2, which diverges (see flexlink.yaml).
Regressor (eq. 25) with the known part moved out: y = (u - J_h x1'', 0) = A theta.
"""

from __future__ import annotations

import math

import numpy as np

from guardid.dynamics.base import BaseParameters
from guardid.robot.description import FlexibleLinkDescription


class FlexibleLinkModel:
    """Flexible-link model behind the common model interface (docs/CONTRACTS.md)."""

    param_names = ["alpha", "gamma", "k"]

    def __init__(self, description: FlexibleLinkDescription):
        self.description = description
        self.n_dof = 2
        self.joint_names = list(description.joint_names)
        self.hub_inertia = description.hub_inertia
        self.params = self.physical_params(
            description.mass, description.l1, description.l2, description.stiffness
        )
        ranges = [description.parameters[k] for k in self.param_names]
        self.nominal = np.array([r.nominal for r in ranges])
        self.bounds = np.array([[r.lo, r.hi] for r in ranges])
        """Admissible (lo, hi) per parameter (p, 2), for the Hopfield scaling."""
        eye = np.eye(3)
        self.base = BaseParameters(tuple(self.param_names), tuple(self.param_names), eye, eye)

    @staticmethod
    def physical_params(mass: float, l1: float, l2: float, stiffness: float) -> np.ndarray:
        """(alpha, gamma, k) = (m l2^2, m l1 l2, k) from physical values."""
        return np.array([mass * l2**2, mass * l1 * l2, stiffness])

    def _p(self, params):
        return self.params if params is None else np.asarray(params, dtype=float)

    def regressor(self, q, qd, qdd) -> np.ndarray:
        """A (N, 2, 3): tau - known_torque = A @ (alpha, gamma, k)."""
        q, qd, qdd = (np.atleast_2d(np.asarray(x, dtype=float)) for x in (q, qd, qdd))
        s, c = np.sin(q[:, 1]), np.cos(q[:, 1])
        v1, v2 = qd[:, 0], qd[:, 1]
        a1, a2 = qdd[:, 0], qdd[:, 1]
        out = np.zeros((q.shape[0], 2, 3))
        out[:, 0, 0] = out[:, 1, 0] = a1 + a2
        out[:, 0, 1] = c * (a1 + 0.5 * a2) - s * (v1 * v2 + 0.5 * v2**2)
        out[:, 1, 1] = 0.5 * (c * a1 + s * v1**2)
        out[:, 1, 2] = q[:, 1]
        return out

    def base_regressor(self, q, qd, qdd) -> np.ndarray:
        """Same as regressor: all three parameters are identifiable."""
        return self.regressor(q, qd, qdd)

    def known_torque(self, q, qd, qdd) -> np.ndarray:
        """Known part (N, 2): (J_h x1'', 0)."""
        qdd = np.atleast_2d(np.asarray(qdd, dtype=float))
        out = np.zeros_like(qdd)
        out[:, 0] = self.hub_inertia * qdd[:, 0]
        return out

    def inverse_dynamics(self, q, qd, qdd, params=None, friction=True) -> np.ndarray:
        """Generalised forces (N, 2) = (u, 0) for a consistent motion; no friction modelled."""
        return self.regressor(q, qd, qdd) @ self._p(params) + self.known_torque(q, qd, qdd)

    def mass_matrix(self, q, params=None) -> np.ndarray:
        """M (N, 2, 2) [kg m^2] including J_h."""
        q = np.atleast_2d(np.asarray(q, dtype=float))
        a, g, _ = self._p(params)
        c = np.cos(q[:, 1])
        m = np.empty((q.shape[0], 2, 2))
        m[:, 0, 0] = self.hub_inertia + a + g * c
        m[:, 0, 1] = m[:, 1, 0] = a + 0.5 * g * c
        m[:, 1, 1] = a
        return m

    def bias(self, q, qd, params=None) -> np.ndarray:
        """Coriolis, centrifugal and spring terms (N, 2) [N m]."""
        q, qd = (np.atleast_2d(np.asarray(x, dtype=float)) for x in (q, qd))
        _, g, k = self._p(params)
        s = np.sin(q[:, 1])
        v1, v2 = qd[:, 0], qd[:, 1]
        return np.stack([-g * s * (v1 * v2 + 0.5 * v2**2), 0.5 * g * s * v1**2 + k * q[:, 1]], 1)

    def forward_dynamics(self, q, qd, tau, params=None) -> np.ndarray:
        """x'' = M^-1 (tau - bias) (N, 2)."""
        rhs = np.atleast_2d(np.asarray(tau, dtype=float)) - self.bias(q, qd, params)
        return np.linalg.solve(self.mass_matrix(q, params), rhs[..., None])[..., 0]

    def mass_matrix_1(self, q, params=None) -> np.ndarray:
        """Single-sample M (2, 2)."""
        a, g, _ = self.params if params is None else params
        c = math.cos(q[1])
        m12 = a + 0.5 * g * c
        return np.array([[self.hub_inertia + a + g * c, m12], [m12, a]])

    def bias_1(self, q, qd, params=None) -> np.ndarray:
        """Single-sample bias (2,)."""
        _, g, k = self.params if params is None else params
        s = math.sin(q[1])
        v1, v2 = qd[0], qd[1]
        return np.array([-g * s * (v1 * v2 + 0.5 * v2 * v2), 0.5 * g * s * v1 * v1 + k * q[1]])
