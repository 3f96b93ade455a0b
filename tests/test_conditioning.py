"""Synthetic tests of guardid.conditioning (deterministic, a few seconds in all)."""

from __future__ import annotations

import numpy as np
import pytest
from capturetools import VARIANT

from guardid.conditioning import (
    CausalConditioner,
    align_period_mean,
    choose_cutoff,
    condition,
    counts_per_joint_rev,
    counts_to_rad,
    decimation_factor,
    drive_gain,
    stiction_mask,
)
from guardid.robot import load_robot

T = 0.015  # s, guard sample period
DURATION = 60.0  # s
# Sum of sines per joint: (amplitude [rad], frequency [Hz], phase [rad]); highest 0.4 Hz.
HARMONICS = (
    ((0.6, 0.1, 0.0), (0.25, 0.25, 1.0), (0.08, 0.4, 2.0)),
    ((0.3, 0.15, 0.5), (0.12, 0.3, 2.5), (0.04, 0.4, 0.3)),
)
F_MAX = 0.4  # Hz


def analytic(t):
    """q, qd, qdd (N, 2) of the sum-of-sines trajectory at times t [s]."""
    q, qd, qdd = (np.zeros((len(t), 2)) for _ in range(3))
    for j, terms in enumerate(HARMONICS):
        for a, f, ph in terms:
            w = 2 * np.pi * f
            q[:, j] += a * np.sin(w * t + ph)
            qd[:, j] += a * w * np.cos(w * t + ph)
            qdd[:, j] -= a * w * w * np.sin(w * t + ph)
    return q, qd, qdd


def encoder_positions(t, seed=0):
    """Positions [rad] as the guard's encoders report them: 24000 / 48000 counts per joint
    revolution, plus Gaussian noise of 0.5 count before quantisation."""
    cpr = counts_per_joint_rev(load_robot("guard"))
    q, _, _ = analytic(t)
    noise = np.random.default_rng(seed).normal(0.0, 0.5, q.shape)
    counts = np.floor(q * cpr / (2 * np.pi) + noise)
    return counts_to_rad(counts, cpr)


def test_counts_per_rev_and_radians():
    guard = load_robot("guard")
    cpr = counts_per_joint_rev(guard)
    np.testing.assert_allclose(cpr, [24000.0, 48000.0])
    np.testing.assert_allclose(counts_to_rad([[6000, 12000]], guard), [[np.pi / 2, np.pi / 2]])
    np.testing.assert_allclose(drive_gain(guard), [500 * 0.7 * 0.02, 1000 * 0.7 * 0.02])


def test_every_stage_reads_one_count_size_from_the_description():
    """Counts per joint radian worked out by hand from the YAMLs (encoder counts per motor
    revolution x gear ratio / 2 pi: the guard 48 x 500 and 48 x 1000, the variant robot
    64 x 300 and 64 x 800), as the description, the plant, capture's limits check and the
    conditioning read them; a joint without a drive counts at gear ratio 1, one without an
    encoder has none."""
    from dataclasses import replace

    from guardid.capture.checks import counts_per_rad
    from guardid.plant.joints import joint_constants

    for robot, per_rev in (("guard", [24000, 48000]), (str(VARIANT), [19200, 51200])):
        d = load_robot(robot)
        want = np.array(per_rev) / (2 * np.pi)
        np.testing.assert_allclose([j.counts_per_rad for j in d.joints], want, rtol=1e-15)
        np.testing.assert_allclose(counts_per_rad(d), want, rtol=1e-15)
        plant = [jc.counts_per_rad for jc in joint_constants(d, True, True)]
        np.testing.assert_allclose(plant, want, rtol=1e-15)
        np.testing.assert_allclose(counts_per_joint_rev(d), per_rev, rtol=1e-15)
    pan = load_robot("guard").joints[0]
    assert replace(pan, drive=None).counts_per_joint_rev == 48
    assert replace(pan, encoder=None).counts_per_rad is None


def _interior(t, edge=3.0):
    return (t > t[0] + edge) & (t < t[-1] - edge)


def test_derivatives_from_quantised_encoder():
    """qd within 0.5 % and qdd within 2 % of the joint's peak value (away from the ends)."""
    t = np.arange(0.0, DURATION, T)
    q_meas = encoder_positions(t)
    out = condition(t, q_meas, np.zeros_like(q_meas), highest_harmonic_hz=F_MAX, decimate=1)
    assert out.cutoff_hz == pytest.approx(8 * F_MAX)  # HARMONIC_FACTOR
    q, qd, qdd = analytic(out.t)
    inside = _interior(out.t)
    for est, ref, tol in ((out.q, q, 0.002), (out.qd, qd, 0.005), (out.qdd, qdd, 0.02)):
        err = np.abs(est - ref)[inside].max(axis=0) / np.abs(ref).max(axis=0)
        assert np.all(err < tol), (err, tol)


def test_uneven_time_stamps():
    """Jittered stamps (up to 40 % of a step) are resampled; derivatives stay accurate."""
    rng = np.random.default_rng(1)
    t = np.arange(0.0, DURATION, T) + rng.uniform(-0.2, 0.2, int(round(DURATION / T))) * T
    q_meas = encoder_positions(t)
    out = condition(t, q_meas, np.zeros_like(q_meas), cutoff_hz=2.0, decimate=1)
    assert any("resampled" in n for n in out.notes)
    np.testing.assert_allclose(np.diff(out.t), np.median(np.diff(t)), rtol=1e-9)
    q, qd, qdd = analytic(out.t)
    inside = _interior(out.t)
    err_qd = np.abs(out.qd - qd)[inside].max(axis=0) / np.abs(qd).max(axis=0)
    err_qdd = np.abs(out.qdd - qdd)[inside].max(axis=0) / np.abs(qdd).max(axis=0)
    assert np.all(err_qd < 0.015) and np.all(err_qdd < 0.05), (err_qd, err_qdd)


def test_decimation_keeps_every_kth_sample():
    t = np.arange(0.0, 20.0, T)
    q_meas = encoder_positions(t)
    effort = np.cos(t)[:, None] * np.ones(2)
    full = condition(t, q_meas, effort, cutoff_hz=2.0, decimate=1, stiction_threshold=0.0)
    dec = condition(t, q_meas, effort, cutoff_hz=2.0, decimate=5, stiction_threshold=0.0)
    assert dec.decimation == 5
    np.testing.assert_array_equal(dec.t, t[::5])
    for name in ("q", "qd", "qdd", "tau"):
        np.testing.assert_array_equal(getattr(dec, name), getattr(full, name)[::5])
    auto = condition(t, q_meas, effort, cutoff_hz=2.0)
    # 66.7 Hz, fc = 2 Hz: largest k with new Nyquist 33.3 / k >= 4 Hz is 8.
    assert auto.decimation == decimation_factor(1 / T, 2.0) == 8
    np.testing.assert_array_equal(auto.t, t[::8])


def test_stiction_mask_flags_reversals():
    t = np.arange(0.0, DURATION, T)
    q_meas = encoder_positions(t)
    out = condition(t, q_meas, np.zeros_like(q_meas), cutoff_hz=2.0, decimate=1)
    _, qd, _ = analytic(out.t)
    inside = _interior(out.t)
    for j in range(2):
        # every reversal (sign change of the true velocity) lies on flagged samples
        rev = np.flatnonzero(np.diff(np.sign(qd[:, j])) != 0)
        rev = rev[inside[rev]]
        assert rev.size > 5
        assert np.all(out.stiction[rev] | out.stiction[rev + 1])
        assert not np.any(out.mask[rev])
    # flagged samples are slow on some joint; unflagged ones are not
    slow = np.any(np.abs(qd) < 0.8 * out.threshold, axis=1)
    assert np.all(out.stiction[slow & inside])
    np.testing.assert_array_equal(out.stiction, stiction_mask(out.qd, out.threshold))
    assert 0.02 < out.stiction.mean() < 0.4


def _current(t):
    """A smooth current [A] (sum of sines up to 2 Hz) and its antiderivative [A s]."""
    comps = ((0.5, 0.3, 0.2), (0.3, 1.1, 1.0), (0.15, 2.0, 2.2))
    i = sum(a * np.sin(2 * np.pi * f * t + p) for a, f, p in comps)
    big_i = sum(-a / (2 * np.pi * f) * np.cos(2 * np.pi * f * t + p) for a, f, p in comps)
    return i, big_i


def test_period_mean_current_aligned_to_ticks():
    """Exact period means (t_{k-1}, t_k] are turned back into i(t_k)."""
    t = np.arange(0.0, 20.0, T)
    i_true, big_i = _current(t)
    means = np.empty_like(t)
    means[1:] = np.diff(big_i) / T
    means[0] = (big_i[0] - _current(np.array([-T]))[1][0]) / T
    raw_err = np.abs(means - i_true)[5:-5].max()
    aligned = align_period_mean(t, means)
    err = np.abs(aligned - i_true)[5:-5].max()
    assert err < 1e-4 < 0.02 < raw_err  # 20 A-level -> 1e-4 A vs 2e-2 A lag error
    assert err < raw_err / 100


def test_period_mean_alignment_in_condition():
    """Through condition(): tau refers to the same instants as q (period-mean effort)."""
    t = np.arange(0.0, 20.0, T)
    i_true, big_i = _current(t)
    means = np.empty_like(t)
    means[1:] = np.diff(big_i) / T
    means[0] = means[1]
    effort = np.column_stack([means, means])
    q_meas = encoder_positions(t)
    kw = dict(cutoff_hz=5.0, decimate=1, gain=[7.0, 14.0])
    on = condition(t, q_meas, effort, align_period_mean=True, **kw)
    off = condition(t, q_meas, effort, align_period_mean=False, **kw)
    ref = condition(t, q_meas, np.column_stack([i_true, i_true]), align_period_mean=False, **kw)
    inside = _interior(on.t, 1.0)
    err_on = np.abs(on.tau - ref.tau)[inside].max()
    err_off = np.abs(off.tau - ref.tau)[inside].max()
    assert on.torque_unit == "N m"
    assert err_on < err_off / 20, (err_on, err_off)


def test_gain_none_keeps_current_units():
    t = np.arange(0.0, 10.0, T)
    q_meas = encoder_positions(t)
    out = condition(t, q_meas, np.ones_like(q_meas), cutoff_hz=2.0, gain=None)
    assert out.torque_unit == "effort"
    assert any("current units" in n for n in out.notes)
    np.testing.assert_allclose(out.tau, 1.0, atol=1e-9)
    desc = condition(t, q_meas, np.ones_like(q_meas), cutoff_hz=2.0, gain=load_robot("guard"))
    np.testing.assert_allclose(desc.tau, [[7.0, 14.0]] * len(desc.t), atol=1e-9)


def test_cutoff_from_bandwidth():
    t = np.arange(0.0, DURATION, T)
    q_meas = encoder_positions(t)
    assert choose_cutoff(t, q_meas, highest_harmonic_hz=0.4) == pytest.approx(3.2)  # 8 x 0.4
    auto = choose_cutoff(t, q_meas)
    assert 2 * 0.25 <= auto <= 2 * 0.45  # 99.5 % of the energy lies below 0.4 Hz
    assert choose_cutoff(t, q_meas, highest_harmonic_hz=100.0) == pytest.approx(0.4 / (2 * T))
    assert choose_cutoff(t, q_meas, highest_harmonic_hz=0.01) == pytest.approx(0.5)


def test_causal_delay_matches_documentation():
    """Streaming output at update k equals the motion at t_k - delay_s (sine well below fc)."""
    fc, f = 3.0, 0.2
    t = np.arange(0.0, 30.0, T)
    w = 2 * np.pi * f
    q = np.column_stack([np.sin(w * t), 0.5 * np.cos(w * t)])
    cc = CausalConditioner(2, T, fc, period_mean=False)
    assert cc.delay_s == pytest.approx(cc.delay_samples * T)
    # analog 4th-order Butterworth: group delay at DC = 2.613 / (2 pi fc)
    assert cc.delay_s - T == pytest.approx(2.6131 / (2 * np.pi * fc), rel=0.05)
    out = cc.update(q, q)
    td = t - cc.delay_s
    ref = np.column_stack([np.sin(w * td), 0.5 * np.cos(w * td)])
    ref_qd = np.column_stack([w * np.cos(w * td), -0.5 * w * np.sin(w * td)])
    late = t > 5.0
    assert np.abs(out.q - ref)[late].max() < 2e-3
    assert np.abs(out.qd - ref_qd)[late].max() < 2e-3 * w
    assert np.abs(out.tau - ref)[late].max() < 2e-3
    # without the delay compensation the error is an order of magnitude larger
    assert np.abs(out.q - q)[late].max() > 10 * np.abs(out.q - ref)[late].max()
    # a delay wrong by one sample is clearly worse
    td1 = td - T
    ref1 = np.column_stack([np.sin(w * td1), 0.5 * np.cos(w * td1)])
    assert np.abs(out.q - ref1)[late].max() > 2 * np.abs(out.q - ref)[late].max()


def test_causal_per_sample_equals_chunk_and_period_mean():
    t = np.arange(0.0, 5.0, T)
    q = encoder_positions(t)
    i_true, big_i = _current(t)
    means = np.empty_like(t)
    means[1:] = np.diff(big_i) / T
    means[0] = means[1]
    eff = np.column_stack([means, means])
    a = CausalConditioner(2, T, 3.0, gain=[7.0, 14.0], stiction_threshold=0.05)
    chunk = a.update(q, eff)
    b = CausalConditioner(2, T, 3.0, gain=[7.0, 14.0], stiction_threshold=0.05)
    rows = [b.update(q[k], eff[k]) for k in range(len(t))]
    for name in ("q", "qd", "qdd", "tau", "stiction"):
        np.testing.assert_allclose(
            np.concatenate([getattr(r, name) for r in rows]), getattr(chunk, name)
        )
    # the period-mean current comes out as the instantaneous current through the same
    # filter (same instants); treating the means as instantaneous lags by T/2
    inst = np.column_stack([i_true, i_true])
    ref = CausalConditioner(2, T, 3.0, period_mean=False).update(q, inst).tau[:, 0]
    late = t > 1.0
    err = np.abs(chunk.tau[:, 0] / 7.0 - ref)[late].max()
    raw = CausalConditioner(2, T, 3.0, period_mean=False).update(q, eff)
    err_raw = np.abs(raw.tau[:, 0] - ref)[late].max()
    assert err < err_raw / 3, (err, err_raw)
