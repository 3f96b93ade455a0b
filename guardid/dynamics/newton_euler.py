"""Vectorised recursive Newton-Euler inverse dynamics of a serial chain (standard DH).

Written independently of the regressor: it uses each link's mass, centre of mass and
inertia about the COM (Luh-Walker-Paul form) instead of the linear standard parameters.
"""

from __future__ import annotations

import numpy as np

from guardid.robot.description import ChainDescription


def link_physical(params: np.ndarray, n: int):
    """Split the first 10n standard parameters into (mass, com (3,), inertia about COM (3,3))."""
    out = []
    for k in range(n):
        xx, xy, xz, yy, yz, zz, mx, my, mz, m = params[10 * k : 10 * k + 10]
        i_o = np.array([[xx, xy, xz], [xy, yy, yz], [xz, yz, zz]], dtype=float)
        h = np.array([mx, my, mz], dtype=float)
        c = h / m if m != 0 else np.zeros(3)
        out.append((float(m), c, i_o - m * (np.dot(c, c) * np.eye(3) - np.outer(c, c))))
    return out


def _cross(u: np.ndarray, v: np.ndarray) -> np.ndarray:
    return np.cross(u, v)


def _rot(theta: np.ndarray, alpha: float) -> np.ndarray:
    """R_{j-1,j} (N, 3, 3) of a standard DH row."""
    st, ct = np.sin(theta), np.cos(theta)
    sa, ca = np.sin(alpha), np.cos(alpha)
    r = np.zeros(theta.shape + (3, 3))
    r[:, 0, 0], r[:, 0, 1], r[:, 0, 2] = ct, -st * ca, st * sa
    r[:, 1, 0], r[:, 1, 1], r[:, 1, 2] = st, ct * ca, -ct * sa
    r[:, 2, 1], r[:, 2, 2] = sa, ca
    return r


def rnea(chain: ChainDescription, links, q, qd, qdd, gravity: bool = True) -> np.ndarray:
    """Rigid-body joint torques (N, n) [N m | N] for states (N, n); links from link_physical."""
    q, qd, qdd = (np.atleast_2d(np.asarray(x, dtype=float)) for x in (q, qd, qdd))
    num, n = q.shape
    g = np.asarray(chain.gravity, dtype=float) if gravity else np.zeros(3)
    w = np.zeros((num, 3))
    wd = np.zeros((num, 3))
    acc = np.tile(-g, (num, 1))
    ez = np.array([0.0, 0.0, 1.0])
    rots, pstars, axes, forces, moments = [], [], [], [], []
    for j, joint in enumerate(chain.joints):
        dh = joint.dh
        revolute = joint.type == "revolute"
        theta = q[:, j] + dh.theta if revolute else np.full(num, dh.theta)
        d = np.full(num, dh.d) if revolute else q[:, j] + dh.d
        rot = _rot(theta, dh.alpha)
        rt = np.swapaxes(rot, 1, 2)
        pstar = np.stack([np.full(num, dh.a), d * np.sin(dh.alpha), d * np.cos(dh.alpha)], axis=1)
        z_qd = qd[:, j, None] * ez
        z_qdd = qdd[:, j, None] * ez
        if revolute:
            w_new = np.einsum("nij,nj->ni", rt, w + z_qd)
            wd_new = np.einsum("nij,nj->ni", rt, wd + z_qdd + _cross(w, z_qd))
            a_new = np.einsum("nij,nj->ni", rt, acc)
        else:
            w_new = np.einsum("nij,nj->ni", rt, w)
            wd_new = np.einsum("nij,nj->ni", rt, wd)
            a_new = np.einsum("nij,nj->ni", rt, acc + z_qdd)
            a_new = a_new + 2.0 * _cross(w_new, np.einsum("nij,nj->ni", rt, z_qd))
        a_new = a_new + _cross(wd_new, pstar) + _cross(w_new, _cross(w_new, pstar))
        w, wd, acc = w_new, wd_new, a_new
        m, c, ic = links[j]
        a_c = acc + _cross(wd, c) + _cross(w, _cross(w, c))
        forces.append(m * a_c)
        moments.append(wd @ ic.T + _cross(w, w @ ic.T))
        rots.append(rot)
        pstars.append(pstar)
        axes.append((rot[:, 2, :], revolute))  # z_{j-1} expressed in frame j
    tau = np.zeros((num, n))
    f_next = np.zeros((num, 3))
    n_next = np.zeros((num, 3))
    for j in range(n - 1, -1, -1):
        if j + 1 < n:
            r_next = rots[j + 1]
            f_child = np.einsum("nij,nj->ni", r_next, f_next)
            n_child = np.einsum("nij,nj->ni", r_next, n_next)
        else:
            f_child = np.zeros((num, 3))
            n_child = np.zeros((num, 3))
        _, c, _ = links[j]
        f_j = f_child + forces[j]
        n_j = n_child + _cross(pstars[j], f_child) + _cross(pstars[j] + c, forces[j]) + moments[j]
        axis, revolute = axes[j]
        tau[:, j] = np.einsum("ni,ni->n", axis, n_j if revolute else f_j)
        f_next, n_next = f_j, n_j
    return tau
