"""Rigid transforms between the robot description's DH frames and exported link frames.

Exported link j's frame is the *proximal* frame P_j of the description's link j (SI):
P_j = DH_{j-1} Rz(theta_j + q_j) Tz(d_j) (revolute; prismatic: Tz(d_j + q_j)), so joint j
turns (slides) about (along) P_j's own z axis through its origin, as URDF and MJCF want.
The link's DH frame is DH_j = P_j Tx(a_j) Rx(alpha_j). The exported base link is DH_0.
"""

from __future__ import annotations

import numpy as np


def rot_x(angle: float) -> np.ndarray:
    """Rotation matrix (3, 3) about x by ``angle`` [rad]."""
    c, s = np.cos(angle), np.sin(angle)
    return np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]])


def rot_z(angle: float) -> np.ndarray:
    """Rotation matrix (3, 3) about z by ``angle`` [rad]."""
    c, s = np.cos(angle), np.sin(angle)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def transform(rot: np.ndarray, pos) -> np.ndarray:
    """Homogeneous transform (4, 4) from a rotation (3, 3) and a position (3,) [m]."""
    out = np.eye(4)
    out[:3, :3] = rot
    out[:3, 3] = pos
    return out


def dh_to_proximal_tail(a: float, alpha: float) -> np.ndarray:
    """E_j = Tx(a) Rx(alpha) (4, 4): DH_j = P_j E_j."""
    return transform(rot_x(alpha), [a, 0.0, 0.0])


def joint_origins(description) -> list[np.ndarray]:
    """Per joint j the transform (4, 4) from the parent's exported frame to P_j at q = 0.

    Parent of joint 1 is DH_0 (the base); of joint j > 1 it is P_{j-1}.
    """
    out = []
    tail = np.eye(4)
    for joint in description.joints:
        dh = joint.dh
        head = transform(rot_z(dh.theta), [0.0, 0.0, dh.d])
        out.append(tail @ head)
        tail = dh_to_proximal_tail(dh.a, dh.alpha)
    return out


def link_inertial(description, k: int) -> tuple[float, np.ndarray, np.ndarray]:
    """Link k's (mass [kg], COM (3,) [m], inertia about the COM (3, 3) [kg m^2]) in P_k."""
    link, dh = description.links[k], description.joints[k].dh
    e = dh_to_proximal_tail(dh.a, dh.alpha)
    rot = e[:3, :3]
    com = e[:3, 3] + rot @ link.com
    return float(link.mass), com, rot @ link.inertia @ rot.T


def rpy_from_matrix(rot: np.ndarray) -> np.ndarray:
    """URDF roll, pitch, yaw [rad] with rot = Rz(yaw) Ry(pitch) Rx(roll)."""
    pitch = np.arctan2(-rot[2, 0], np.hypot(rot[0, 0], rot[1, 0]))
    if np.hypot(rot[0, 0], rot[1, 0]) < 1e-12:  # gimbal lock: put everything in roll
        return np.array([np.arctan2(-rot[1, 2], rot[1, 1]), pitch, 0.0])
    return np.array([np.arctan2(rot[2, 1], rot[2, 2]), pitch, np.arctan2(rot[1, 0], rot[0, 0])])


def matrix_from_rpy(rpy) -> np.ndarray:
    """Rotation (3, 3) = Rz(yaw) Ry(pitch) Rx(roll) of URDF rpy [rad]."""
    r, p, y = rpy
    cp, sp = np.cos(p), np.sin(p)
    ry = np.array([[cp, 0.0, sp], [0.0, 1.0, 0.0], [-sp, 0.0, cp]])
    return rot_z(y) @ ry @ rot_x(r)


def gravity_alignment(gravity) -> np.ndarray:
    """Rotation R (3, 3) with R @ gravity = (0, 0, -|g|): the base's pose in a z-up world."""
    g = np.asarray(gravity, dtype=float)
    norm = np.linalg.norm(g)
    if norm == 0.0:
        return np.eye(3)
    u, v = g / norm, np.array([0.0, 0.0, -1.0])
    axis = np.cross(u, v)
    s, c = np.linalg.norm(axis), float(np.dot(u, v))
    if s < 1e-12:
        return np.eye(3) if c > 0 else rot_x(np.pi)
    k = axis / s
    kx = np.array([[0.0, -k[2], k[1]], [k[2], 0.0, -k[0]], [-k[1], k[0], 0.0]])
    return np.eye(3) + s * kx + (1.0 - c) * kx @ kx
