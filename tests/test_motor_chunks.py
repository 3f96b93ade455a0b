"""The motor equation's least squares by chunks (issue 30: memory of long logs).

Independent truth: the period-averaged motor equation V = R i + Ke N dq / T + e built from
chosen R and Ke, and the bias-compensated normal equations solved here in a few lines of
numpy on every run's rows stacked at once."""

from __future__ import annotations

import numpy as np
import pytest

from guardid.identify import electrical


def _run(rng, n, start_tick, gaps):
    ticks = start_tick + np.arange(n)
    for g in gaps:
        ticks[g:] += 3  # lost ticks
    q = np.cumsum(rng.normal(0.0, 2e-3, n))
    i = rng.normal(0.0, 0.5, n)
    return ticks, q, i


@pytest.mark.parametrize("inductance", [False, True])
def test_chunked_motor_fit_equals_the_stacked_one(monkeypatch, inductance):
    """Two runs (gaps inside, ticks overlapping between the runs), rows formed 7 ticks at a
    time: R, Ke, L, their std, the row count and the residual equal the stacked solve's
    to 1e-10 relative (the sums of the normal equations taken in another order; the std the
    larger of the homoscedastic and the sandwich one); the
    estimates are near the R = 2 ohm, Ke = 0.01 V s/rad the voltages were made with."""
    rng = np.random.default_rng(3)
    N, T, R, KE, L = 30.0, 0.015, 2.0, 0.01, 1e-3
    runs, rows_A, rows_y = [], [], []
    for start, gaps in ((100, (50, 51, 300)), (120, (7,))):
        ticks, q, i = _run(rng, 400, start, gaps)
        v = R * i + KE * N * np.diff(q, prepend=q[0]) / T + rng.normal(0, 0.01, len(i))
        if inductance:
            v += L * np.diff(i, prepend=i[0]) / T
        runs.append((ticks, q, v, i))
        k = np.flatnonzero(np.diff(ticks) == 1) + 1  # pairs (k-1, k) of consecutive ticks
        if inductance:
            k = k[(k >= 2) & (ticks[k - 1] - ticks[np.maximum(k - 2, 0)] == 1)]
        k = k[np.abs(i[k]) >= 0.05]
        cols = [i[k], N * (q[k] - q[k - 1]) / T] + ([(i[k] - i[k - 1]) / T] if inductance else [])
        rows_A.append(np.column_stack(cols))
        rows_y.append(v[k])
    A, y = np.vstack(rows_A), np.concatenate(rows_y)
    noise = np.array(
        [0.02**2, (N / T) ** 2 * 1e-4**2 / 6.0] + ([2 * 0.02**2 / T**2] if inductance else [])
    )
    normal = A.T @ A - len(y) * np.diag(noise)
    theta = np.linalg.solve(normal, A.T @ y)
    r = y - A @ theta
    inv = np.linalg.inv(normal)
    plain = np.diag(r @ r / (len(y) - A.shape[1]) * inv)
    sandwich = np.diag(inv @ (A.T * r**2) @ A @ inv)  # White's: sum r_k^2 a_k a_k^T inside
    std = np.sqrt(np.maximum(plain, sandwich))

    monkeypatch.setattr(electrical, "MOTOR_CHUNK", 7)
    m = electrical.identify_motor_runs(
        "j", runs, N, T, with_inductance=inductance, min_current_a=0.05,
        current_noise_a=0.02, count_rad=1e-4,
    )  # fmt: skip
    assert m.rows == len(y)
    got = [m.resistance, m.ke] + ([m.inductance] if inductance else [])
    np.testing.assert_allclose(got, theta, rtol=1e-10)
    np.testing.assert_allclose([m.resistance_std, m.ke_std], std[:2], rtol=1e-10)
    assert m.residual_rms_v == pytest.approx(np.sqrt(np.mean(r**2)), rel=1e-10)
    assert abs(m.resistance - R) < 0.05 and abs(m.ke - KE) < 1e-3
