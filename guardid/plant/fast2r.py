"""Specialised evaluator for two-revolute-joint chains, fitted to the generic model.

For a chain of two revolute joints the first axis is fixed in the (inertial) base, so
M depends on q2 only and every entry is a trigonometric polynomial of degree 2 in q2
(span {1, cos q2, sin q2, cos^2 q2, sin q2 cos q2}); the gravity torque lies in the span
of products of {1, cos, sin} of q1 and q2 (9 functions). Coriolis/centrifugal terms follow
from D = dM/dq2 exactly: c1 = (D11 qd1 + D12 qd2) qd2, c2 = (D22 qd2^2 - D11 qd1^2) / 2.

The coefficients are fitted by least squares to the generic model's ``mass_matrix`` and
``bias`` for one parameter vector and then checked at random states; if the check fails
(e.g. a prismatic joint) :func:`fit_two_revolute` returns None and the caller uses the
generic ``mass_matrix_1``/``bias_1``.
"""

from __future__ import annotations

import math

import numpy as np

_TOL = 1e-9


def _m_basis(q2: np.ndarray) -> np.ndarray:
    c, s = np.cos(q2), np.sin(q2)
    return np.stack([np.ones_like(c), c, s, c * c, s * c], axis=-1)


def _g_basis(q: np.ndarray) -> np.ndarray:
    c1, s1, c2, s2 = np.cos(q[:, 0]), np.sin(q[:, 0]), np.cos(q[:, 1]), np.sin(q[:, 1])
    one = np.ones_like(c1)
    return np.stack([one, c1, s1, c2, s2, c1 * c2, c1 * s2, s1 * c2, s1 * s2], axis=-1)


def fit_two_revolute(model, params, seed: int = 12345):
    """``dyn(q1, q2, qd1, qd2) -> (m11, m12, m22, b1, b2)`` in plain floats, or None.

    Units: M [kg m^2], b [N m]; verified against ``model`` to 1e-9 relative.
    """
    if model.n_dof != 2:
        return None
    rng = np.random.default_rng(seed)
    q = rng.uniform(-math.pi, math.pi, (40, 2))
    mm = model.mass_matrix(q, params)
    a = _m_basis(q[:, 1])
    cm = [np.linalg.lstsq(a, mm[:, r, c], rcond=None)[0] for r, c in ((0, 0), (0, 1), (1, 1))]
    g = model.bias(q, np.zeros_like(q), params)
    ag = _g_basis(q)
    cg = [np.linalg.lstsq(ag, g[:, j], rcond=None)[0] for j in range(2)]
    dyn = _make(cm, cg)
    qt = rng.uniform(-math.pi, math.pi, (20, 2))
    qdt = rng.uniform(-2.0, 2.0, (20, 2))
    m_ref, b_ref = model.mass_matrix(qt, params), model.bias(qt, qdt, params)
    scale = max(1.0, float(np.abs(m_ref).max()), float(np.abs(b_ref).max()))
    for k in range(len(qt)):
        m11, m12, m22, b1, b2 = dyn(*qt[k].tolist(), *qdt[k].tolist())
        err = np.abs(np.array([m11, m12, m22, b1, b2]) - [*m_ref[k][np.triu_indices(2)], *b_ref[k]])
        if err.max() > _TOL * scale:
            return None
    return dyn


# The terms both evaluators share, written once: M(q2) and D = dM/dq2 from the fitted
# coefficients, and the gravity torque. ``_FACTORY`` turns them into two closures over the
# coefficients (closure variables, as if written by hand, so the evaluators stay as fast).
_TERMS = """\
c = cos(q2)
s = sin(q2)
cc = c * c
sc = s * c
# derivatives wrt q2: d(c) = -s, d(s) = c, d(cc) = -2 sc, d(sc) = cc - s s
d_c = -s
d_cc = -2.0 * sc
d_sc = cc - s * s
m11 = a0 + a1 * c + a2 * s + a3 * cc + a4 * sc
m12 = b0 + b1 * c + b2 * s + b3 * cc + b4 * sc
m22 = c0 + c1 * c + c2 * s + c3 * cc + c4 * sc
d11 = a1 * d_c + a2 * c + a3 * d_cc + a4 * d_sc
d12 = b1 * d_c + b2 * c + b3 * d_cc + b4 * d_sc
d22 = c1 * d_c + c2 * c + c3 * d_cc + c4 * d_sc
k1 = cos(q1)
s1 = sin(q1)
kc = k1 * c
ks = k1 * s
sc1 = s1 * c
ss = s1 * s
gr1 = g10 + g11 * k1 + g12 * s1 + g13 * c + g14 * s + g15 * kc + g16 * ks + g17 * sc1
gr1 += g18 * ss
gr2 = g20 + g21 * k1 + g22 * s1 + g23 * c + g24 * s + g25 * kc + g26 * ks + g27 * sc1
gr2 += g28 * ss
"""
_COEFFICIENTS = (
    "a0, a1, a2, a3, a4, b0, b1, b2, b3, b4, c0, c1, c2, c3, c4, "
    "g10, g11, g12, g13, g14, g15, g16, g17, g18, g20, g21, g22, g23, g24, g25, g26, g27, g28"
)


def _indented(text: str, spaces: int) -> str:
    return "".join(" " * spaces + line + "\n" for line in text.splitlines())


_SOURCE = f"""\
def factory({_COEFFICIENTS}, cos, sin):
    def dyn(q1, q2, qd1, qd2):
{_indented(_TERMS, 8)}\
        b1_ = (d11 * qd1 + d12 * qd2) * qd2 + gr1
        b2_ = 0.5 * (d22 * qd2 * qd2 - d11 * qd1 * qd1) + gr2
        return m11, m12, m22, b1_, b2_

    def free_accel(e1, e2, c11, c12, ia1, ia2):
        def acc(q1, q2, qd1, qd2):
{_indented(_TERMS, 12)}\
            r1 = e1 - c11 * qd1 - ((d11 * qd1 + d12 * qd2) * qd2 + gr1)
            r2 = e2 - c12 * qd2 - (0.5 * (d22 * qd2 * qd2 - d11 * qd1 * qd1) + gr2)
            m11 -= ia1
            m22 -= ia2
            det = m11 * m22 - m12 * m12
            return (r1 * m22 - r2 * m12) / det, (r2 * m11 - r1 * m12) / det

        return acc

    def mass(q2):  # (m11, m12, m22) [kg m^2]: the first three of dyn (same expressions)
        c, s = cos(q2), sin(q2)
        cc, sc = c * c, s * c
        m11 = a0 + a1 * c + a2 * s + a3 * cc + a4 * sc
        m12 = b0 + b1 * c + b2 * s + b3 * cc + b4 * sc
        m22 = c0 + c1 * c + c2 * s + c3 * cc + c4 * sc
        return m11, m12, m22

    return dyn, free_accel, mass
"""
_NAMESPACE: dict = {}
exec(compile(_SOURCE, "<guardid fast2r evaluators>", "exec"), _NAMESPACE)  # noqa: S102
_FACTORY = _NAMESPACE["factory"]


def _make(cm, cg):
    """``dyn(q1, q2, qd1, qd2) -> (m11, m12, m22, b1, b2)`` for the fitted coefficients.

    ``dyn.mass(q2)`` -> (m11, m12, m22) [kg m^2]. ``dyn.free_accel(e1, e2, c11, c12, ia1,
    ia2)`` -> ``acc(q1, q2, qd1, qd2) -> (qdd1, qdd2)`` [rad/s^2] with both joints moving:
    (M - diag(ia)) qdd = (e1 - c11 qd1, e2 - c12 qd2) - b solved by Cramer's rule, dyn's
    terms inlined (one call per RK4 stage instead of two; same operations, same results).
    e [N m], c [N m s/rad], ia [kg m^2]."""
    coefficients = [x for row in cm for x in row.tolist()]
    coefficients += [x for row in cg for x in row.tolist()]
    dyn, free_accel, mass = _FACTORY(*coefficients, math.cos, math.sin)
    dyn.mass = mass
    dyn.free_accel = free_accel
    return dyn


def generic_two(model, params):
    """``dyn`` with the same signature built on the model's mass_matrix_1 / bias_1."""
    mm1, bb1 = model.mass_matrix_1, model.bias_1
    p = [float(x) for x in params]

    def dyn(q1, q2, qd1, qd2):
        (m11, m12), (_, m22) = mm1([q1, q2], p).tolist()
        b1, b2 = bb1([q1, q2], [qd1, qd2], p).tolist()
        return m11, m12, m22, b1, b2

    return dyn
