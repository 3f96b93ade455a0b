"""Estimators against independent truths: synthetic linear models with known theta."""

import copy
import pickle

import numpy as np
import pytest

from guardid.estimators import (
    RLS,
    Gradient,
    Hopfield,
    LeastSquares,
    WeightedLeastSquares,
    d_tau,
    d_theta,
)
from guardid.estimators.hopfield import _sample_step


def model(N=2000, p=6, n=2, noise=(0.05, 0.05), seed=0, cond=None):
    """Random block regressor (N, n, p), theta (p,), noisy y (N, n)."""
    rng = np.random.default_rng(seed)
    A = rng.normal(size=(N, n, p))
    if cond is not None:  # columns scaled to make cond(A) ~ cond
        A = A * np.logspace(0, -np.log10(cond), p)
    th = rng.uniform(-1, 1, p)
    y = A @ th + rng.normal(size=(N, n)) * np.asarray(noise)
    return A, th, y


def rls_reference(A, y, lam, p0, every):
    """Straightforward per-sample RLS (seed 001 eqs. 5-7 with forgetting)."""
    p = A.shape[2]
    P, th, hist = p0 * np.eye(p), np.zeros(p), []
    for k in range(A.shape[0]):
        phi = A[k].T
        K = P @ phi @ np.linalg.inv(lam * np.eye(phi.shape[1]) + phi.T @ P @ phi)
        th = th + K @ (y[k] - phi.T @ th)
        P = (P - K @ phi.T @ P) / lam
        if (k + 1) % every == 0:
            hist.append(th)
    return th, P, np.array(hist)


# ---------------------------------------------------------------- LS / WLS
def test_ls_matches_lstsq_both_shapes():
    A, th, y = model()
    ref = np.linalg.lstsq(A.reshape(-1, A.shape[2]), y.ravel(), rcond=None)[0]
    m3 = LeastSquares().fit(A, y)
    m2 = LeastSquares().fit(A.reshape(-1, A.shape[2]), y.ravel())
    np.testing.assert_allclose(m3.theta_, ref, rtol=1e-10, atol=1e-12)
    np.testing.assert_allclose(m2.theta_, ref, rtol=1e-10, atol=1e-12)
    Am = A.reshape(-1, A.shape[2])
    assert m3.cond_ == pytest.approx(np.linalg.cond(Am), rel=1e-8)
    r = y.ravel() - Am @ ref
    assert m3.residual_rms_ == pytest.approx(np.sqrt(np.mean(r**2)), rel=1e-10)
    assert m3.residual_rms_per_output_.shape == (2,)
    np.testing.assert_allclose(m3.rel_std_, 100 * m3.std_ / np.abs(m3.theta_))


def test_ls_std_matches_empirical_spread():
    rng = np.random.default_rng(1)
    N, p = 300, 5
    A = rng.normal(size=(N, 2, p)) * np.array([1, 0.5, 2, 1, 0.2])
    th = rng.normal(size=p)
    ests, stds = [], []
    for _ in range(200):
        y = A @ th + 0.1 * rng.normal(size=(N, 2))
        m = LeastSquares().fit(A, y)
        ests.append(m.theta_)
        stds.append(m.std_)
    emp = np.std(ests, axis=0, ddof=1)
    np.testing.assert_allclose(np.mean(stds, axis=0), emp, rtol=0.15)


def test_ls_update_equals_batch_and_continues_fit():
    A, th, y = model(N=300)
    full = LeastSquares().fit(A, y)
    m = LeastSquares().fit(A[:100], y[:100])
    for k in range(100, 300):
        m.update(A[k], y[k])
    np.testing.assert_allclose(m.theta_, full.theta_, rtol=1e-10)
    np.testing.assert_allclose(m.std_, full.std_, rtol=1e-8)
    assert m.cond_ == pytest.approx(full.cond_, rel=1e-8)


def test_wls_beats_ols_with_unequal_joint_noise():
    rng = np.random.default_rng(2)
    N, p = 200, 6
    A = rng.normal(size=(N, 2, p))
    th = rng.normal(size=p)
    err_ols, err_wls, err_w3, sig = [], [], [], []
    for _ in range(100):
        y = A @ th + rng.normal(size=(N, 2)) * np.array([0.01, 1.0])
        o = LeastSquares().fit(A, y)
        w = WeightedLeastSquares().fit(A, y)
        w3 = WeightedLeastSquares(n_iter=3).fit(A, y)
        err_ols.append(o.theta_ - th)
        err_wls.append(w.theta_ - th)
        sig.append(w3.sigma_per_output_)
        err_w3.append(w3.theta_ - th)
        assert w.sigma_per_output_[0] < 0.2 * w.sigma_per_output_[1]
    mse_o, mse_w = np.mean(np.square(err_ols)), np.mean(np.square(err_wls))
    assert mse_w < 0.1 * mse_o
    np.testing.assert_allclose(np.mean(sig, axis=0), [0.01, 1.0], rtol=0.05)
    # iterated WLS: reported std agrees with the empirical spread; the single pass is
    # conservative (its sigma_1 is inflated by the OLS residual) but never optimistic
    np.testing.assert_allclose(w3.std_, np.std(err_w3, axis=0), rtol=0.2)
    assert np.all(w.std_ > np.std(err_wls, axis=0))


# ---------------------------------------------------------------- RLS
@pytest.mark.parametrize("lam", [1.0, 0.98])
@pytest.mark.parametrize("every", [1, 7])
def test_fast_rls_equals_reference(lam, every):
    A, th, y = model(N=1003, p=8)
    th_ref, P_ref, h_ref = rls_reference(A, y, lam, 100.0, every)
    f = RLS(lam=lam, p0=100.0, history_every=every).fit(A, y)
    np.testing.assert_allclose(f.theta_, th_ref, rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(f.P_, P_ref, rtol=1e-9, atol=1e-9 * np.abs(P_ref).max())
    np.testing.assert_allclose(f.history_, h_ref, rtol=1e-9, atol=1e-11)
    assert list(f.history_samples_) == list(range(every, 1004, every))


def test_rls_online_matches_reference_and_continues_fit():
    A, th, y = model(N=500, p=6)
    th_ref, P_ref, _ = rls_reference(A, y, 0.99, 10.0, 10)
    m = RLS(lam=0.99, p0=10.0).fit(A[:200], y[:200])
    for k in range(200, 500):
        m.update(A[k], y[k])
    np.testing.assert_allclose(m.theta_, th_ref, rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(m.P_, P_ref, rtol=1e-7, atol=1e-12)


def test_rls_stacked_and_three_outputs():
    A, th, y = model(N=300, p=5, n=3, noise=0.01)
    th_ref, _, _ = rls_reference(A, y, 1.0, 100.0, 10)
    np.testing.assert_allclose(RLS(p0=100.0).fit(A, y).theta_, th_ref, rtol=1e-9)
    on = RLS(p0=100.0)
    for k in range(300):
        on.update(A[k], y[k])
    np.testing.assert_allclose(on.theta_, th_ref, rtol=1e-9)
    As, ys = A.reshape(-1, 5), y.ravel()
    th1, _, _ = rls_reference(As[:, None, :], ys[:, None], 1.0, 100.0, 10)
    np.testing.assert_allclose(RLS(p0=100.0).fit(As, ys).theta_, th1, rtol=1e-9)


def test_rls_close_to_ls():
    A, th, y = model(N=3000, p=10)
    ls = LeastSquares().fit(A, y)
    r = RLS(lam=1.0, p0=1e8).fit(A, y)
    assert np.max(np.abs(r.theta_ - ls.theta_) / np.abs(ls.theta_)) < 1e-3


def rls_general(m, A, y):
    """Run RLS ``m`` over the samples through the reference per-sample step only."""
    for k in range(A.shape[0]):
        if not hasattr(m, "P_"):
            m._init_state(A.shape[2])
        m._update_general(A[k], y[k])
    return m


def assert_rls_state_close(a, b, rtol=1e-12):
    np.testing.assert_allclose(a.theta_, b.theta_, rtol=rtol, atol=rtol * np.abs(b.theta_).max())
    np.testing.assert_allclose(a.P_, b.P_, rtol=rtol, atol=rtol * np.abs(b.P_).max())
    assert a.n_samples_ == b.n_samples_


@pytest.mark.parametrize("lam", [1.0, 0.97])
@pytest.mark.parametrize("p", [6, 13])
def test_rls_fast_update_equals_general_step(lam, p):
    """The n_out = 2 fast path against the reference step over 700 random samples (crossing
    the symmetrisation every 64 samples), with list inputs mixed in (converted, then fast)."""
    A, th, y = model(N=700, p=p, seed=p)
    fast = RLS(lam=lam, p0=50.0)
    for k in range(700):
        if k % 97 == 5:
            fast.update(A[k].tolist(), y[k].tolist())
        else:
            fast.update(A[k], y[k])
        assert fast.P_ is fast._ws[1]  # every sample took the fast computations
    ref = rls_general(RLS(lam=lam, p0=50.0), A, y)
    assert_rls_state_close(fast, ref)
    np.testing.assert_allclose(fast.theta_, th, atol=0.05)


def test_rls_fast_update_continues_fit_and_picks_up_replaced_state():
    A, th, y = model(N=600, p=8)
    fast = RLS(lam=0.99, p0=10.0).fit(A[:200], y[:200])
    ref = RLS(lam=0.99, p0=10.0).fit(A[:200], y[:200])
    for k in range(200, 400):
        fast.update(A[k], y[k])
    rls_general(ref, A[200:400], y[200:400])
    assert_rls_state_close(fast, ref)
    # theta_ and P_ are new arrays after each fast update; replacing them is picked up
    old = fast.theta_
    fast.update(A[400], y[400])
    assert fast.theta_ is not old
    rls_general(ref, A[400:401], y[400:401])
    for m in (fast, ref):
        m.theta_ = m.theta_ + 0.1
        m.P_ = 2.0 * m.P_
    for k in range(401, 600):
        fast.update(A[k], y[k])
    rls_general(ref, A[401:], y[401:])
    assert_rls_state_close(fast, ref)
    # a refit restarts from the initial state
    fast.fit(A[:50], y[:50])
    for k in range(50, 100):
        fast.update(A[k], y[k])
    assert_rls_state_close(fast, rls_general(RLS(lam=0.99, p0=10.0), A[:100], y[:100]), 1e-9)


def test_rls_copy_and_pickle_mid_stream_continue_identically():
    A, th, y = model(N=300, p=7)
    m = RLS(lam=0.995, p0=10.0)
    for k in range(100):
        m.update(A[k], y[k])
    clones = [copy.deepcopy(m), pickle.loads(pickle.dumps(m))]
    for k in range(100, 300):
        m.update(A[k], y[k])
    for c in clones:
        for k in range(100, 300):
            c.update(A[k], y[k])
        np.testing.assert_array_equal(c.theta_, m.theta_)
        np.testing.assert_array_equal(c.P_, m.P_)


# ---------------------------------------------------------------- Hopfield
def box(p, half=2.0):
    return -half * np.ones(p), half * np.ones(p)


@pytest.mark.parametrize("fit_block", [1, 8])
def test_hopfield_converges_to_ls(fit_block):
    A, th, y = model(N=6000, p=6, noise=0.001)
    ls = LeastSquares().fit(A, y)
    h = Hopfield(bounds=box(6), beta=0.05, dt=0.015, fit_block=fit_block).fit(A, y)
    assert np.max(np.abs(h.theta_ - ls.theta_) / np.abs(ls.theta_)) < 0.01
    assert d_theta(h.theta_, th) < 0.01


def test_hopfield_fit_block1_equals_online_and_grouped_step():
    from guardid.estimators.hopfield import _run_blocks

    A, th, y = model(N=400, p=5)
    h = Hopfield(bounds=box(5), beta=0.02, dt=0.01, fit_block=1, history_every=50).fit(A, y)
    on = Hopfield(bounds=box(5), beta=0.02, dt=0.01)
    for k in range(400):
        on.update(A[k], y[k])
    np.testing.assert_allclose(h.theta_, on.theta_, rtol=1e-12, atol=1e-14)
    # the grouped step with K = 1 is the same step written with a p x p solve
    s, _, _ = _run_blocks(np.zeros(5), A * 2.0, y, 0.01 / 0.02, 1, 50)
    np.testing.assert_allclose(2.0 * s, h.theta_, rtol=1e-9, atol=1e-12)
    assert h.history_.shape == (8, 5)


@pytest.mark.parametrize("cond", [None, 1e2, 1e4])
def test_hopfield_stable_over_beta_dt_grid(cond):
    """No NaN, s inside (-1, 1) everywhere; convergence where the gain allows it in 1500
    samples (the weakly excited direction of an ill-conditioned A is slow by nature)."""
    A, th, y = model(N=1500, p=6, noise=0.0, cond=cond, seed=3)
    for beta in [1e-4, 1e-3, 1e-2, 1e-1, 1.0]:
        for dt in [1e-4, 1e-3, 1e-2, 1e-1, 1.0]:
            for fb in (1, 8):
                h = Hopfield(bounds=box(6), beta=beta, dt=dt, fit_block=fb).fit(A, y)
                assert np.all(np.isfinite(h.theta_)) and np.all(np.abs(h.s_) < 1)
                assert np.all(np.abs(h.history_ - h.center_) < h.scale_)
                err = np.max(np.abs(h.theta_ - th)) / np.max(np.abs(th))
                if cond is None and dt / beta >= 0.1:
                    assert err < 0.01, (beta, dt, fb)
                if cond == 1e2 and fb == 8 and dt / beta >= 100:
                    assert err < 1e-3, (beta, dt, fb)


def test_hopfield_tracks_step_and_respects_bounds():
    A, th, y = model(N=4000, p=6, noise=0.001)
    th2 = th.copy()
    th2[0] += 0.5
    y[2000:] = A[2000:] @ th2 + 0.001 * np.random.default_rng(9).normal(size=(2000, 2))
    h = Hopfield(bounds=box(6), beta=0.05, dt=0.015).fit(A[:2000], y[:2000])
    assert np.max(np.abs(h.theta_ - th)) < 0.01
    for k in range(2000, 4000):
        h.update(A[k], y[k])
    assert np.max(np.abs(h.theta_ - th2)) < 0.01
    # truth outside the box: estimate stays inside, pinned near the face
    hb = Hopfield(bounds=(th - 0.5, th + 0.5), theta_n=th, beta=0.05, dt=0.015).fit(A, y)
    assert np.all(hb.theta_ < th + 0.5) and hb.theta_[0] > th[0] + 0.45


def test_hopfield_half_widths_and_bad_args():
    h = Hopfield(theta_n=np.ones(3), half_widths=0.5)
    np.testing.assert_allclose(h.theta_, 1.0)
    with pytest.raises(ValueError):
        Hopfield(theta_n=np.ones(3), bounds=(np.zeros(3), 0.5 * np.ones(3)))
    with pytest.raises(ValueError):
        Hopfield(bounds=box(3), beta=0.0)


def hop_general(h, A, y):
    """s after running Hopfield ``h``'s step over the samples with the reference kernel."""
    s = h.s_.copy()
    for k in range(A.shape[0]):
        s = _sample_step(s, A[k] * h.scale_, y[k] - A[k] @ h.center_, h.beta / h.dt)
    return s


@pytest.mark.parametrize(("beta", "dt"), [(0.05, 0.015), (1e-4, 1.0), (1.0, 1e-3)])
def test_hopfield_fast_update_equals_general_step(beta, dt):
    """Fast path against the reference per-sample step, including fraction-to-boundary cuts
    (small beta: large steps) and a parameter pinned at its bound (truth outside the box)."""
    A, th, y = model(N=1500, p=12, noise=0.01, seed=4, cond=10)
    lo, hi = th - 0.4, th + 0.4
    hi[3] = th[3] - 0.1  # truth outside the box: s_3 pinned near +1
    h = Hopfield(bounds=(lo, hi), beta=beta, dt=dt)
    s_ref = hop_general(h, A, y)
    for k in range(1500):
        h.update(A[k], y[k])
        assert h.s_ is h._ws_s  # every sample took the fast computations
    np.testing.assert_allclose(h.s_, s_ref, rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(h.theta_, h.center_ + h.scale_ * s_ref, rtol=1e-12, atol=1e-12)
    assert np.all(np.abs(h.s_) < 1)
    if dt / beta >= 0.1:
        assert h.s_[3] > 0.99
    assert h.n_samples_ == 1500


def test_hopfield_fast_update_clips_at_the_last_double_below_one():
    """From s_0 = largest double below 1, a small push upward rounds s_0 to 1.0; the fast path
    must clip it back exactly like the reference step."""
    A, th, y = model(N=50, p=4, noise=0.0, seed=5)
    h = Hopfield(bounds=box(4), beta=0.05, dt=0.015)
    s0 = np.array([np.nextafter(1.0, 0.0), 0.2, -0.3, 0.1])
    h.s_ = s0.copy()  # a replaced s_ is picked up
    y = A @ (2.0 * np.array([1.0, 0.2, -0.3, 0.1]) + np.array([0.5, 0, 0, 0]))
    s_ref = hop_general(h, A, y)
    for k in range(50):
        h.update(A[k], y[k])
        assert h.s_[0] < 1.0
    np.testing.assert_allclose(h.s_, s_ref, rtol=1e-12, atol=1e-13)
    assert h.s_[0] == np.nextafter(1.0, 0.0)


def test_hopfield_general_path_other_output_counts_and_copies():
    A, th, y = model(N=200, p=5, n=3, noise=0.01)
    h = Hopfield(bounds=box(5), beta=0.02, dt=0.01)
    s_ref = hop_general(h, A, y)
    for k in range(200):
        h.update(A[k], y[k])
    np.testing.assert_allclose(h.s_, s_ref, rtol=1e-12, atol=1e-14)
    # 2 outputs, mid-stream copies continue exactly like the original
    A, th, y = model(N=300, p=5)
    h = Hopfield(bounds=box(5), beta=0.02, dt=0.01)
    for k in range(100):
        h.update(A[k], y[k])
    clones = [copy.deepcopy(h), pickle.loads(pickle.dumps(h))]
    for m in [h] + clones:
        for k in range(100, 300):
            m.update(A[k], y[k])
    for c in clones:
        np.testing.assert_array_equal(c.s_, h.s_)
        np.testing.assert_array_equal(c.theta_, h.theta_)


# ---------------------------------------------------------------- Gradient
def test_gradient_converges_small_eta_and_diverges_large_eta():
    A, th, y = model(N=5000, p=6, noise=0.001)
    g = Gradient(eta=0.02).fit(A, y)
    assert not g.diverged_ and np.max(np.abs(g.theta_ - th)) < 0.01
    bad = Gradient(eta=2.0).fit(A, y)
    assert bad.diverged_ and bad.diverged_at_ < 5000
    on = Gradient(eta=2.0)
    for k in range(3000):
        on.update(A[k], y[k])
    assert on.diverged_
    gs = Gradient(eta=0.02).fit(A.reshape(-1, 6), y.ravel())
    assert np.max(np.abs(gs.theta_ - th)) < 0.01


# ---------------------------------------------------------------- metrics
def test_metrics():
    assert d_theta([1.0, 2.0], [1.0, 2.0]) == 0.0
    assert d_theta([2.0, 0.0], [1.0, 0.0]) == pytest.approx(2 / 2 * (1 / 3))
    A, th, y = model(N=100, noise=0.0)
    assert d_tau(A, y, th) < 1e-12
    per = d_tau(A, y, np.zeros_like(th), per_joint=True)
    np.testing.assert_allclose(per, [1.0, 1.0])
    assert d_tau(A.reshape(-1, 6), y.ravel(), np.zeros(6)) == pytest.approx(1.0)


def test_hopfield_settle_reaches_the_box_constrained_least_squares():
    """Settling with the log's weights: LS inside the box; the box face when LS is outside."""
    rng = np.random.default_rng(7)
    A = rng.normal(size=(3000, 2, 5))
    theta = np.array([1.0, -2.0, 0.5, 3.0, 0.0])
    y = A @ theta + 0.05 * rng.normal(size=(3000, 2))
    ls = LeastSquares().fit(A, y).theta_
    h = Hopfield(theta_n=0.5 * theta + 0.1, half_widths=4.0, beta=0.3, dt=0.01).fit(A, y)
    h.settle(A, y)
    assert np.allclose(h.theta_, ls, rtol=0, atol=1e-9)
    # a box that excludes the truth of parameter 3: the estimate sits at (just inside) the face
    tight = Hopfield(theta_n=np.zeros(5), bounds=(-np.full(5, 2.5), np.full(5, 2.5)), beta=0.3)
    tight.fit(A, y).settle(A, y)
    assert np.all(np.abs(tight.s_) < 1.0) and tight.theta_[3] > 2.49
    assert np.all(np.isfinite(tight.theta_))


def test_least_squares_r_is_scipys_qr_of_the_weighted_rows_bit_for_bit():
    """Issue 30 (memory): LS and WLS factor [A y] in place and copy out only R's top rows;
    R, theta and the row count are those of scipy.linalg.qr(mode='r') of the weighted,
    stacked [A y] (rows i * n + j), to the last bit. A is not C-ordered, as identify's is."""
    from scipy.linalg import qr

    from guardid.estimators import LeastSquares, WeightedLeastSquares

    rng = np.random.default_rng(3)
    A = np.transpose(rng.normal(size=(5, 300, 2)), (1, 2, 0))  # (N, n, p), not C-ordered
    A[40:60, 1] = 0.0  # a cut joint's equations: zero rows
    y = A @ np.arange(1.0, 6.0) + 0.1 * rng.normal(size=(300, 2))
    y[40:60, 1] = 0.0
    for est in (LeastSquares().fit(A, y), WeightedLeastSquares().fit(A, y)):
        w = np.tile(est._w, 300)[:, None]
        R = qr(np.column_stack([A.reshape(600, 5), y.reshape(600)]) * w, mode="r")[0]
        assert np.array_equal(est.R_, R[:5, :5]) and np.array_equal(est.z_, R[:5, 5])
        assert est.rss_ == R[5, 5] ** 2 and est.n_rows_ == 580
