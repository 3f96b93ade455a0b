"""Dynamics of serial chains against independent truths (guardid.dynamics)."""

from __future__ import annotations

import numpy as np
import pytest

from guardid.dynamics import ChainModel, PlanarPaperModel, build_model
from guardid.robot import load_robot

N = 1000


def _states(n: int, seed: int, num: int = N):
    rng = np.random.default_rng(seed)
    q = rng.uniform(-np.pi, np.pi, (num, n))
    return q, 2.0 * rng.standard_normal((num, n)), 3.0 * rng.standard_normal((num, n))


@pytest.fixture(scope="module", params=["guard", "planar2"])
def model(request) -> ChainModel:
    return build_model(request.param)


def _rel(a, b):
    return np.abs(a - b).max() / np.abs(b).max()


def test_regressor_equals_newton_euler(model):
    q, qd, qdd = _states(model.n_dof, 1)
    tau_ne = model.inverse_dynamics(q, qd, qdd)
    assert _rel(model.regressor(q, qd, qdd) @ model.params, tau_ne) < 1e-9
    # also for arbitrary (non-physical) parameter vectors
    p = np.random.default_rng(2).uniform(0.1, 1.0, model.params.size)
    assert _rel(model.regressor(q, qd, qdd) @ p, model.inverse_dynamics(q, qd, qdd, p)) < 1e-9


def _closed_form(q, qd, qdd, th, g=9.81):
    q1, q2 = q.T
    v1, v2 = qd.T
    a1, a2 = qdd.T
    t1 = (
        th[0] * a1
        + th[1] * (np.cos(q2) * (2 * a1 + a2) - np.sin(q2) * (v2**2 + 2 * v1 * v2))
        + th[2] * (a1 + a2)
        + th[3] * g * np.cos(q1)
        + th[4] * g * np.cos(q1 + q2)
    )
    t2 = (
        th[1] * (np.cos(q2) * a1 + np.sin(q2) * v1**2)
        + th[2] * (a1 + a2)
        + th[4] * g * np.cos(q1 + q2)
    )
    return np.stack([t1, t2], axis=1)


def test_planar_newton_euler_equals_closed_form():
    m = build_model("planar2")
    q, qd, qdd = _states(2, 3)
    truth = _closed_form(q, qd, qdd, (1.5, 0.5, 0.25, 1.5, 1.0))
    assert _rel(m.inverse_dynamics(q, qd, qdd), truth) < 1e-12
    paper = PlanarPaperModel.from_description(load_robot("planar2"))
    np.testing.assert_allclose(paper.params, [1.5, 0.5, 0.25, 1.5, 1.0], rtol=1e-12)
    assert _rel(paper.inverse_dynamics(q, qd, qdd), truth) < 1e-12
    assert _rel(paper.regressor(q, qd, qdd) @ paper.params, truth) < 1e-12


def test_planar_base_parameters_are_paper_parameters():
    m = build_model("planar2")
    base = m.base
    values = base.values(m.params)
    assert base.names == ("ZZ1R", "MX1R", "ZZ2R", "MX2R")
    np.testing.assert_allclose(values, [1.5, 1.5, 0.25, 1.0], atol=1e-12)  # th1 th4 th3 th5
    assert base.formulas[0] == "ZZ1 + MX1 + 0.25*M1 + 0.25*M2"
    # th2 = l1 th5: the chain, with base values mapped to the paper's five parameters
    zz1, mx1, zz2, mx2 = values
    l1 = load_robot("planar2").joints[0].dh.a
    th = [zz1, l1 * mx2, zz2, mx1, mx2]
    q, qd, qdd = _states(2, 4)
    assert _rel(_closed_form(q, qd, qdd, th), m.inverse_dynamics(q, qd, qdd)) < 1e-12


def test_base_regressor(model):
    q, qd, qdd = _states(model.n_dof, 5)
    yb = model.base_regressor(q, qd, qdd)
    flat = yb.reshape(-1, yb.shape[-1])
    assert np.linalg.matrix_rank(flat) == flat.shape[1]
    tau = model.regressor(q, qd, qdd) @ model.params
    assert _rel(yb @ model.base.values(model.params), tau) < 1e-9
    assert len(model.base.names) == len(model.base.formulas) == model.base.K.shape[0]


def test_guard_base_parameters():
    m = build_model("guard")
    b = dict(zip(m.base.names, m.base.formulas, strict=True))
    assert b["ZZ1R"] == "YY1 + YY2 + Ia1 + 0.2*MX2 + 0.01*M2"
    assert b["MX2R"] == "MX2 + 0.1*M2"
    assert {"Fv1", "Fc1", "Fo1", "Fv2", "Fc2", "Fo2", "MY2", "YZ2"} <= set(b)
    v = dict(zip(m.base.names, m.base.values(m.params), strict=True))
    assert v["MX2R"] == pytest.approx(3.5 * 0.22)  # m2 times COM distance along the arm


def test_forward_inverts_inverse(model):
    q, qd, qdd = _states(model.n_dof, 6)
    tau = model.inverse_dynamics(q, qd, qdd, friction=False)
    back = model.forward_dynamics(q, qd, tau)
    assert _rel(back, qdd) < 1e-9


def test_mass_matrix_spd(model):
    q, _, _ = _states(model.n_dof, 7)
    m = model.mass_matrix(q)
    np.testing.assert_allclose(m, np.swapaxes(m, 1, 2), atol=1e-12)
    assert np.linalg.eigvalsh(m).min() > 0


def _dh_transform(a, alpha, d, theta):
    ct, st, ca, sa = np.cos(theta), np.sin(theta), np.cos(alpha), np.sin(alpha)
    return np.array(
        [
            [ct, -st * ca, st * sa, a * ct],
            [st, ct * ca, -ct * sa, a * st],
            [0, sa, ca, d],
            [0, 0, 0, 1.0],
        ]
    )


def _poses(desc, q):
    t = np.eye(4)
    out = []
    for joint, qi in zip(desc.joints, q, strict=True):
        dh = joint.dh
        if joint.type == "revolute":
            t = t @ _dh_transform(dh.a, dh.alpha, dh.d, dh.theta + qi)
        else:
            t = t @ _dh_transform(dh.a, dh.alpha, dh.d + qi, dh.theta)
        out.append(t)
    return out


def test_kinetic_energy_matches_link_velocities(model):
    """0.5 qd' M qd equals the links' kinetic energy from finite-differenced poses."""
    desc = model.description
    q, qd, _ = _states(model.n_dof, 8, num=50)
    m = model.mass_matrix(q)
    h = 1e-6
    for k in range(q.shape[0]):
        energy = 0.0
        plus, minus, mid = (_poses(desc, q[k] + s * h * qd[k]) for s in (1, -1, 0))
        for link, tp, tm, t0 in zip(desc.links, plus, minus, mid, strict=True):
            c_plus = tp[:3, :3] @ link.com + tp[:3, 3]
            c_minus = tm[:3, :3] @ link.com + tm[:3, 3]
            v = (c_plus - c_minus) / (2 * h)
            w_skew = (tp[:3, :3] - tm[:3, :3]) / (2 * h) @ t0[:3, :3].T
            w = np.array([w_skew[2, 1], w_skew[0, 2], w_skew[1, 0]])
            inertia = t0[:3, :3] @ link.inertia @ t0[:3, :3].T
            energy += 0.5 * link.mass * v @ v + 0.5 * w @ inertia @ w
        for j, joint in enumerate(desc.joints):
            if joint.drive is not None:
                energy += 0.5 * joint.drive.reflected_inertia * qd[k, j] ** 2
        assert 0.5 * qd[k] @ m[k] @ qd[k] == pytest.approx(energy, rel=1e-7)


def test_fast_evaluators_match_vectorised(model):
    q, qd, _ = _states(model.n_dof, 9, num=200)
    m = model.mass_matrix(q)
    b = model.bias(q, qd)
    p = np.random.default_rng(3).uniform(0.1, 1.0, model.params.size)
    mp, bp = model.mass_matrix(q, p), model.bias(q, qd, p)
    for k in range(q.shape[0]):
        np.testing.assert_allclose(model.mass_matrix_1(q[k]), m[k], rtol=1e-12, atol=1e-12)
        np.testing.assert_allclose(model.bias_1(q[k], qd[k]), b[k], rtol=1e-12, atol=1e-11)
        np.testing.assert_allclose(model.mass_matrix_1(q[k], p), mp[k], rtol=1e-12, atol=1e-12)
        np.testing.assert_allclose(
            model.bias_1(list(q[k]), list(qd[k]), p), bp[k], rtol=1e-12, atol=1e-11
        )


def test_prismatic_chain(tmp_path):
    """A revolute-prismatic-revolute chain: regressor, energy-free checks and base rank."""
    text = """
name: rpr
gravity: [0.0, -9.81, -3.0]
joints:
  - {type: revolute, dh: {a: 0.1, alpha: 0.5, d: 0.2, theta: 0.3},
     limits: {position: null, velocity: 1, acceleration: 1}, drive: null,
     friction: {viscous: 0.1, coulomb: 0.2}}
  - {type: prismatic, dh: {a: 0.05, alpha: -1.2, d: 0.4, theta: 0.7},
     limits: {position: [-0.5, 0.5], velocity: 1, acceleration: 1}, drive: null,
     friction: null}
  - {type: revolute, dh: {a: 0.2, alpha: 1.0, d: 0.1, theta: 0.0},
     limits: {position: null, velocity: 1, acceleration: 1}, drive: null, friction: null}
links:
  - {mass: 1.0, com: [0.1, 0.02, -0.03], inertia: {xx: 0.02, yy: 0.03, zz: 0.04, xy: 0.001}}
  - {mass: 2.0, com: [-0.05, 0.1, 0.02], inertia: {xx: 0.05, yy: 0.04, zz: 0.03, yz: 0.002}}
  - {mass: 0.5, com: [0.03, -0.02, 0.1], inertia: {xx: 0.01, yy: 0.012, zz: 0.015}}
"""
    path = tmp_path / "rpr.yaml"
    path.write_text(text)
    model = build_model(load_robot(path))
    q, qd, qdd = _states(3, 10)
    tau = model.inverse_dynamics(q, qd, qdd)
    assert _rel(model.regressor(q, qd, qdd) @ model.params, tau) < 1e-9
    assert _rel(model.base_regressor(q, qd, qdd) @ model.base.values(model.params), tau) < 1e-9
    assert (
        _rel(model.forward_dynamics(q, qd, model.inverse_dynamics(q, qd, qdd, friction=False)), qdd)
        < 1e-9
    )
    test_kinetic_energy_matches_link_velocities(model)
    test_fast_evaluators_match_vectorised(model)
