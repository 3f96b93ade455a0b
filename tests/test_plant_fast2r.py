"""The fitted two-revolute evaluator agrees with the generic dynamics model."""

import numpy as np

from guardid.dynamics import build_model
from guardid.plant import PayloadChange, Plant
from guardid.plant.fast2r import fit_two_revolute, generic_two
from guardid.robot import load_robot


def test_fitted_evaluator_matches_generic_model():
    for name in ("guard", "planar2"):
        model = build_model(load_robot(name))
        fast = fit_two_revolute(model, model.params)
        slow = generic_two(model, model.params)
        assert fast is not None
        rng = np.random.default_rng(1)
        for q1, q2, v1, v2 in rng.uniform(-4, 4, (200, 4)).tolist():
            np.testing.assert_allclose(fast(q1, q2, v1, v2), slow(q1, q2, v1, v2),
                                       rtol=1e-10, atol=1e-10)  # fmt: skip


def test_fast_and_generic_plants_agree_with_payload():
    kw = dict(seed=2, q0=[0.0, 0.1], payload=[PayloadChange(0.5, 0.8, (0.15, 0.0, 0.01))])
    a, b = Plant("guard", **kw), Plant("guard", fast=False, **kw)
    assert a.fast_path and not b.fast_path
    for k in range(100):
        u = [8 * np.sin(0.05 * k), 4.5 + 3 * np.sin(0.09 * k)]
        sa, sb = a.step(u), b.step(u)
        np.testing.assert_allclose(sa.q, sb.q, atol=1e-9)
        assert sa.counts == sb.counts or np.abs(np.array(sa.q) - sb.q).max() < 1e-9


def test_torque_input_for_driveless_planar_arm():
    model = build_model(load_robot("planar2"))
    plant = Plant("planar2", noise=False, q0=[0.0, 0.0])
    s = plant.step([0.0, 0.0])  # released from rest: qd ~ dt * M^-1 (-gravity torque)
    qdd0 = np.linalg.solve(model.mass_matrix_1([0.0, 0.0]), -model.bias_1([0.0, 0.0], [0, 0]))
    np.testing.assert_allclose(s.qd, qdd0 * plant.dt, rtol=1e-2)
    g = model.bias_1(np.array([0.3, 0.2]), np.zeros(2))
    hold = Plant("planar2", noise=False, q0=[0.3, 0.2])
    for _ in range(100):
        s = hold.step(g.tolist())
    np.testing.assert_allclose(s.q, [0.3, 0.2], atol=1e-9)
