"""The fast paths of issue 21 against the slow ones they replace.

- The block CUSUM of the offline replay (skips stretches where a zero CUSUM stays zero; and
  its C kernel, guardid/online/replay_rows.c) against :meth:`ChangeDetector._cusum` row by
  row: the same first alarm row and, after it or after the block, the same CUSUM state
  (values, last zeros, rises).
- ``condition`` a column at a time and with ``keep_every``: every output equal to the
  whole-array steps (scipy's filter, the stencils, the spline alignment on both columns at
  once) and to ``decimate=1`` sliced, counts of every sample kept.
"""

from __future__ import annotations

import numpy as np
import pytest

from guardid.conditioning import align_period_mean, condition
from guardid.conditioning.filters import central_derivatives, zero_phase_lowpass
from guardid.online import ChangeDetector, DetectorSettings
from guardid.online.replay_loop import _cusum_block

DT = 0.015


def _armed(sigma):
    det = ChangeDetector(("MX2R", "MY2"), 2, "rls", DetectorSettings())
    det.sigma = np.asarray(sigma, float)
    det._sigma_list = [float(x) for x in sigma]
    det._arm(0.0, refresh=True)
    det._refreshing = False
    det._recent.append((0.0, np.zeros(2)))  # an estimate before any change
    return det


def _c_cusum(det, t, z, ok):
    from guardid.online import replay_native

    lib = replay_native.kernel()
    if lib is None:
        pytest.skip("needs a C compiler")
    return replay_native.cusum_rows(lib, det, t, z, ok)


@pytest.mark.parametrize("block_cusum", [_cusum_block, _c_cusum], ids=["numpy", "c"])
@pytest.mark.parametrize("seed", range(6))
def test_block_cusum_matches_the_detector_row_by_row(seed, block_cusum):
    rng = np.random.default_rng(seed)
    L = 3000
    sigma = np.array([0.5, 2.0])
    e = rng.normal(size=(L, 2)) * sigma  # residuals, with bursts that climb and fall back
    for start in rng.integers(0, L - 40, size=6):  # (5.5 - kappa 4) x 12 rows < h = 40
        j = rng.integers(0, 2)
        e[start : start + rng.integers(3, 13), j] += rng.choice([-1, 1]) * 5.5 * sigma[j]
    if seed % 2:  # a sustained bias: an alarm inside the block
        e[2000:, 1] += 5.5 * sigma[1]
    ok = rng.random((L, 2)) > 0.2  # absent joint equations
    ok[rng.random(L) < 0.1] = [True, False]
    e[~ok] = 0.0
    t = (np.arange(L) + 1000) * DT
    live, block = _armed(sigma), _armed(sigma)
    fired = None
    for i in range(L):
        if live._cusum(float(t[i]), ok[i], e[i][ok[i]]) is not None:
            fired = i
            break
    assert (fired is not None) == bool(seed % 2)  # the bursts alone never fire
    got = block_cusum(block, t, e / sigma, ok)
    assert got == fired
    assert block._g == live._g
    assert block._zero_t == live._zero_t
    assert block._rise_t == live._rise_t


def _log(seed, gap):
    """A 2-joint log (t, q, period-mean current) of 200 s, a gap in it if ``gap``."""
    rng = np.random.default_rng(seed)
    t = np.arange(int(200 / DT)) * DT
    if gap:
        t[6000:] += 1.5
    q = np.column_stack([0.6 * np.sin(0.6 * t), 0.3 * np.cos(1.1 * t + 0.4)])
    q = np.round(q / 2.6e-4) * 2.6e-4  # encoder quanta (flat runs at reversals)
    cur = np.column_stack([0.4 * np.cos(0.6 * t), -0.2 * np.sin(1.1 * t)])
    return t, q, cur + 0.01 * rng.normal(size=cur.shape)


@pytest.mark.parametrize("gap", [False, True])
def test_condition_by_column_equals_the_whole_array_steps(gap):
    t, q, cur = _log(1, gap)
    c = condition(t, q, cur, cutoff_hz=3.0, decimate=1, gain=np.array([1.5, 2.0]))
    fs = 1.0 / np.median(np.diff(c.t))
    if not gap:  # uniform: the steps on both columns at once, as scipy gives them
        qf = zero_phase_lowpass(q, fs, 3.0)
        assert np.array_equal(c.q, qf)
        assert np.array_equal(c.qd, central_derivatives(qf, 1.0 / fs)[0])
        assert np.array_equal(c.qdd, central_derivatives(qf, 1.0 / fs)[1])
        raw = align_period_mean(t, cur) * np.array([1.5, 2.0])
        assert np.array_equal(c.tau_raw, raw)
        tau = zero_phase_lowpass(align_period_mean(t, cur), fs, 3.0) * np.array([1.5, 2.0])
        assert np.array_equal(c.tau, tau)
    for j, gain in enumerate((1.5, 2.0)):  # each joint conditioned alone: the same signals
        one = condition(t, q[:, j], cur[:, j], cutoff_hz=3.0, decimate=1, gain=gain)
        for name in ("q", "qd", "qdd", "tau", "tau_raw"):
            assert np.array_equal(getattr(c, name)[:, j], getattr(one, name)[:, 0]), name


@pytest.mark.parametrize("gap", [False, True])
@pytest.mark.parametrize("k", [2, 8])
def test_keep_every_is_decimate_1_sliced(gap, k):
    t, q, cur = _log(2, gap)
    kw = dict(cutoff_hz=2.0, gain=np.array([1.5, 2.0]), stiction_guard_s=0.12, flat_is_stuck=True)
    full = condition(t, q, cur, decimate=1, **kw)
    kept = condition(t, q, cur, decimate=1, keep_every=k, **kw)
    for name in ("t", "q", "qd", "qdd", "tau", "tau_raw", "mask", "stiction"):
        assert np.array_equal(getattr(kept, name), getattr(full, name)[::k]), name
    assert kept.dropped == full.dropped and sum(full.dropped.values()) > 0
    assert kept.n_flagged == full.n_flagged and kept.notes == full.notes
    assert kept.decimation == full.decimation == 1
