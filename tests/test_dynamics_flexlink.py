"""Seed 000's flexible link model (guardid.dynamics.FlexibleLinkModel)."""

from __future__ import annotations

import numpy as np

from guardid.dynamics import build_model


def test_flexlink_model():
    m = build_model("flexlink")
    np.testing.assert_allclose(m.params, [0.75, 1.5, 2.0])
    np.testing.assert_allclose(m.nominal, [1.0, 2.0, 2.4])
    assert np.all(m.bounds[:, 0] < m.params) and np.all(m.params < m.bounds[:, 1])
    rng = np.random.default_rng(0)
    q, qd, qdd = (rng.standard_normal((500, 2)) for _ in range(3))
    # independent closed form of eq. 24 with J_h on M11 and a restoring spring
    a, g, k = m.params
    c, s = np.cos(q[:, 1]), np.sin(q[:, 1])
    t1 = (
        (2.0 + a + g * c) * qdd[:, 0]
        + (a + g * c / 2) * qdd[:, 1]
        - g * s * (qd[:, 0] * qd[:, 1] + qd[:, 1] ** 2 / 2)
    )
    t2 = (a + g * c / 2) * qdd[:, 0] + a * qdd[:, 1] + g * s * qd[:, 0] ** 2 / 2 + k * q[:, 1]
    truth = np.stack([t1, t2], 1)
    np.testing.assert_allclose(m.inverse_dynamics(q, qd, qdd), truth, atol=1e-12)
    y = truth - m.known_torque(q, qd, qdd)
    np.testing.assert_allclose(m.regressor(q, qd, qdd) @ m.params, y, atol=1e-12)
    np.testing.assert_allclose(m.forward_dynamics(q, qd, truth), qdd, atol=1e-10)
    mm = m.mass_matrix(q)
    assert np.linalg.eigvalsh(mm).min() > 0
    for i in range(20):
        np.testing.assert_allclose(m.mass_matrix_1(q[i]), mm[i], atol=1e-14)
        np.testing.assert_allclose(m.bias_1(q[i], qd[i]), m.bias(q[i], qd[i])[0], atol=1e-14)
    assert m.base.names == ("alpha", "gamma", "k")
