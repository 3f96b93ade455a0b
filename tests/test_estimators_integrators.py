"""Integrator options of the gradient and Hopfield estimators against closed-form truth.

Scalar problems y = a theta*, worked out by hand: for dtheta/dt = -lam (theta - theta*) held
over a step h, explicit Euler multiplies the error by (1 - h lam) (stable iff h < 2 / lam),
implicit Euler by 1 / (1 + h lam) (always in (0, 1)).
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from guardid.estimators import Gradient, Hopfield

A_SCALAR, THETA_TRUE = 2.0, 3.0  # y = a theta*


def _gradient_run(integrator, eta, dt, n, fit):
    A = np.full((n, 1, 1), A_SCALAR)
    y = np.full((n, 1), A_SCALAR * THETA_TRUE)
    est = Gradient(eta=eta, dt=dt, theta0=[0.0], history_every=1, blowup=1e6, integrator=integrator)
    if fit:
        return est.fit(A, y)
    for k in range(n):
        est.update(A[k], y[k])
    return est


@pytest.mark.parametrize("fit", [True, False])
def test_gradient_scalar_steps_match_closed_form(fit):
    # lam = 2 eta a^2 = 4 1/s, h = 0.1 s: explicit factor 0.6, implicit 1 / 1.4
    for integrator, factor in (("euler", 0.6), ("implicit", 1 / 1.4)):
        est = _gradient_run(integrator, eta=0.5, dt=0.1, n=5, fit=fit)
        assert est.theta_[0] == pytest.approx(THETA_TRUE - 3.0 * factor**5, rel=1e-12)
    # by hand: 3 - 3 * 0.6^5 = 2.76672, 3 - 3 / 1.4^5 = 2.442197...
    assert _gradient_run("euler", 0.5, 0.1, 5, fit).theta_[0] == pytest.approx(2.76672)
    assert _gradient_run("implicit", 0.5, 0.1, 5, fit).theta_[0] == pytest.approx(2.4421966, 1e-7)


def test_gradient_explicit_euler_stability_bound_and_implicit_always_stable():
    # lam = 2 eta a^2 = 4 1/s: explicit Euler is stable iff dt < 2 / lam = 0.5 s
    below = _gradient_run("euler", 0.5, 0.49, 3000, fit=True)
    assert abs(below.theta_[0] - THETA_TRUE) < 1e-6 and not below.diverged_
    above = _gradient_run("euler", 0.5, 0.51, 3000, fit=True)
    assert above.diverged_
    for dt in (0.51, 100.0):
        imp = _gradient_run("implicit", 0.5, dt, 400, fit=True)
        assert not imp.diverged_
        # monotone: the error never changes sign (factor 1 / (1 + h lam) > 0)
        assert np.all(imp.history_[:, 0] <= THETA_TRUE)
        assert abs(imp.theta_[0] - THETA_TRUE) < 1e-9


def test_gradient_implicit_multi_output_step_is_backward_euler():
    rng = np.random.default_rng(3)
    A_k, y_k, th0 = rng.normal(size=(2, 4)), rng.normal(size=2), rng.normal(size=4)
    eta, dt = 7.0, 0.01
    est = Gradient(eta=eta, dt=dt, theta0=th0, integrator="implicit").update(A_k, y_k)
    c = 2 * eta * dt  # (I + c A^T A) dtheta = c A^T (y - A theta), the p x p system
    dth = np.linalg.solve(np.eye(4) + c * A_k.T @ A_k, c * A_k.T @ (y_k - A_k @ th0))
    np.testing.assert_allclose(est.theta_, th0 + dth, rtol=1e-12)
    with pytest.raises(ValueError, match="integrator"):
        Gradient(integrator="rk4")


def _hopfield_scalar(integrator, h_over_beta, s0, y, n):
    est = Hopfield(
        theta_n=[s0],
        bounds=([-1.0], [1.0]),
        beta=1.0,
        dt=h_over_beta,
        fit_block=1,
        history_every=1,
        integrator=integrator,
    )
    return est.fit(np.ones((n, 1, 1)), np.full((n, 1), y))


def test_hopfield_euler_one_step_by_hand():
    # box (-1, 1): S = 1, c = 0; s0 = 0.2, a = 1, y = 0.5, h/beta = 0.5:
    # s1 = 0.2 + 0.5 (1 - 0.04) (0.5 - 0.2) = 0.344
    est = _hopfield_scalar("euler", 0.5, 0.2, 0.5, 1)
    assert est.theta_[0] == pytest.approx(0.344, rel=1e-12)
    # the same sample online gives the same state
    on = Hopfield(theta_n=[0.2], bounds=([-1.0], [1.0]), beta=1.0, dt=0.5, integrator="euler")
    assert on.update(np.ones((1, 1)), np.array([0.5])).theta_[0] == pytest.approx(0.344)


def test_hopfield_euler_stability_bound_by_hand():
    # truth at the centre (y = 0): s -> s - c (1 - s^2) s, c = h / beta; linear factor 1 - c
    settled = _hopfield_scalar("euler", 1.9, 0.5, 0.0, 600)
    assert abs(settled.theta_[0]) < 1e-9
    # c = 2.1 > 2: the centre is unstable; the 2-cycle s = +-sqrt(1 - 2 / c) (from
    # -s = s - c (1 - s^2) s) has multiplier (1 - c (1 - 3 s^2))^2 = 0.64 < 1, so it attracts
    osc = _hopfield_scalar("euler", 2.1, 0.5, 0.0, 600)
    assert not osc.diverged_
    assert abs(osc.theta_[0]) == pytest.approx(math.sqrt(1 - 2 / 2.1), rel=1e-6)
    # the default (linearly implicit) step settles at the same gain and far beyond
    for c in (2.1, 1e4):
        assert abs(_hopfield_scalar("implicit", c, 0.5, 0.0, 600).theta_[0]) < 1e-9
    # c = 10 from s = 0.5: s1 = 0.5 - 10 * 0.75 * 0.5 = -3.25 (outside the box), then
    # s2 = -3.25 - 10 (1 - 10.5625) (-3.25) = -314.0, s3 ~ -3.1e8 > blowup = 1e6
    blown = _hopfield_scalar("euler", 10.0, 0.5, 0.0, 200)
    assert blown.diverged_ and blown.n_samples_ <= 64  # offline: checked every 64 samples
    on = Hopfield(theta_n=[0.5], bounds=([-1.0], [1.0]), beta=1.0, dt=10.0, integrator="euler")
    with np.errstate(over="ignore", invalid="ignore"):
        for _ in range(5):
            on.update(np.ones((1, 1)), np.zeros(1))
    assert on.diverged_ and on.diverged_at_ == 3
    with pytest.raises(ValueError, match="integrator"):
        Hopfield(theta_n=[0.0], half_widths=[1.0], integrator="rk4")
