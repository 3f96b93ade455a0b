"""The motor fit's std holds when a few rows lie far off the motor equation.

A row whose angle step is not the motion its voltage and current were measured over (rows
cut out of a log without a trace in the ticks, a step within the drives' reach so not a
jump) pulls R and Ke by many times the homoscedastic std. The reported std is the larger of
that and the sandwich (White) std, which grows with such a row's pull.

Independent truth: the period-averaged motor equation V = R i + Ke N dq / T + e built here
from chosen R and Ke, and the homoscedastic std worked out in numpy on the same rows.
"""

from __future__ import annotations

import numpy as np

from guardid.identify.electrical import identify_motor_runs

N, T, R, KE = 30.0, 0.015, 2.0, 0.01  # gear, tick [s], ohm, V s/rad
ROWS = 3000


def _run(seed: int, step_rad: float = 0.0):
    """ticks, q [rad], v [V], i [A]: the motion's own voltages; ``step_rad`` added to every
    angle from row 1500 on (a cut the ticks do not show: the voltage is the motion's)."""
    rng = np.random.default_rng(seed)
    ticks = np.arange(ROWS)
    q = np.cumsum(rng.normal(0.0, 2e-3, ROWS))
    i = rng.normal(0.0, 0.5, ROWS)
    v = R * i + KE * N * np.diff(q, prepend=q[0]) / T + rng.normal(0.0, 0.01, ROWS)
    q = q + np.where(ticks >= 1500, step_rad, 0.0)
    return ticks, q, v, i


def _homoscedastic_ke_std(ticks, q, v, i) -> float:
    """Ke's std of plain least squares on rows 1.. (sigma^2 (A^T A)^-1), in numpy."""
    A = np.column_stack([i[1:], N * np.diff(q) / T])
    theta, *_ = np.linalg.lstsq(A, v[1:], rcond=None)
    r = v[1:] - A @ theta
    return float(np.sqrt(r @ r / (len(r) - 2) * np.linalg.inv(A.T @ A)[1, 1]))


def test_one_row_off_the_equation_widens_the_std_to_its_pull():
    """A 0.03 rad step in one row (15 times the motion's typical step of 2 mrad): Ke is
    tens of homoscedastic std off; the reported std covers the error."""
    run = _run(1, step_rad=0.03)
    m = identify_motor_runs("j", [run], N, T)
    plain = _homoscedastic_ke_std(*run)
    assert abs(m.ke - KE) > 10 * plain  # the row's pull, in the std that ignores it
    assert abs(m.ke - KE) < 3 * m.ke_std
    assert abs(m.resistance - R) < 3 * m.resistance_std


def test_on_an_honest_log_the_std_is_the_homoscedastic_one_and_covers_the_truth():
    """200 seeds without a step: the reported std within 10 % of plain least squares' (the
    sandwich does not widen it on homoscedastic noise), and Ke within 3 std in at least
    98 % of the seeds (99.7 % expected)."""
    inside, ratios = 0, []
    for seed in range(200):
        run = _run(100 + seed)
        m = identify_motor_runs("j", [run], N, T)
        ratios.append(m.ke_std / _homoscedastic_ke_std(*run))
        inside += abs(m.ke - KE) < 3 * m.ke_std
    assert 1.0 - 1e-9 <= min(ratios) and max(ratios) < 1.1
    assert inside >= 196
