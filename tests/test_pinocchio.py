"""guardid's dynamics checked against pinocchio (an independent implementation).

The pinocchio model is built here from the robot YAML's DH rows by the textbook definition
(joint j's placement Tx(a_{j-1}) Rx(alpha_{j-1}) Rz(theta_j) Tz(d_j), link inertia moved
from DH frame j by Tx(a_j) Rx(alpha_j)); the rotor and friction terms are added from the
YAML's documented closed form. flexlink is not a rigid serial chain: not applicable.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest
from capturetools import THIRD, VARIANT

from guardid.dynamics import build_model
from guardid.robot import load_robot

CHAINS = ("guard", "planar2", "dfki_double_pendulum", str(VARIANT), str(THIRD))
"""Shipped chains and bench/bench_std_check.py's variant and third robots (their arms' COM
off-plane)."""


def _name(robot: str) -> str:
    return Path(robot).stem


def _rx(a):
    c, s = np.cos(a), np.sin(a)
    return np.array([[1.0, 0, 0], [0, c, -s], [0, s, c]])


def _rz(a):
    c, s = np.cos(a), np.sin(a)
    return np.array([[c, -s, 0], [s, c, 0], [0, 0, 1.0]])


def pin_model(desc):
    """pinocchio Model of a serial-chain description (module docstring)."""
    model = pin.Model()
    parent, tail = 0, pin.SE3.Identity()
    for j, joint in enumerate(desc.joints):
        dh = joint.dh
        place = tail * pin.SE3(_rz(dh.theta), np.array([0.0, 0.0, dh.d]))
        jm = pin.JointModelRZ() if joint.type == "revolute" else pin.JointModelPZ()
        jid = model.addJoint(parent, jm, place, joint.name)
        tail = pin.SE3(_rx(dh.alpha), np.array([dh.a, 0.0, 0.0]))
        link = desc.links[j]
        rot, off = tail.rotation, tail.translation
        inertia = pin.Inertia(link.mass, off + rot @ link.com, rot @ link.inertia @ rot.T)
        model.appendBodyToJoint(jid, inertia, pin.SE3.Identity())
        parent = jid
    model.gravity.linear = np.asarray(desc.gravity, dtype=float)
    return model


def rotor_mass_matrix(desc):
    """Constant rotor inertia matrix (n, n) [kg m^2] of docs/ROBOT_YAML.md's rotor model:
    N^2 J on the joint's diagonal; a coupled rotor (coupling s, motor on the previous link,
    parallel axes) spins at q_{j-1}' + s N q_j': J [[1, s N], [s N, N^2]] on joints j-1, j."""
    n = desc.n_dof
    m = np.zeros((n, n))
    for j, joint in enumerate(desc.joints):
        if joint.drive is not None:
            m[j, j] += joint.drive.gear_ratio**2 * joint.drive.rotor_inertia
        elif joint.rotor is not None:
            r = joint.rotor
            if r.coupling == 0:
                m[j, j] += r.gear_ratio**2 * r.inertia
            else:
                assert j == 1 and np.cos(desc.joints[0].dh.alpha) == 1.0  # the shipped case
                s = r.coupling * r.gear_ratio
                m[np.ix_([0, 1], [0, 1])] += r.inertia * np.array([[1.0, s], [s, s * s]])
    return m


def coulomb_shape(fr, qd):
    """The Coulomb term's shape, written here from docs/ROBOT_YAML.md (not guardid's code)."""
    if fr.model == "sign":
        return np.sign(qd)
    if fr.model == "tanh":
        return np.tanh(qd / fr.velocity_scale)
    if fr.model == "atan":
        return np.arctan(qd / fr.velocity_scale)
    raise AssertionError(f"no independent shape for friction model {fr.model}")


def friction_torque(desc, qd):
    out = np.zeros_like(qd)
    for j, joint in enumerate(desc.joints):
        fr = joint.friction
        if fr is not None:
            out[:, j] = fr.viscous * qd[:, j] + fr.coulomb * coulomb_shape(fr, qd[:, j]) + fr.offset
    return out


def states(n, num, seed):
    rng = np.random.default_rng(seed)
    return (
        rng.uniform(-np.pi, np.pi, (num, n)),
        rng.normal(0.0, 2.0, (num, n)),
        rng.normal(0.0, 5.0, (num, n)),
    )


def perturbed(desc, seed):
    """The description with every link's mass, COM and inertia changed (still physical)."""
    from dataclasses import replace

    rng = np.random.default_rng(seed)
    links = []
    for link in desc.links:
        a = rng.normal(size=(3, 3))
        rot = np.linalg.qr(a)[0]
        diag = np.diag(link.inertia) * rng.uniform(0.8, 1.2, 3)
        inertia = link.inertia if link.known_zero else rot @ np.diag(np.sort(diag)) @ rot.T
        com = link.com + (0.0 if link.known_zero else rng.normal(0, 0.02, 3))
        links.append(
            replace(link, mass=link.mass * rng.uniform(0.7, 1.3), com=com, inertia=inertia)
        )
    return replace(desc, links=tuple(links))


@pytest.mark.parametrize("robot", CHAINS, ids=_name)
@pytest.mark.parametrize("seed", [0, 1])
def test_inverse_dynamics_matches_pinocchio(robot, seed):
    desc = load_robot(robot) if seed == 0 else perturbed(load_robot(robot), seed)
    model = build_model(desc)
    pm = pin_model(desc)
    data = pm.createData()
    q, qd, qdd = states(desc.n_dof, 300, seed)
    ours = model.inverse_dynamics(q, qd, qdd)
    rotor = rotor_mass_matrix(desc)
    theirs = np.array([pin.rnea(pm, data, a, b, c) for a, b, c in zip(q, qd, qdd, strict=True)])
    theirs += qdd @ rotor.T + friction_torque(desc, qd)
    scale = np.abs(theirs).max()
    assert np.abs(ours - theirs).max() <= 1e-9 * scale
    m_ours = model.mass_matrix(q[:20])
    m_pin = np.array([pin.crba(pm, data, a) for a in q[:20]])
    m_pin = np.triu(m_pin) + np.triu(m_pin, 1).transpose(0, 2, 1) + rotor
    assert np.abs(m_ours - m_pin).max() <= 1e-9 * np.abs(m_pin).max()


def _standard_to_pin(desc):
    """T (10n, 10n): pinocchio's dynamic parameters per joint body (m, m c, I about the joint
    frame, pinocchio's order) = T @ guardid's rigid standard parameters. The map is linear;
    its columns come from pinocchio's own Inertia on a unit-mass reference link."""
    n = desc.n_dof
    t = np.zeros((10 * n, 10 * n))
    ref = np.array([1.0, 0.0, 0.0, 1.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0])

    def to_pin(phi, j):
        xx, xy, xz, yy, yz, zz, mx, my, mz, m = phi
        c = np.array([mx, my, mz]) / m
        i_o = np.array([[xx, xy, xz], [xy, yy, yz], [xz, yz, zz]])
        i_c = i_o - m * (c @ c * np.eye(3) - np.outer(c, c))
        dh = desc.joints[j].dh
        e = pin.SE3(_rx(dh.alpha), np.array([dh.a, 0.0, 0.0]))
        inertia = pin.Inertia(m, c, i_c)
        return e.act(inertia).toDynamicParameters()

    for j in range(n):
        base = to_pin(ref, j)
        for i in range(10):
            t[10 * j : 10 * j + 10, 10 * j + i] = to_pin(ref + np.eye(10)[i], j) - base
    return t


@pytest.mark.parametrize("robot", CHAINS, ids=_name)
def test_regressor_and_base_parameters_match_pinocchio(robot):
    desc = load_robot(robot)
    model = build_model(desc)
    n = desc.n_dof
    pm = pin_model(desc)
    data = pm.createData()
    q, qd, qdd = states(n, 200, 7)
    y_pin = np.array(
        [
            pin.computeJointTorqueRegressor(pm, data, a, b, c)
            for a, b, c in zip(q, qd, qdd, strict=True)
        ]
    )
    t = _standard_to_pin(desc)
    ours = model.regressor(q, qd, qdd)
    rigid = ours[:, :, : 10 * n]
    assert np.abs(rigid - y_pin @ t).max() <= 1e-9 * np.abs(rigid).max()
    # base parameters: same column space as pinocchio's regressor (known-zero parameters
    # removed) with the rotor and friction columns added by hand, and the same rank
    mask = np.ones(len(model.param_names))
    mask[model.known_zero] = 0.0
    cols = [y_pin @ t @ np.diag(mask[: 10 * n])]
    rotor = rotor_mass_matrix(desc)
    if rotor.any():
        for j in range(n):
            if desc.joints[j].reflected_inertia is not None:
                unit = np.zeros_like(rotor)
                unit[j, j] = 1.0
                if j == 1 and desc.joints[1].rotor is not None and desc.joints[1].rotor.coupling:
                    s = 1.0 / (desc.joints[1].rotor.coupling * desc.joints[1].rotor.gear_ratio)
                    unit = np.array([[s * s, s], [s, 1.0]])
                cols.append((qdd @ unit.T)[:, :, None])
    for j, joint in enumerate(desc.joints):
        fr = joint.friction
        if fr is not None:
            # the offset's column too: the base regressor keeps it when the offset is declared
            # absent (identification then leaves it out, at 0)
            f = np.zeros((len(q), n, 3))
            f[:, j] = np.column_stack([qd[:, j], coulomb_shape(fr, qd[:, j]), np.ones(len(q))])
            cols.append(f)
    w = np.concatenate(cols, axis=2).reshape(len(q) * n, -1)
    yb = model.base_regressor(q, qd, qdd).reshape(len(q) * n, -1)
    b = yb.shape[1]

    def rank(m):
        sv = np.linalg.svd(m, compute_uv=False)
        return int((sv > 1e-9 * sv[0]).sum())

    assert rank(w) == b
    assert rank(yb) == b
    assert rank(np.hstack([w, yb])) == b


@pytest.mark.parametrize("robot", CHAINS, ids=_name)
def test_base_parameter_values_give_pinocchios_torques(robot):
    """The base parameters' values (the truth bench/bench_std_check.py scores against) times
    the base regressor give pinocchio's inverse dynamics plus the rotors and friction."""
    desc = load_robot(robot)
    model = build_model(desc)
    pm = pin_model(desc)
    data = pm.createData()
    q, qd, qdd = states(desc.n_dof, 200, 11)
    theirs = np.array([pin.rnea(pm, data, a, b, c) for a, b, c in zip(q, qd, qdd, strict=True)])
    theirs += qdd @ rotor_mass_matrix(desc).T + friction_torque(desc, qd)
    ours = model.base_regressor(q, qd, qdd) @ model.base.values(model.params)
    assert np.abs(ours - theirs).max() <= 1e-9 * np.abs(theirs).max()
