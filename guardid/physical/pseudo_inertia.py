"""Pseudo-inertia of one link and its log-Cholesky parameterisation (SI units).

A link's ten standard parameters phi = (XX XY XZ YY YZ ZZ [kg m^2] about the link frame's
origin, MX MY MZ [kg m], M [kg]) are physically consistent (a positive mass distribution:
mass > 0, inertia about the COM positive definite with the triangle inequalities) exactly
when the 4x4 pseudo-inertia

    J = [[Sigma, h], [h^T, m]],  Sigma = tr(I)/2 * eye(3) - I,  h = (MX, MY, MZ)

is positive definite (Wensing, Kim, Slotine 2018). Every J > 0 is U U^T for one upper
triangular U with a positive diagonal; writing

    U = exp(a) [[exp(d1), s12, s13, t1], [0, exp(d2), s23, t2], [0, 0, exp(d3), t3], [0, 0, 0, 1]]

the ten unconstrained numbers x = (a, d1, d2, d3, s12, s23, s13, t1, t2, t3) cover exactly
the consistent links (log-Cholesky, Rucker and Wensing 2022): any x gives one.
"""

from __future__ import annotations

import numpy as np


def pseudo_inertia(phi: np.ndarray) -> np.ndarray:
    """J (4, 4) [kg m^2, kg m, kg] of one link's standard parameters phi (10,)."""
    xx, xy, xz, yy, yz, zz, mx, my, mz, m = np.asarray(phi, dtype=float)
    inertia = np.array([[xx, xy, xz], [xy, yy, yz], [xz, yz, zz]])
    sigma = 0.5 * np.trace(inertia) * np.eye(3) - inertia
    out = np.empty((4, 4))
    out[:3, :3] = sigma
    out[:3, 3] = out[3, :3] = (mx, my, mz)
    out[3, 3] = m
    return out


def standard_from_pseudo(j: np.ndarray) -> np.ndarray:
    """Standard parameters phi (10,) of a pseudo-inertia J (4, 4) (inverse of pseudo_inertia)."""
    sigma = j[:3, :3]
    inertia = np.trace(sigma) * np.eye(3) - sigma
    return np.array(
        [
            inertia[0, 0],
            inertia[0, 1],
            inertia[0, 2],
            inertia[1, 1],
            inertia[1, 2],
            inertia[2, 2],
            *j[:3, 3],
            j[3, 3],
        ]
    )


_EXP_LIMIT = 300.0
"""Exponents are clipped to +-this so that a wild trial step cannot overflow [-]."""


def _u_matrix(x: np.ndarray) -> np.ndarray:
    a, d1, d2, d3, s12, s23, s13, t1, t2, t3 = np.clip(x, -_EXP_LIMIT, _EXP_LIMIT)
    return np.exp(a) * np.array(
        [
            [np.exp(d1), s12, s13, t1],
            [0.0, np.exp(d2), s23, t2],
            [0.0, 0.0, np.exp(d3), t3],
            [0.0, 0.0, 0.0, 1.0],
        ]
    )


_ENTRY = ((None,), (0, 0), (1, 1), (2, 2), (0, 1), (1, 2), (0, 2), (0, 3), (1, 3), (2, 3))
"""Entry of U that each log-Cholesky coordinate sets (a scales all of U)."""


def standard_from_log_cholesky(x: np.ndarray) -> np.ndarray:
    """phi (10,) of the log-Cholesky coordinates x (10,) (module docstring); always consistent."""
    u = _u_matrix(np.asarray(x, dtype=float))
    return standard_from_pseudo(u @ u.T)


def standard_jacobian(x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(phi (10,), d phi / d x (10, 10)) at the log-Cholesky coordinates x (10,)."""
    x = np.asarray(x, dtype=float)
    u = _u_matrix(x)
    du = np.zeros((10, 4, 4))
    du[0] = u  # d/da scales all of U
    scale = np.exp(np.clip(x[0], -_EXP_LIMIT, _EXP_LIMIT))
    for i, (r, c) in enumerate(_ENTRY[1:], start=1):
        du[i, r, c] = u[r, c] if i <= 3 else scale
    dj = du @ u.T
    dj = dj + np.swapaxes(dj, 1, 2)
    tr = np.trace(dj[:, :3, :3], axis1=1, axis2=2)
    inertia = tr[:, None, None] * np.eye(3) - dj[:, :3, :3]
    jac = np.column_stack(
        [inertia[:, 0, 0], inertia[:, 0, 1], inertia[:, 0, 2], inertia[:, 1, 1],
         inertia[:, 1, 2], inertia[:, 2, 2], dj[:, 0, 3], dj[:, 1, 3], dj[:, 2, 3], dj[:, 3, 3]]
    ).T  # fmt: skip
    return standard_from_pseudo(u @ u.T), jac


def log_cholesky_from_standard(phi: np.ndarray, floor: float = 1e-9) -> np.ndarray:
    """x (10,) with standard_from_log_cholesky(x) == phi for a consistent link.

    A link on the boundary (J only semi-definite, e.g. a point mass or a thin rod) is moved
    inside by adding ``floor`` x (largest eigenvalue of J) to J's diagonal first.
    """
    j = pseudo_inertia(phi)
    scale = float(np.max(np.abs(np.linalg.eigvalsh(j))))
    if np.linalg.eigvalsh(j)[0] <= floor * scale:
        j = j + floor * scale * np.eye(4)
    flip = np.eye(4)[::-1]
    u = flip @ np.linalg.cholesky(flip @ j @ flip) @ flip  # upper triangular, j = u u^T
    e_a = u[3, 3]
    u = u / e_a
    return np.array(
        [
            np.log(e_a),
            np.log(u[0, 0]),
            np.log(u[1, 1]),
            np.log(u[2, 2]),
            u[0, 1],
            u[1, 2],
            u[0, 2],
            u[0, 3],
            u[1, 3],
            u[2, 3],
        ]
    )


def consistency_margin(phi: np.ndarray) -> float:
    """Smallest eigenvalue of J divided by its largest (> 0: consistent; dimensionless)."""
    ev = np.linalg.eigvalsh(pseudo_inertia(phi))
    return float(ev[0] / max(abs(ev[-1]), 1e-300))


def link_violations(phi: np.ndarray, tol: float = 1e-12) -> list[str]:
    """What is physically wrong with one link's phi (10,): [] when consistent.

    Checks (each relative to the link's own scale ``tol``): mass > 0, inertia about the COM
    positive definite, its principal moments obeying the triangle inequality.
    """
    out = []
    m = float(phi[9])
    if m <= 0.0:
        return [f"mass {m:.4g} kg <= 0"]
    c = np.asarray(phi[6:9]) / m
    xx, xy, xz, yy, yz, zz = phi[:6]
    i_o = np.array([[xx, xy, xz], [xy, yy, yz], [xz, yz, zz]])
    i_c = i_o - m * (np.dot(c, c) * np.eye(3) - np.outer(c, c))
    ev = np.linalg.eigvalsh(i_c)
    scale = max(abs(ev).max(), 1e-300)
    if ev[0] <= -tol * scale:
        out.append(f"inertia about the COM not positive (eigenvalue {ev[0]:.3g} kg m^2)")
    if ev[2] > ev[0] + ev[1] + tol * scale:
        out.append("principal moments violate the triangle inequality")
    return out
