"""Bias-compensated least squares for the encoder's rounding in the momentum form's columns
(guardid.estimators.ls ColumnNoise, guardid.conditioning.momentum.quantisation_noise,
identify's rows; issue 27).

Independent truths: the errors-in-variables attenuation of least squares in closed form
(a column measured with noise of variance s2 shrinks its coefficient by var_x / (var_x +
s2)), the spread of the estimates over seeds, and the noise a filtered velocity difference
of rounded positions carries, worked out from the filter's impulse response.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
from scipy.signal import sosfilt

from guardid.conditioning import momentum as mom
from guardid.conditioning.options import ConditioningOptions
from guardid.conditioning.units import counts_per_joint_rev
from guardid.dynamics import build_model
from guardid.estimators import ColumnNoise, LeastSquares, WeightedLeastSquares
from guardid.identify.equation import drive_gain
from guardid.identify.rows import stacked_rows
from guardid.robot import load_robot


def _eiv(rng, m=4000, s2=0.25, kappa=0.0, scale=(1.0, 1.0)):
    """Two outputs, two parameters; column 0 measured with noise of variance s2 (per row,
    output j's noise scaled by scale[j]), y carrying kappa times that noise as well."""
    theta = np.array([2.0, -1.0])
    A_true = rng.normal(size=(m, 2, 2))
    noise = np.zeros_like(A_true)
    noise[:, :, 0] = rng.normal(size=(m, 2)) * np.sqrt(s2) * np.asarray(scale)
    y = A_true @ theta + kappa * noise[:, :, 0] + 0.05 * rng.normal(size=(m, 2))
    gram = np.zeros((2, 2, 2))
    gram[:, 0, 0] = m * s2 * np.asarray(scale) ** 2
    cross = np.zeros((2, 2))
    cross[:, 0] = kappa * m * s2 * np.asarray(scale) ** 2
    return theta, A_true + noise, y, ColumnNoise(gram, cross)


def test_compensated_ls_removes_the_errors_in_variables_bias():
    """Plain LS shrinks the noisy column's coefficient by 1 / (1 + s2) (unit-variance
    columns), the closed form; with the noise's Gram removed it recovers the truth; noise in
    y correlated with the column's (kappa) biases plain LS by kappa s2 / (1 + s2) more, and
    the cross moment removes that too."""
    rng = np.random.default_rng(3)
    theta, A, y, noise = _eiv(rng, kappa=0.5)
    plain = LeastSquares().fit(A, y)
    want = (theta[0] + 0.5 * 0.25) / 1.25  # attenuated, plus kappa's share
    assert plain.theta_[0] == pytest.approx(want, abs=0.02)
    assert not plain.compensated_
    comp = LeastSquares(noise).fit(A, y)
    assert comp.compensated_
    assert np.abs(comp.theta_ - theta).max() < 0.03
    no_cross = LeastSquares(ColumnNoise(noise.gram, np.zeros((2, 2)))).fit(A, y)
    assert no_cross.theta_[0] == pytest.approx(theta[0] + 0.5 * 0.25, abs=0.03)


def test_compensated_wls_weights_the_noise_per_output_and_its_std_holds():
    """WLS with outputs of different noise: the Gram is weighted per output like its rows;
    over 150 seeds the compensated estimates centre on the truth (plain WLS's do not) and
    their spread matches the reported std (the sandwich covariance) within 20 %."""
    est, std, plain = [], [], []
    for seed in range(150):
        rng = np.random.default_rng(100 + seed)
        theta, A, y, noise = _eiv(rng, m=600, s2=0.3, scale=(1.0, 2.0))
        w = WeightedLeastSquares(column_noise=noise).fit(A, y)
        assert w.compensated_
        est.append(w.theta_)
        std.append(w.std_)
        plain.append(WeightedLeastSquares().fit(A, y).theta_)
    est, std, plain = np.array(est), np.array(std), np.array(plain)
    se = std.mean(0) / np.sqrt(len(est))
    assert np.all(np.abs(est.mean(0) - theta) < 4 * se)
    assert abs(plain.mean(0)[0] - theta[0]) > 20 * se[0]
    ratio = est.std(0, ddof=1) / std.mean(0)
    assert np.all((ratio > 0.8) & (ratio < 1.2)), ratio


def test_a_noise_larger_than_the_rows_leaves_the_plain_estimate():
    """A Gram that would make the normal matrix indefinite is not removed: the estimate is
    plain LS's and says so."""
    rng = np.random.default_rng(5)
    _, A, y, noise = _eiv(rng)
    huge = ColumnNoise(noise.gram * 100.0, noise.cross)
    comp = LeastSquares(huge).fit(A, y)
    assert not comp.compensated_
    np.testing.assert_allclose(comp.theta_, LeastSquares().fit(A, y).theta_, rtol=1e-10)


def test_on_grid_accepts_whole_counts_from_any_offset_only():
    """Positions that are whole steps from an offset lie on the grid; a third of a step
    off in one sample does not."""
    res = np.array([0.01, 0.002])
    counts = np.array([[0, 0], [3, -7], [-12, 40], [5, 5]])
    q = counts * res + np.array([0.0043, -0.0009])
    assert mom.on_grid(q, res).tolist() == [True, True]
    q[2, 1] += res[1] / 3
    assert mom.on_grid(q, res).tolist() == [True, False]


def _moving_run(seconds=600.0):
    """Guard positions [rad] that never slow down (one way plus a wobble), rounded to the
    encoder's counts, on the tick grid, with zero current: rows without cuts."""
    desc = load_robot("guard")
    dt = desc.sample_period
    t = np.arange(int(seconds / dt)) * dt
    q = np.column_stack([0.5 * t + 0.1 * np.sin(2 * np.pi * 0.4 * t),
                         0.3 * t + 0.05 * np.sin(2 * np.pi * 0.7 * t)])  # fmt: skip
    res = 2 * np.pi / counts_per_joint_rev(desc)
    return desc, t, np.round(q / res) * res, res


def test_noise_of_a_momentum_column_matches_the_closed_form():
    """ZZ1R's column in the pan's rows is the filtered change of the pan's stencil velocity
    (its momentum): the rounding error e (uniform over a count, variance res^2 / 12, white)
    enters it as (e_(k+1) - e_k - e_(k-1) + e_(k-2)) / (2 T), filtered by h and divided by T:
    variance res^2 / 12 ||h * [1, -1, -1, 1]||^2 / (4 T^4) per row. The estimate (windows
    over a 40 000-tick run, scaled to its rows) is within 15 % of that times the rows;
    the Coulomb columns, whose sign does not change while the joint moves, carry none."""
    desc, t, q, res = _moving_run()
    model = build_model(desc)
    gain = drive_gain(desc)
    cond, _, _ = mom.condition_momentum(t, q, np.zeros_like(q), model, gain=gain,
                                        cutoff_hz=2.0, stiction_threshold=0.0)  # fmt: skip
    state = cond.momentum
    rows = state.row_mask.sum(axis=0)
    assert rows.min() > 2000
    S, _ = mom.quantisation_noise(state, model, res, mom.electrical_damping(desc, gain))
    x = np.zeros(4096)
    x[0] = 1.0
    g = np.convolve(sosfilt(state.sos, x), [1.0, -1.0, -1.0, 1.0])
    dt = state.dt
    per_row = res[0] ** 2 / 12.0 * np.sum(g**2) / (4.0 * dt**4)
    names = list(model.base.names)
    zz1 = names.index("ZZ1R")
    assert S[0, zz1, zz1] == pytest.approx(rows[0] * per_row, rel=0.15)
    for j in (1, 2):
        fc = names.index(f"Fc{j}")
        assert S[j - 1, fc, fc] <= 1e-9 * S[0, zz1, zz1]


def _swinging_run(seconds=60.0):
    """Guard positions [rad] inside its limits (sums of sines), rounded to whole counts."""
    desc = load_robot("guard")
    dt = desc.sample_period
    t = np.arange(int(seconds / dt)) * dt
    w = 2 * np.pi * t
    q = np.column_stack([0.6 * np.sin(0.23 * w) + 0.3 * np.sin(0.61 * w),
                         0.2 + 0.2 * np.sin(0.31 * w) + 0.1 * np.sin(0.83 * w)])  # fmt: skip
    res = 2 * np.pi / counts_per_joint_rev(desc)
    return desc, t, np.round(q / res) * res, res


def _rows(desc, q, t, **options):
    return stacked_rows([(t, q, np.zeros_like(q))], desc,
                        ConditioningOptions(cutoff_hz=2.0, **options))  # fmt: skip


def test_rows_compensate_only_what_the_log_allows():
    """Every branch: whole counts -> compensated (recorded true); positions off the grid,
    measured velocities, a joint without an encoder -> not (recorded false, the reason in
    the notes); --no-quantisation-compensation -> not; a recorded true (options reused on
    another log) -> where that log allows."""
    desc, t, q, res = _swinging_run()
    r = _rows(desc, q, t)
    assert r.column_noise is not None and r.options.quantisation is True
    assert r.column_noise.gram.shape == (2, r.A.shape[2], r.A.shape[2])
    off = q.copy()
    off[::7, 1] += res[1] / 3
    r = _rows(desc, off, t)
    assert r.column_noise is None and r.options.quantisation is False
    assert any("off the encoder's grid" in n for n in r.cond.notes)
    r = _rows(desc, off, t, quantisation=True)  # a params file's record: where it can
    assert r.column_noise is None and r.options.quantisation is False
    r = _rows(desc, q, t, quantisation=False)
    assert r.column_noise is None and r.options.quantisation is False
    measured = stacked_rows([(t, q, np.zeros_like(q), np.gradient(q, t, axis=0))], desc,
                            ConditioningOptions(cutoff_hz=2.0))  # fmt: skip
    assert measured.column_noise is None
    assert any("measured velocities" in n for n in measured.cond.notes)
    bare = replace(desc, joints=tuple(replace(j, encoder=None) for j in desc.joints))
    r = _rows(bare, q, t)
    assert r.column_noise is None
    assert any("without an encoder" in n for n in r.cond.notes)


def test_cross_moment_of_the_back_emf_slope_matches_a_monte_carlo():
    """c_j = E[dA_j^T dy_j] (``quantisation_noise``'s second moment, summed over joint j's
    usable rows): the rounding error reaches the impulses through the back-EMF slope term
    -D (s_k - s_(k-1)) of the stencil's velocities, and the viscous column through the same
    slope's + Fv share, so the Fv column's cross moment is about -D E[slope^2] < 0.
    Independent truth: 200 fresh draws of e uniform over one count added to the counts of a
    20 s run that never slows (no period changes its direction or its cut), the whole
    momentum rows formed again (``condition_momentum``) and dA^T dy averaged over the draws
    on every usable row. The estimate (100 draws of its own, another seed) lies within 4
    standard errors of that mean (from the spread of the draws, both averages counted) for
    every column; on the Fv columns, whose moment stands 10 standard errors clear of 0, the
    sign is the Monte Carlo's."""
    desc, t, q, res = _moving_run(20.0)
    assert np.all(np.abs(np.diff(q, axis=0)).min(axis=0) > 2 * res)  # directions stay
    model = build_model(desc)
    gain = drive_gain(desc)
    damping = mom.electrical_damping(desc, gain)
    assert damping.min() > 0.0
    kw = {"gain": gain, "cutoff_hz": 2.0, "stiction_threshold": 0.0}
    cond, A, y = mom.condition_momentum(t, q, np.zeros_like(q), model, **kw)
    _, c = mom.quantisation_noise(cond.momentum, model, res, damping, draws=100)
    rng = np.random.default_rng(1)
    draws = []
    for _ in range(200):
        q_e = q + (rng.random(q.shape) - 0.5) * res
        cond_e, A_e, y_e = mom.condition_momentum(t, q_e, np.zeros_like(q), model, **kw)
        np.testing.assert_array_equal(cond_e.joint_mask, cond.joint_mask)
        draws.append(np.einsum("mja,mj->ja", A_e - A, y_e - y))
    draws = np.array(draws)
    mean = draws.mean(axis=0)
    se = draws.std(axis=0, ddof=1) * np.sqrt(1 / 200 + 1 / 100)
    floor = 1e-9 * np.abs(mean).max()  # the columns without noise (Coulomb, offset)
    z = (c - mean) / (se + floor)
    assert np.all(np.abs(z) <= 4.0), np.round(z, 1).tolist()
    names = list(model.base.names)
    for j in range(2):
        fv = names.index(f"Fv{j + 1}")
        assert mean[j, fv] < -10 * se[j, fv]
        assert c[j, fv] < 0.0
