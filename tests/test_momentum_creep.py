"""A joint that creeps at under one encoder count per period, in the momentum form
(guardid.conditioning.momentum.slow_ticks, period_direction, period_regressor).

Independent truth: encoder counts written here as the floor of a straight-line motion, the
flagged ticks and directions worked out by hand from those counts, and the Coulomb term
Fc T d_k of the period equation (DESIGN.md section 5b) from the robot's own friction value.
"""

from __future__ import annotations

import numpy as np

from guardid.conditioning import momentum as mom
from guardid.dynamics import build_model
from guardid.robot import load_robot

DT = 0.015


def creeping_counts(speed_counts_per_tick: float, n: int = 40) -> np.ndarray:
    """(n,) whole counts of a joint moving at a constant speed from 0.3 of a count."""
    return np.floor(0.3 + speed_counts_per_tick * np.arange(n))


def test_creeping_counts_are_not_stuck_but_two_still_periods_are():
    """0.6 counts per period: periods without a count come one at a time between counts
    (the joint moves on): no tick flagged. Three equal counts in a row (stuck for two
    periods): the middle tick and its two neighbours flagged, nothing else."""
    c = creeping_counts(0.6)
    dq = np.diff(c)
    assert (dq == 0).sum() >= 10 and not np.any((dq[:-1] == 0) & (dq[1:] == 0))
    q = c[:, None] * 1e-3
    v = mom.tick_velocity(q, DT)[0]
    bad = mom.slow_ticks(q, v, threshold=np.zeros(1), flat_is_stuck=True)
    assert not bad.any()
    assert not mom.slow_ticks(q, v, threshold=np.zeros(1), flat_is_stuck=False).any()

    stuck = np.array([0, 1, 2, 3, 3, 3, 4, 5, 5, 6, 7.0])  # ticks 3-5 equal: stuck twice
    q = stuck[:, None] * 1e-3
    v = mom.tick_velocity(q, DT)[0]
    bad = mom.slow_ticks(q, v, threshold=np.zeros(1), flat_is_stuck=True)[:, 0]
    assert bad.tolist() == [False, False, False, True, True, True] + [False] * 5
    assert not mom.slow_ticks(q, v, threshold=np.zeros(1), flat_is_stuck=False).any()


def test_a_period_without_a_count_keeps_the_direction_of_the_motion():
    """Forward and backward creep: every period from the second on has the direction of
    the motion, +1 or -1, the periods without a count too (their count change is 0)."""
    for sign in (1.0, -1.0):
        q = sign * creeping_counts(0.6)[:, None] * 1e-3
        v = mom.tick_velocity(q, DT)[0]
        d = mom.period_direction(q, v)[:, 0]
        assert d[0] == 0.0
        assert np.all(d[1:] == sign), d


def test_the_coulomb_term_of_a_period_without_a_count():
    """The guard's pan creeping, the tilt still: Phi theta changes by Fc T d_k on the pan's
    equation when the pan's Coulomb friction Fc grows by 1 N m, d_k = +1 in every period
    whose stencils lie inside the ticks (rows 3 .. N-3; the kink correction of a constant
    term is zero there), those without a count included."""
    desc = load_robot("guard")
    model = build_model(desc)
    n = 40
    q = np.zeros((n, 2))
    q[:, 0] = creeping_counts(0.6, n) * 2.0 * np.pi / 24000.0
    q[:, 1] = 0.2
    v = mom.tick_velocity(q, DT)[0]
    phi = mom.period_regressor(model, q, v, DT, 3)
    params = np.array(model.params, dtype=float)
    more = params.copy()
    more[model.friction_index(0) + 1] += 1.0  # Fc of the pan
    d_theta = model.base.values(more) - model.base.values(params)
    change = phi @ d_theta  # (N, 2)
    rows = slice(3, n - 2)
    assert np.any(np.diff(q[rows, 0]) == 0.0)
    np.testing.assert_allclose(change[rows, 0], DT, rtol=1e-9)
    np.testing.assert_allclose(change[rows, 1], 0.0, atol=1e-15)


def test_the_rounding_compensation_does_not_turn_a_creeping_joint():
    """The compensation's draws (fresh rounding added to the counts) keep each period's
    direction: the Coulomb column of a joint that creeps between counts carries no noise
    (its rows of S = E[dA^T dA] are zero), while its viscous column does."""
    desc = load_robot("guard")
    model = build_model(desc)
    n = 3000
    res = 2.0 * np.pi / 24000.0
    t = np.arange(n) * DT
    q = np.zeros((n, 2))
    q[:, 0] = creeping_counts(0.6, n) * res
    q[:, 1] = np.floor((0.3 + 0.2 * np.sin(2 * np.pi * 0.5 * t)) / res) * res
    cur = np.random.default_rng(3).normal(0.0, 0.1, (n, 2))
    cond, _, _ = mom.condition_momentum(
        t, q, cur, model, gain=None, cutoff_hz=2.0, flat_is_stuck=True,
        stiction_threshold=np.zeros(2),
    )  # fmt: skip
    state = cond.momentum
    assert state.valid[:, 0].mean() > 0.9 and np.any(np.diff(q[state.valid[:, 0], 0]) == 0)
    S, _ = mom.quantisation_noise(state, model, np.full(2, res), np.zeros(2))
    names = list(model.base.names)
    fc, fv = names.index("Fc1"), names.index("Fv1")
    assert np.all(S[0, fc, :] == 0.0) and np.all(S[0, :, fc] == 0.0)
    assert S[0, fv, fv] > 0.0


def test_a_reversal_through_a_period_without_a_count_is_cut():
    """Up to a count, one period without a count, back down: the joint turns inside the
    flat period (or in one next to it), so no period there has one direction. The ticks
    of the flat period (4 and 5) are flagged, as a reversal between two counts flags its
    tick; symmetric (the velocities at ticks 4 and 5 cancel) and not. Nothing else is."""
    for counts in ([0, 1, 2, 3, 4, 4, 3, 2, 1, 0], [0, 2, 4, 6, 7, 7, 5, 3, 1, 0]):
        q = np.array(counts, dtype=float)[:, None] * 1e-3
        v = mom.tick_velocity(q, DT)[0]
        for flat_is_stuck in (True, False):
            bad = mom.slow_ticks(q, v, threshold=np.zeros(1), flat_is_stuck=flat_is_stuck)
            assert np.flatnonzero(bad[:, 0]).tolist() == [4, 5], (counts, flat_is_stuck)
    q = np.array([0, 1, 2, 3, 4, 4, 4, 3, 2, 1.0])[:, None] * 1e-3  # two flat periods
    v = mom.tick_velocity(q, DT)[0]
    bad = mom.slow_ticks(q, v, threshold=np.zeros(1), flat_is_stuck=False)
    assert np.flatnonzero(bad[:, 0]).tolist() == [4, 5, 6]
