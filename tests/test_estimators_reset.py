"""RLS.discard and the windowed Hopfield (lam, info_floor, discard) against plain numpy truths.

Truths computed here: the prior-regularised (forgetting) least-squares solution of the
weighted normal equations, the Schur-complement marginal information of the kept parameters,
and the closed-form minimiser after a reset (prior information on the reset parameters plus
the kept parameters' marginal information, centred on the pre-change estimate, plus the new
regime's normal equations). Regime 1 has theta TH1, regime 2 changes only IDX (TH2).
"""

import numpy as np
import pytest

from guardid.estimators import RLS, Hopfield

IDX, KEEP = np.array([1, 3]), np.array([0, 2])
TH1 = np.array([0.5, -0.3, 0.8, 0.2])
TH2 = TH1 + np.array([0.0, 0.6, 0.0, -0.5])
THN = np.array([0.3, 0.0, 0.6, 0.0])  # Hopfield nominal: TH1 and TH2 inside the box
HW = np.array([1.0, 2.0, 0.5, 1.5])


def regime(theta, n_out, N, seed, noise=1e-3, unexcited=()):
    """Random regressor (N, n_out, p) (columns ``unexcited`` 0) and noisy y (N, n_out)."""
    rng = np.random.default_rng(seed)
    A = rng.normal(size=(N, n_out, theta.size))
    A[:, :, list(unexcited)] = 0.0
    return A, A @ theta + noise * rng.normal(size=(N, n_out))


def feed(est, A, y):
    for A_k, y_k in zip(A, y, strict=True):
        est.update(A_k, y_k)
    return est


def info(A):
    return np.einsum("nip,niq->pq", A, A)


def rhs(A, y):
    return np.einsum("nip,ni->p", A, y)


def reset_info(R, prior_info):
    """blockdiag(prior_info on IDX, Schur complement of R on KEEP)."""
    Rki = R[np.ix_(KEEP, IDX)]
    out = np.zeros_like(R)
    out[np.ix_(KEEP, KEEP)] = (
        R[np.ix_(KEEP, KEEP)] - Rki @ np.linalg.inv(R[np.ix_(IDX, IDX)]) @ Rki.T
    )
    out[IDX, IDX] = prior_info
    return out


def reset_minimiser(R_pre, theta_pre, prior_info, A2, y2):
    """Minimiser of (th - theta_pre)^T R_d (th - theta_pre) + |y2 - A2 th|^2 after a reset."""
    R_d = reset_info(R_pre, prior_info)
    return np.linalg.solve(R_d + info(A2), R_d @ theta_pre + rhs(A2, y2))


# ---------------------------------------------------------------- RLS.discard
@pytest.mark.parametrize("n_out", [1, 2])  # general path / fast path
def test_rls_discard_covariance_blocks(n_out):
    A, y = regime(TH1, n_out, 60, seed=1)
    est = feed(RLS(lam=0.98, p0=1e3), A, y)
    assert (est._ws is not None) == (n_out == 2)
    P = est.P_.copy()
    theta = np.array([1.0, 2.0, 3.0, 4.0])
    est.discard(IDX, [4.0, 9.0], theta=theta)
    np.testing.assert_array_equal(est.P_[np.ix_(KEEP, KEEP)], P[np.ix_(KEEP, KEEP)])
    np.testing.assert_array_equal(est.P_[np.ix_(IDX, IDX)], np.diag([4.0, 9.0]))
    np.testing.assert_array_equal(est.P_[np.ix_(IDX, KEEP)], 0.0)
    np.testing.assert_array_equal(est.P_[np.ix_(KEEP, IDX)], 0.0)
    np.testing.assert_array_equal(est.theta_, theta)
    # the next sample starts from the reset state: one RLS step by hand
    P0, phi = est.P_.copy(), A[0].T
    K = P0 @ phi @ np.linalg.inv(0.98 * np.eye(n_out) + phi.T @ P0 @ phi)
    est.update(A[0], y[0])
    np.testing.assert_allclose(est.theta_, theta + K @ (y[0] - phi.T @ theta), rtol=1e-12)
    np.testing.assert_allclose(est.P_, (P0 - K @ phi.T @ P0) / 0.98, rtol=1e-10, atol=1e-14)


def test_rls_discard_before_any_update():
    """A fresh RLS starts from p0 / theta0; without a size it says what it needs."""
    est = RLS(p0=1e3, theta0=np.zeros(4)).discard(IDX, 5.0, theta=TH1)
    expected = 1e3 * np.eye(4)
    expected[IDX, IDX] = 5.0
    np.testing.assert_array_equal(est.P_, expected)
    np.testing.assert_array_equal(est.theta_, TH1)
    with pytest.raises(ValueError, match="needs theta or theta0"):
        RLS().discard(IDX, 5.0)


@pytest.mark.parametrize("n_out", [1, 2])
def test_rls_discard_tracks_regime_change(n_out):
    p0, prior_var = 1e4, 1e2
    A1, y1 = regime(TH1, n_out, 150, seed=2)
    A2, y2 = regime(TH2, n_out, 150, seed=3)
    R_pre = np.eye(4) / p0 + info(A1)
    est = feed(RLS(p0=p0), A1, y1)
    np.testing.assert_allclose(est.theta_, np.linalg.solve(R_pre, rhs(A1, y1)), rtol=1e-8)
    theta_pre = est.theta_.copy()
    feed(est.discard(IDX, prior_var, theta=theta_pre), A2, y2)
    assert (est._ws is not None) == (n_out == 2)  # fast path rebuilt after the reset
    truth = reset_minimiser(R_pre, theta_pre, 1.0 / prior_var, A2, y2)
    np.testing.assert_allclose(est.theta_, truth, rtol=1e-7)
    np.testing.assert_allclose(est.theta_, TH2, atol=5e-3)
    # without the reset a lam = 1 RLS is the LS fit of both regimes: biased towards TH1
    plain = feed(feed(RLS(p0=p0), A1, y1), A2, y2)
    ls = np.linalg.solve(R_pre + info(A2), rhs(A1, y1) + rhs(A2, y2))
    np.testing.assert_allclose(plain.theta_, ls, rtol=1e-7)
    assert np.max(np.abs(plain.theta_ - TH2)) > 0.1


# ---------------------------------------------------------------- windowed Hopfield
def forgetting_ls(A, y, lam, floor=0.0):
    """W_k = lam W + A^T A (+ (1 - lam) floor), b_k likewise from W_0 = S^-2, b_0 = W_0 THN."""
    W, b = np.diag(1.0 / HW**2), THN / HW**2
    for A_k, y_k in zip(A, y, strict=True):
        W = lam * W + A_k.T @ A_k + (1.0 - lam) * np.diag(np.broadcast_to(floor, 4))
        b = lam * b + A_k.T @ y_k
    return W, b


@pytest.mark.parametrize("n_out", [1, 2])
def test_hopfield_window_follows_forgetting_ls(n_out):
    A, y = regime(TH1, n_out, 300, seed=4, noise=1e-2)
    W, b = forgetting_ls(A, y, 0.99)
    ls = np.linalg.solve(W, b)
    small = feed(Hopfield(THN, half_widths=HW, beta=1e-4, lam=0.99), A, y)
    np.testing.assert_allclose(small.W_, W, rtol=1e-10, atol=1e-12)
    np.testing.assert_allclose(small.b_, b, rtol=1e-10, atol=1e-12)
    np.testing.assert_allclose(small.theta_, ls, rtol=1e-6)
    large = feed(Hopfield(THN, half_widths=HW, beta=10.0, lam=0.99), A, y)
    err_large = np.max(np.abs(large.theta_ - ls))
    assert err_large > 100 * np.max(np.abs(small.theta_ - ls))
    assert np.all(np.abs(large.s_) < 1)


@pytest.mark.parametrize("beta", [1e-4, 10.0])
def test_hopfield_window_stays_inside_box(beta):
    th = TH1.copy()
    th[0] = THN[0] + 1.5 * HW[0]  # LS optimum outside the box
    A, y = regime(th, 2, 300, seed=5)
    est = Hopfield(THN, half_widths=HW, beta=beta, lam=0.99)
    lo, hi = THN - HW, THN + HW
    for A_k, y_k in zip(A, y, strict=True):
        est.update(A_k, y_k)
        assert np.all(np.abs(est.s_) < 1)
        assert np.all((lo < est.theta_) & (est.theta_ < hi))
    if beta < 1:
        assert est.s_[0] > 0.99  # pressed against the upper bound


def test_hopfield_discard_tracks_regime_change():
    A1, y1 = regime(TH1, 2, 150, seed=6)
    A2, y2 = regime(TH2, 2, 150, seed=7)
    W_pre = np.diag(1.0 / HW**2) + info(A1)
    est = feed(Hopfield(THN, half_widths=HW, beta=1e-4, lam=1.0), A1, y1)
    np.testing.assert_allclose(est.W_, W_pre, rtol=1e-10)
    theta_pre = est.theta_.copy()
    est.discard(IDX, theta=theta_pre)
    np.testing.assert_allclose(est.W_, reset_info(W_pre, 1.0 / HW[IDX] ** 2), rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(est.b_, est.W_ @ theta_pre, rtol=1e-12)
    np.testing.assert_allclose(est.theta_, theta_pre, rtol=1e-12)
    feed(est, A2, y2)
    truth = reset_minimiser(W_pre, theta_pre, 1.0 / HW[IDX] ** 2, A2, y2)
    np.testing.assert_allclose(est.theta_, truth, rtol=1e-6)
    np.testing.assert_allclose(est.theta_, TH2, atol=5e-3)
    plain = feed(feed(Hopfield(THN, half_widths=HW, beta=1e-4, lam=1.0), A1, y1), A2, y2)
    assert np.max(np.abs(plain.theta_ - TH2)) > 0.1


def test_hopfield_info_floor_prevents_windup():
    lam, floor, k = 0.95, np.full(4, 2.0), 400
    A1, y1 = regime(TH1, 2, 100, seed=8)
    A2, y2 = regime(TH1, 2, k, seed=9, unexcited=[3])  # then parameter 3 is not excited
    A_w = np.zeros((2, 4))
    A_w[0, 3] = 0.1  # finally one weak excitation of parameter 3 with an output error of 1
    y_w = A_w @ TH1 + np.array([1.0, 0.0])
    jump = {}
    for fl in (floor, None):
        est = feed(Hopfield(THN, half_widths=HW, beta=1e-4, lam=lam, info_floor=fl), A1, y1)
        theta_mid = est.theta_.copy()
        assert abs(theta_mid[3] - TH1[3]) < 1e-3  # identified while excited
        feed(est, A2, y2)
        W, _ = forgetting_ls(
            np.concatenate([A1, A2]), np.concatenate([y1, y2]), lam, 0.0 if fl is None else fl
        )
        np.testing.assert_allclose(est.W_, W, rtol=1e-9, atol=1e-12)
        assert abs(est.theta_[3] - theta_mid[3]) < 1e-3  # unexcited: stays where it was
        np.testing.assert_allclose(est.theta_[:3], TH1[:3], atol=1e-3)
        if fl is not None:
            assert est.W_[3, 3] >= (1.0 - lam**k) * floor[3]
        theta3 = est.theta_[3]
        jump[fl is None] = abs(est.update(A_w, y_w).theta_[3] - theta3)
    # LS step 0.1 * 1 / (W_33 + 0.01): ~0.05 with the floor; without it W_33 has decayed by
    # lam^k and the one weak sample throws theta_3 towards the bound (windup)
    assert jump[False] == pytest.approx(0.1 / (floor[3] + 0.01), rel=0.05)
    assert jump[True] > 0.5


def test_hopfield_window_argument_errors():
    with pytest.raises(ValueError, match="lam"):
        Hopfield(THN, half_widths=HW).discard(IDX)
    for lam in (0.0, -0.5, 1.5):
        with pytest.raises(ValueError, match="lam"):
            Hopfield(THN, half_widths=HW, lam=lam)
