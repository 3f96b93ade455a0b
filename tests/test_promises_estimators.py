"""Promises of the estimators and the online detector that no test defended (issue 26,
deliverable 7), each against a truth worked out by hand or computed independently in numpy:

* the change detector's default CUSUM: a bias of m sigma fires after the first row at which
  rows x (m - kappa) exceeds h (kappa = 4 sigma, h = 40 sigma rows);
* IDIM-IV's covariance s^2 (Z^T A)^-1 Z^T Z (A^T Z)^-1 with instruments Z != A (and the
  spread of its estimates over noise draws);
* DIDIM re-weights its rows from the simulated regressor's residual y - Z theta;
* WLS's per-joint sigma_j^2 = ||r_j||^2 / (N - p_j) on a small problem solved by hand;
* a negative rotor inertia is flagged and bounded at 0 by ``bls``;
* the online RLS's covariance reset puts the prior half-width *squared* on the diagonal.
"""

from __future__ import annotations

import numpy as np
import pytest
import synthetic

from guardid.closedloop.fit import closed_loop_fit, iv_solve
from guardid.estimators import WeightedLeastSquares
from guardid.identify import IdentifyOptions, identify, run_from_arrays
from guardid.online import ChangeDetector, DetectorSettings
from guardid.online.detector import Alarm
from guardid.online.tracker import OnlineIdentifier
from guardid.robot import load_robot

DT = 0.015


# ---------------------------------------------------------------- (c) detector's default kappa
def _armed_detector(s: float = 0.5) -> tuple[ChangeDetector, float]:
    """A default-settings detector armed on residuals of exactly +-s (sigma = s)."""
    det = ChangeDetector(("MX2R", "MY2"), n_joints=2, method="rls", settings=DetectorSettings())
    t, k = 0.0, 0
    while det.state != "armed":
        sign = 1.0 if k % 2 else -1.0
        assert det.update(t, np.array([True, True]), [sign * s, sign * s], [0.77, 0.07]) is None
        t, k = t + DT, k + 1
    assert det.sigma == pytest.approx([s, s], rel=1e-12)
    return det, t


def _rows_to_alarm(m: float, limit: int = 3000, s: float = 0.5) -> int | None:
    """Rows of a constant m-sigma bias on joint 0 until the default detector fires."""
    det, t = _armed_detector(s)
    for k in range(1, limit + 1):
        if det.update(t, np.array([True, True]), [m * s, 0.0], [0.77, 0.07]) is not None:
            return k
        t += DT
    return None


def test_default_cusum_fires_after_h_over_m_minus_kappa_rows():
    """The documented CUSUM G <- max(0, G + z - kappa) with the design values kappa = 4
    sigma and h = 40 sigma rows: a 6-sigma bias adds 2 per row, 40 after 20 rows (not yet
    over h), 42 after 21; an 8-sigma bias adds 4: 44 after 11 rows. A 3.9-sigma bias (below
    kappa) never accumulates. kappa or h 10 % off moves these counts (4.4: 26 rows; 3.6: 17;
    h 44: 23; h 36: 19)."""
    kappa, h = 4.0, 40.0
    for m in (6.0, 8.0):
        expected = int(np.floor(h / (m - kappa))) + 1
        assert _rows_to_alarm(m) == expected, m
    assert _rows_to_alarm(3.9) is None


# ---------------------------------------------------------------- (f) IV covariance, Z != A
def _iv_problem(seed=0, M=300):
    """Rows A (M, 2, 4) of two joints sharing parameters, instruments Z correlated with A
    but different, y = A theta + noise of a different scale per joint."""
    rng = np.random.default_rng(seed)
    Z = rng.normal(size=(M, 2, 4))
    A = 0.8 * Z + 0.6 * rng.normal(size=(M, 2, 4)) + 0.3 * Z[:, :, ::-1]
    theta = np.array([1.0, -2.0, 0.5, 3.0])
    return A, Z, theta, rng


def test_iv_covariance_with_instruments_unlike_the_regressor():
    A, Z, theta, rng = _iv_problem()
    y = A @ theta + rng.normal(size=(len(A), 2)) * [0.2, 1.5]
    w = np.array([5.0, 0.7])
    # independently: the weighted stacked rows and the textbook IV formulas
    Aw = np.concatenate([A[:, 0] * w[0], A[:, 1] * w[1]])
    Zw = np.concatenate([Z[:, 0] * w[0], Z[:, 1] * w[1]])
    yw = np.concatenate([y[:, 0] * w[0], y[:, 1] * w[1]])
    th = np.linalg.solve(Zw.T @ Aw, Zw.T @ yw)
    r = yw - Aw @ th
    s2 = r @ r / (len(yw) - 4)
    ZA_inv = np.linalg.inv(Zw.T @ Aw)
    cov = s2 * ZA_inv @ (Zw.T @ Zw) @ np.linalg.inv(Aw.T @ Zw)
    got_theta, got_cov = iv_solve(A, y, Z, w)
    np.testing.assert_allclose(got_theta, th, rtol=1e-10)
    np.testing.assert_allclose(got_cov, cov, rtol=1e-9, atol=1e-15)
    # the problem tells the two orders apart (Z^T A is not symmetric)
    swapped = s2 * ZA_inv.T @ (Zw.T @ Zw) @ ZA_inv
    assert np.max(np.abs(swapped - cov) / np.sqrt(np.outer(np.diag(cov), np.diag(cov)))) > 0.05


def test_iv_std_matches_the_spread_over_noise_draws():
    """Monte Carlo: 2000 noise draws on fixed A, Z (sigma 1 per joint, weights 1): the
    empirical covariance of the IV estimates matches iv_solve's (diagonal within 10 %: the
    sampling error of a variance from 2000 draws is ~3 %)."""
    A, Z, theta, rng = _iv_problem(seed=1, M=200)
    w = np.ones(2)
    draws = np.array(
        [iv_solve(A, A @ theta + rng.normal(size=(len(A), 2)), Z, w)[0] for _ in range(2000)]
    )
    emp = np.cov(draws.T)
    _, cov = iv_solve(A, A @ theta + rng.normal(size=(len(A), 2)), Z, w)
    np.testing.assert_allclose(np.diag(emp), np.diag(cov), rtol=0.10)
    assert np.all(np.abs(draws.mean(axis=0) - theta) <= 4 * np.sqrt(np.diag(cov) / 2000))


# ---------------------------------------------------------------- (g) DIDIM's weights from Z
def test_didim_reweights_from_the_simulated_regressors_residual():
    """A fixed simulated regressor Z, block-separable (joint 0: parameters 0, 1; joint 1: 2,
    3): DIDIM's estimate is per-joint OLS of y on Z whatever the weights, and with weights
    1 / sigma_j from y - Z theta its covariance is sigma_j^2 (Z_j^T Z_j)^-1 per joint exactly
    (the pooled s^2 is then 1). The measured A differs from Z on joint 1 only, so weights
    from y - A theta would give another covariance."""
    rng = np.random.default_rng(4)
    M = 250
    Z = np.zeros((M, 2, 4))
    Z[:, 0, :2] = rng.normal(size=(M, 2))
    Z[:, 1, 2:] = rng.normal(size=(M, 2))
    y = Z @ np.array([1.0, 2.0, -1.0, 0.5]) + rng.normal(size=(M, 2)) * [0.05, 0.8]
    A = Z.copy()
    A[:, 1, 2:] += rng.normal(size=(M, 2))  # the measured motion's regressor differs
    truth_theta, truth_std = np.zeros(4), np.zeros(4)
    for j, cols in enumerate((slice(0, 2), slice(2, 4))):
        Zj = Z[:, j, cols]
        th, *_ = np.linalg.lstsq(Zj, y[:, j], rcond=None)
        r = y[:, j] - Zj @ th
        truth_theta[cols] = th
        truth_std[cols] = np.sqrt(r @ r / (M - 2) * np.diag(np.linalg.inv(Zj.T @ Zj)))
    start = truth_theta + 5 * truth_std  # a few simulations to settle (half steps)
    est = closed_loop_fit("didim", A, y, start, lambda theta: Z)
    assert est.converged and est.iterations >= 3
    np.testing.assert_allclose(est.theta_, truth_theta, rtol=1e-10)
    np.testing.assert_allclose(est.std_, truth_std, rtol=1e-9)


# ---------------------------------------------------------------- (h) WLS sigma_j dof
def test_wls_sigma_per_joint_with_n_minus_p_j_by_hand():
    """Joint 0: a line y = a + b x through (0, 0), (1, 1), (2, 1), (3, 3): b = 4.5 / 5 =
    0.9, a = -0.1, residuals 0.1, 0.2, -0.7, 0.4, RSS 0.70 over N - p_0 = 4 - 2 rows:
    sigma_0^2 = 0.35. Joint 1: a constant through 1, 2, 3, 6: 3, residuals -2, -1, 0, 3, RSS
    14 over 4 - 1: sigma_1^2 = 14 / 3. The joints share no parameter, so the weighted s^2 =
    (2 + 3) / (8 - 3) = 1 and the std are per-joint OLS's: a sqrt(0.35 (1/4 + 1.5^2 / 5)),
    b sqrt(0.35 / 5), the constant sqrt(14 / 3 / 4)."""
    x = np.arange(4.0)
    A = np.zeros((4, 2, 3))
    A[:, 0, 0], A[:, 0, 1], A[:, 1, 2] = 1.0, x, 1.0
    y = np.column_stack([[0.0, 1.0, 1.0, 3.0], [1.0, 2.0, 3.0, 6.0]])
    w = WeightedLeastSquares().fit(A, y)
    np.testing.assert_allclose(w.sigma_per_output_, np.sqrt([0.35, 14 / 3]), rtol=1e-12)
    np.testing.assert_allclose(w.theta_, [-0.1, 0.9, 3.0], rtol=1e-12)
    np.testing.assert_allclose(w.std_, np.sqrt([0.245, 0.07, 14 / 12]), rtol=1e-10)


# ---------------------------------------------------------------- (k) negative rotor inertia
def test_negative_rotor_inertia_is_flagged_and_bls_keeps_it_at_zero():
    """Pendulum data (closed-form model) whose rotor inertia is negative (Ia2 = 36 x
    -7.66e-5 = -2.76e-3 kg m^2, impossible): LS follows it below 0; the warning names Ia2 as
    a negative rotor inertia, and bls holds it at its bound 0."""
    saved = dict(synthetic.P)
    synthetic.P["Ir"] = -synthetic.P["Ir"]
    try:
        t, q, tau = synthetic.log(500, 0.5, 5.0, 5, duration_s=20.0)
    finally:
        synthetic.P.update(saved)
    run = run_from_arrays(t, q, tau, torque=True)
    r = identify([run], load_robot("dfki_double_pendulum"), IdentifyOptions(methods=("ls", "bls")))
    k = r.names.index("Ia2")
    ls = r.results["ls"]
    assert ls.theta[k] < -5 * ls.std[k]  # clearly negative
    assert any(w.startswith("Ia2 = ") and "negative rotor inertia" in w for w in r.warnings)
    assert r.results["bls"].theta[k] == 0.0


# ---------------------------------------------------------------- (m) RLS covariance reset
def test_online_rls_reset_puts_the_half_width_squared_on_the_diagonal():
    """After a detected change the RLS forgets every parameter but friction: their variance
    becomes the prior half-width squared [(kg m^2)^2, (kg m)^2]. Guard's half-widths by hand
    (guard.yaml): the largest inertia-kind base value ZZ2R = ZZ2 + Ia2 + 0.2 MX2 + 0.01 M2 =
    (0.30 + 3.5 (0.12^2 + 0.02^2)) + 1000^2 2e-6 + 0.2 (3.5 0.12) + 0.01 3.5 = 2.4708;
    the largest first moment MX2R = 3.5 0.12 + 0.1 3.5 = 0.77."""
    ident = OnlineIdentifier(load_robot("guard"), methods=("rls",), detector=False)
    est = ident.estimators["rls"]
    before = ident.nominal * 1.1
    ident._restart_at("rls", est, Alarm(0.0, 0.0, before, 0.0))
    names = ident.names
    var = np.diag(est.P_)
    inertia = [n for n in names if n[:2] in ("ZZ", "XX", "XY", "XZ", "YZ")]
    moments = [n for n in names if n[:2] in ("MX", "MY")]
    assert len(inertia) == 6 and len(moments) == 2
    for n in inertia:
        assert var[names.index(n)] == pytest.approx(2.4708**2, rel=1e-4), n
    for n in moments:
        assert var[names.index(n)] == pytest.approx(0.77**2, rel=1e-9), n
    P = est.P_
    changing = [names.index(n) for n in inertia + moments]
    off = P[np.ix_(changing, changing)] - np.diag(np.diag(P)[changing])
    assert np.all(off == 0.0)
    np.testing.assert_array_equal(est.theta_, before)
