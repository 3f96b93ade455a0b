"""MLP estimator (seed 001 section 3.3): backprop against finite differences, convergence on
a synthetic linear model with constant theta, the interface (states, update, determinism)."""

from __future__ import annotations

import numpy as np
import pytest

from guardid.estimators import MLP
from guardid.estimators.mlp import AUTO_STEPS


def linear_model(N=3000, p=5, n=2, k=6, noise=0.05, seed=0):
    """Random regressor A (N, n, p), states X (N, k), constant theta (p,), noisy y (N, n)."""
    rng = np.random.default_rng(seed)
    A = rng.normal(size=(N, n, p))
    X = rng.normal(size=(N, k)) * np.array([0.5, 0.3, 2.0, 1.0, 10.0, 5.0])[:k]
    theta = rng.uniform(0.5, 2.0, p) * rng.choice([-1.0, 1.0], p)
    y = A @ theta + noise * rng.normal(size=(N, n))
    return A, X, theta, y


@pytest.mark.parametrize("weight_decay", [0.0, 0.3])
def test_backprop_matches_finite_differences(weight_decay):
    A, X, _, y = linear_model(N=40)
    net = MLP(epochs=0, init_scale=1.0, weight_decay=weight_decay, seed=3).fit(A, y, X=X)
    # move b1 off zero so every term of the hidden-layer gradient is exercised
    net.weights_["b1"] += np.random.default_rng(1).normal(size=net.weights_["b1"].shape)
    loss, grads = net.loss_grad(A, y, X)
    h = 1e-6
    for name, w in net.weights_.items():
        num = np.zeros_like(w)
        for idx in np.ndindex(w.shape):
            old = w[idx]
            w[idx] = old + h
            up = net.loss_grad(A, y, X)[0]
            w[idx] = old - h
            down = net.loss_grad(A, y, X)[0]
            w[idx] = old
            num[idx] = (up - down) / (2 * h)
        err = np.max(np.abs(num - grads[name])) / max(np.max(np.abs(num)), 1e-12)
        assert err < 1e-6, (name, err)
    assert loss == pytest.approx(net.loss_grad(A, y, X)[0])


def test_mean_output_converges_to_constant_theta_and_spread_shrinks():
    A, X, theta, y = linear_model()
    # a wide initial network (init_scale 1): its output varies strongly with the state
    init = MLP(epochs=0, init_scale=1.0, seed=0).fit(A, y, X=X)
    net = MLP(init_scale=1.0, seed=0).fit(A, y, X=X)
    steps_per_epoch = -(-A.shape[0] // 64)
    assert net.n_epochs_ == -(-AUTO_STEPS // steps_per_epoch)
    assert not net.diverged_
    err = np.abs(net.theta_history_ - theta).max(axis=1)
    assert err[-1] < 0.01 * np.abs(theta).min()  # mean estimate within 1 % of the truth
    assert err[-1] < 0.1 * err[0]
    np.testing.assert_allclose(net.theta_, theta, rtol=0.01)
    # the spread across samples shrinks from the initial network's by orders of magnitude
    spread, spread0 = net.output_spread_, init.output_spread_
    assert np.all(spread < 0.02 * spread0), (spread0, spread)
    assert np.all(net.spread_history_[-1] < net.spread_history_[0])
    assert net.output_spread_ == pytest.approx(net.spread_history_[-1])
    assert net.loss_history_[-1] < 0.1 * net.loss_history_[0]
    # the torque fit reaches the noise floor (noise variance 0.05^2 per row)
    assert net.loss_ == pytest.approx(0.05**2, rel=0.2)


def test_paper_plain_backprop_full_batch_also_converges():
    A, X, theta, y = linear_model(N=500)
    net = MLP(momentum=0.0, weight_decay=0.0, batch_size=None, lr=0.1, epochs=3000)
    net.fit(A, y, X=X)
    np.testing.assert_allclose(net.theta_, theta, rtol=0.02)
    assert np.all(net.output_spread_ < 0.05 * np.abs(theta))


def test_target_stops_training_and_flags_convergence():
    A, X, _, y = linear_model(N=500, noise=0.0)
    net = MLP(target=1e-3, epochs=500).fit(A, y, X=X)
    assert net.converged_ and net.n_epochs_ < 500
    assert net.loss_ <= 1e-3 and net.loss_history_[-1] <= 1e-3


def test_states_required_and_checked():
    A, X, _, y = linear_model(N=50)
    with pytest.raises(ValueError, match="states"):
        MLP().fit(A, y)
    with pytest.raises(ValueError, match="one row of states per sample"):
        MLP().fit(A, y, X=X[:-1])


def test_stacked_shapes_and_predict():
    A, X, theta, y = linear_model(N=400, n=1)
    net = MLP().fit(A[:, 0, :], y[:, 0], X=X)  # stacked (M, p) / (M,)
    np.testing.assert_allclose(net.theta_, theta, rtol=0.02)
    assert net.predict(A[:, 0, :]).shape == (400,)
    assert net.predict(A[:, 0, :], X=X).shape == (400,)
    assert net.theta_net(X).shape == (400, 5)
    np.testing.assert_allclose(net.theta_net(X).mean(axis=0), net.theta_)


def test_deterministic_given_seed():
    A, X, _, y = linear_model(N=300)
    a = MLP(epochs=20, seed=5).fit(A, y, X=X)
    b = MLP(epochs=20, seed=5).fit(A, y, X=X)
    c = MLP(epochs=20, seed=6).fit(A, y, X=X)
    np.testing.assert_array_equal(a.theta_, b.theta_)
    np.testing.assert_array_equal(a.output_spread_, b.output_spread_)
    assert not np.array_equal(a.theta_, c.theta_)


def test_online_update_is_one_gradient_step():
    A, X, _, y = linear_model(N=300)
    with pytest.raises(RuntimeError, match="prior fit"):
        MLP().update(A[0], y[0], X[0])
    net = MLP(epochs=5, momentum=0.0, lr=0.01).fit(A, y, X=X)
    with pytest.raises(ValueError, match="state"):
        net.update(A[0], y[0])
    before = np.sum((A[7] @ net.theta_net(X[7:8])[0] - y[7]) ** 2)
    n = net.n_samples_
    net.update(A[7], y[7], X[7])
    after = np.sum((A[7] @ net.theta_ - y[7]) ** 2)
    assert after < before  # a small step along -gradient lowers that sample's error
    np.testing.assert_allclose(net.theta_, net.theta_net(X[7:8])[0])
    assert net.n_samples_ == n + 1


def test_divergence_is_flagged():
    A, X, _, y = linear_model(N=200)
    net = MLP(lr=50.0, momentum=0.0, epochs=50).fit(A, y, X=X)
    assert net.diverged_ and not net.converged_


def test_bad_hyper_parameters_rejected():
    with pytest.raises(ValueError):
        MLP(momentum=1.0)
    with pytest.raises(ValueError):
        MLP(lr=0.0)
    with pytest.raises(ValueError):
        MLP(weight_decay=-1.0)
