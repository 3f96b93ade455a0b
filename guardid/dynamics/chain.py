"""ChainModel: dynamics of a serial chain described by a ChainDescription.

Parameter vector (p,): per link j (1-based) XXj XYj XZj YYj YZj ZZj MXj MYj MZj Mj
(inertia tensor about the origin of standard-DH frame j [kg m^2], first moments m*c [kg m],
mass [kg]); then per joint with a drive or a mechanical-only rotor Iaj = N^2 J_rotor
[kg m^2]; then per joint with friction Fvj [N m s/rad] Fcj [N m] Foj [N m] (and Fsj [N m],
the Stribeck excess, with the Stribeck model); the Coulomb column is the YAML friction
model's shape (sign, tanh or atan of the velocity).

Rotor j adds Iaj u_j u_j^T to M(q) with u_j = e_j, or, for a coupled rotor (YAML
``rotor.coupling`` = s = +-1: the rotor sits on link j-1 and spins at v . q', v_k = c_k for
the earlier revolute joints, c_k = +-1 the sign of z_k . z_j, and v_j = s N),
u_j = v / N. With parallel axes u_j is constant, so the term has no velocity part.
"""

from __future__ import annotations

from functools import cached_property

import numpy as np

from guardid.dynamics import codegen
from guardid.dynamics.base import BaseParameters, compute_base
from guardid.dynamics.newton_euler import link_physical, rnea
from guardid.robot.description import STANDARD_NAMES, ChainDescription

_BASES: dict = {}
"""compute_base's results by all they depend on (the joints: geometry, drives, rotors,
friction; gravity; the parameter names; the known zeros): a process builds the same few
models again and again (every command, every simulated port)."""


class ChainModel:
    """Rigid-body + drive + friction model of a serial chain (see module docstring)."""

    def __init__(self, description: ChainDescription):
        self.description = description
        self.n_dof = description.n_dof
        self.joint_names = [j.name for j in description.joints]
        n = self.n_dof
        names = [f"{s}{k + 1}" for k in range(n) for s in STANDARD_NAMES]
        values = [v for link in description.links for v in link.standard_parameters()]
        self._ia_index: list[int | None] = [None] * n
        self._ia_vector: list[np.ndarray | None] = [None] * n
        for j, joint in enumerate(description.joints):
            inertia = joint.reflected_inertia
            if inertia is not None:
                self._ia_index[j] = len(names)
                self._ia_vector[j] = _rotor_vector(description, j)
                names.append(f"Ia{j + 1}")
                values.append(inertia)
        self._fric_index: list[int | None] = [None] * n
        for j, joint in enumerate(description.joints):
            if joint.friction is not None:
                self._fric_index[j] = len(names)
                fr = joint.friction
                names += [f"Fv{j + 1}", f"Fc{j + 1}", f"Fo{j + 1}"]
                values += [fr.viscous, fr.coulomb, fr.offset]
                if fr.model == "stribeck":
                    names.append(f"Fs{j + 1}")
                    values.append(fr.stribeck)
        self.param_names = names
        self.params = np.array(values, dtype=float)
        self.known_zero = [
            names.index(f"{s}{k + 1}")
            for k, link in enumerate(description.links)
            for s in link.known_zero
        ]
        self._rigid = codegen.compile_source(
            codegen.vector_regressor_source(description),
            "rigid_regressor",
            codegen.NAMESPACE_VECTOR,
        )
        fast_ns = dict(codegen.NAMESPACE_SCALAR, P0=self.params.tolist())
        src = codegen.fast_sources(description, self._ia_index, self._ia_vector)
        self.mass_matrix_1 = codegen.compile_source(src, "mass_matrix_1", fast_ns)
        self.bias_1 = codegen.compile_source(src, "bias_1", fast_ns)
        """Fast single-sample M(q) (n, n) and bias(q, qd) (n,); params default to true ones."""

    # ------------------------------------------------------------------ regressor
    def regressor(self, q, qd, qdd) -> np.ndarray:
        """Y (N, n, p) with joint torque = Y @ params (incl. rotor inertia and friction)."""
        q, qd, qdd = _states(q, qd, qdd)
        out = np.zeros((q.shape[0], self.n_dof, len(self.param_names)))
        self._rigid(q, qd, qdd, out)
        for j in range(self.n_dof):
            if self._ia_index[j] is not None:
                u = self._ia_vector[j]
                out[:, :, self._ia_index[j]] += np.outer(qdd @ u, u)
            k = self._fric_index[j]
            if k is not None:
                fr = self.description.joints[j].friction
                out[:, j, k] = qd[:, j]
                out[:, j, k + 1] = fr.shape(qd[:, j])
                out[:, j, k + 2] = 1.0
                if fr.model == "stribeck":
                    out[:, j, k + 3] = fr.stribeck_shape(qd[:, j])
        return out

    @cached_property
    def base(self) -> BaseParameters:
        """Base parameters (Gautier's QR; names, formulas, K, B: read-only arrays)."""
        d = self.description
        key = (d.joints, tuple(float(g) for g in d.gravity), tuple(self.param_names),
               tuple(self.known_zero))  # fmt: skip
        try:
            found = _BASES.get(key)
        except TypeError:  # an unhashable joint field: no sharing
            key, found = None, None
        if found is None:
            found = compute_base(self, self.known_zero)
            found.K.flags.writeable = found.B.flags.writeable = False
            if key is not None:
                if len(_BASES) >= 64:
                    _BASES.clear()
                _BASES[key] = found
        return found

    def base_regressor(self, q, qd, qdd) -> np.ndarray:
        """(N, n, b) regressor of the base parameters: tau = base_regressor @ base.values."""
        return self.regressor(q, qd, qdd) @ self.base.B

    def known_torque(self, q, qd, qdd) -> np.ndarray:
        """Torque (N, n) not covered by the parameters (always zero for a chain)."""
        q, _, _ = _states(q, qd, qdd)
        return np.zeros_like(q)

    # ------------------------------------------------------------------ momentum form
    def momentum_regressor(self, q, v) -> np.ndarray:
        """Y_p (N, n, p) with the generalised momentum M(q) v = Y_p @ params [N m s | N s]
        (rigid bodies and rotors; no friction): Y(q, 0, v) - Y(q, 0, 0). Complex ``q`` is
        accepted (the complex step of :meth:`rest_regressor`)."""
        q = np.atleast_2d(q)
        v = np.atleast_2d(np.asarray(v, dtype=float))
        dtype = np.result_type(q.dtype, float)
        zero = np.zeros(q.shape, dtype=float)
        with_v = np.zeros((q.shape[0], self.n_dof, len(self.param_names)), dtype=dtype)
        self._rigid(q, zero, v, with_v)
        still = np.zeros_like(with_v)
        self._rigid(q, zero, zero, still)
        out = with_v - still
        for j in range(self.n_dof):
            if self._ia_index[j] is not None:
                u = self._ia_vector[j]
                out[:, :, self._ia_index[j]] += np.outer(v @ u, u)
        return out

    def rest_regressor(self, q, qd) -> np.ndarray:
        """Y_r (N, n, p): tau = d/dt (Y_p(q, qd) params) + Y_r(q, qd) params, i.e. the
        regressor of -C(q, qd)^T qd + g(q) + friction(qd) = Y(q, qd, 0) - (dM/dt) qd.
        (dM/dt) qd = d/de Y_p(q + e qd, qd) at e = 0 is taken by the complex step (exact to
        rounding: no difference is subtracted)."""
        q, qd, _ = _states(q, qd, qd)
        h = 1e-30
        mdot = self.momentum_regressor(q + 1j * h * qd, qd).imag / h
        return self.regressor(q, qd, np.zeros_like(qd)) - mdot

    def momentum_and_rest_regressors(self, q, qd) -> tuple[np.ndarray, np.ndarray]:
        """(Y_p, Y_r) (N, n, p) of :meth:`momentum_regressor` and :meth:`rest_regressor` at
        the same states in one complex-step evaluation: Y_p is the real part of the momentum
        regressor at q + i h qd (its h^2 terms vanish at h = 1e-30, so it is the real
        evaluation's, to rounding), which :meth:`rest_regressor` forms anyway."""
        q, qd, _ = _states(q, qd, qd)
        h = 1e-30
        stepped = self.momentum_regressor(q + 1j * h * qd, qd)
        rest = self.regressor(q, qd, np.zeros_like(qd))
        rest -= stepped.imag / h
        return np.ascontiguousarray(stepped.real), rest

    def friction_index(self, j: int) -> int | None:
        """Index in ``param_names`` of joint j's first friction column (Fv; then Fc, Fo and
        Fs with the Stribeck model), None without friction."""
        return self._fric_index[j]

    # ------------------------------------------------------------------ dynamics
    def _p(self, params) -> np.ndarray:
        return self.params if params is None else np.asarray(params, dtype=float)

    def inverse_dynamics(self, q, qd, qdd, params=None, friction=True) -> np.ndarray:
        """Joint torques (N, n) by recursive Newton-Euler, plus rotor inertia and friction."""
        q, qd, qdd = _states(q, qd, qdd)
        p = self._p(params)
        tau = rnea(self.description, link_physical(p, self.n_dof), q, qd, qdd)
        return tau + self._drive_terms(p, qd, qdd, friction)

    def _drive_terms(self, p, qd, qdd, friction: bool) -> np.ndarray:
        out = np.zeros_like(qd)
        for j in range(self.n_dof):
            if self._ia_index[j] is not None:
                u = self._ia_vector[j]
                out += p[self._ia_index[j]] * np.outer(qdd @ u, u)
            k = self._fric_index[j]
            if friction and k is not None:
                fr = self.description.joints[j].friction
                out[:, j] += p[k] * qd[:, j] + p[k + 1] * fr.shape(qd[:, j]) + p[k + 2]
                if fr.model == "stribeck":
                    out[:, j] += p[k + 3] * fr.stribeck_shape(qd[:, j])
        return out

    def mass_matrix(self, q, params=None) -> np.ndarray:
        """M(q) (N, n, n) [kg m^2 | kg], including reflected rotor inertia."""
        q = np.atleast_2d(np.asarray(q, dtype=float))
        p = self._p(params)
        links = link_physical(p, self.n_dof)
        zero = np.zeros_like(q)
        cols = []
        for i in range(self.n_dof):
            e = np.zeros_like(q)
            e[:, i] = 1.0
            col = rnea(self.description, links, q, zero, e, gravity=False)
            cols.append(col + self._drive_terms(p, zero, e, friction=False))
        return np.stack(cols, axis=2)

    def bias(self, q, qd, params=None) -> np.ndarray:
        """Coriolis + centrifugal + gravity torques (N, n), no friction."""
        q, qd, _ = _states(q, qd, qd)
        p = self._p(params)
        return rnea(self.description, link_physical(p, self.n_dof), q, qd, np.zeros_like(q))

    def forward_dynamics(self, q, qd, tau, params=None) -> np.ndarray:
        """Joint accelerations qdd = M^-1 (tau - bias) (N, n), no friction."""
        m = self.mass_matrix(q, params)
        rhs = np.atleast_2d(np.asarray(tau, dtype=float)) - self.bias(q, qd, params)
        return np.linalg.solve(m, rhs[..., None])[..., 0]


def _rotor_vector(description: ChainDescription, j: int) -> np.ndarray:
    """u_j (n,): rotor j's inertia term is Iaj u_j u_j^T in M (see the module docstring)."""
    u = np.zeros(description.n_dof)
    u[j] = 1.0
    rotor = description.joints[j].rotor
    if description.joints[j].drive is not None or rotor is None or rotor.coupling == 0:
        return u
    u[j] = float(rotor.coupling)
    sign = 1.0
    for k in range(j - 1, -1, -1):  # z_j = cos(alpha_k) ... cos(alpha_{j-1}) z_k
        sign *= float(np.sign(np.cos(description.joints[k].dh.alpha)))
        if description.joints[k].type == "revolute":
            u[k] = sign / rotor.gear_ratio
    return u


def _states(q, qd, qdd):
    q, qd, qdd = (np.atleast_2d(np.asarray(x, dtype=float)) for x in (q, qd, qdd))
    return q, qd, qdd
