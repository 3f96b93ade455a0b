"""The motor current's lag behind each voltage step, in the momentum form's stencil error
(guardid.conditioning.electrical_lag).

The truth is an independent closed-loop-free simulation: one joint (inertia M) driven by a
DC motor whose voltage is held over each period, state (q, v, i, integral of i) stepped
exactly by a matrix exponential per period (L di/dt = V - R i - N Ke v, M dv/dt = N eta Kt
i). From it: the exact positions and velocities at the ticks and the period-mean torque the
telemetry would report. The three-point stencil's momentum error M (v_hat - v) is then
compared with what identify adds to the impulses for it.
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy.integrate import quad
from scipy.linalg import expm

from guardid.conditioning import momentum as mom
from guardid.conditioning.electrical_lag import (
    electrical_time_constants,
    lag_correction,
    lag_factor,
    lag_weights,
)
from guardid.robot import load_robot

T = 0.015  # tick [s]
N, ETA, KT, KE, R = 1000.0, 0.7, 0.02, 0.02, 8.0  # the guard's pan drive
M = 1.0  # joint inertia [kg m^2]
GAIN = N * ETA * KT  # torque per ampere [N m / A]
D = GAIN * N * KE / R  # electrical damping [N m s / rad]


def _drive(inductance: float, ticks: int = 400, seed: int = 3, ke: float = KE, volts=None):
    """(q, v at the ticks, period-mean torque) of the motor-driven joint, random voltages
    (or ``volts``) held over each period (exact per period: the state equation is linear)."""
    if volts is None:
        volts = np.random.default_rng(seed).uniform(-6.0, 6.0, ticks)
    ticks = len(volts)
    # state (q, v, i, z = integral of i), input V as a fifth constant state
    A = np.zeros((5, 5))
    A[0, 1] = 1.0
    A[1, 2] = GAIN / M
    A[2, 1], A[2, 2], A[2, 4] = -N * ke / inductance, -R / inductance, 1.0 / inductance
    A[3, 2] = 1.0
    step = expm(A * T)
    x = np.zeros(5)
    q, v, tau = np.zeros(ticks), np.zeros(ticks), np.zeros(ticks)
    for k in range(1, ticks):
        x[4] = volts[k]
        z0 = x[3]
        x = step @ x
        q[k], v[k], tau[k] = x[0], x[1], GAIN * (x[3] - z0) / T
    return q[:, None], v[:, None], tau[:, None]


def _stencil_error(q, v):
    """(p_hat_k - p_hat_(k-1)) - (p_k - p_(k-1)) of the three-point stencil."""
    v_hat, _ = mom.tick_velocity(q, T, 3)
    e = M * (v_hat - v)
    return np.diff(e, axis=0, prepend=e[:1])


def _corrections(q, tau, tau_e, damping=D):
    """(kink and back-EMF slope terms, the lag term) identify adds to the impulses."""
    v_hat, _ = mom.tick_velocity(q, T, 3)
    kink = mom.kink_correction(tau, T, 3) - damping * mom.slope_term(v_hat, T, 3)
    lag = lag_correction(tau, q, T, *mom.STENCILS[3], np.array([tau_e]), np.array([damping]))
    return kink, lag


def _rms(x) -> float:
    return float(np.sqrt(np.mean(np.square(x))))


@pytest.mark.parametrize("inductance", [0.002, 0.006])
def test_without_back_emf_the_lag_term_is_what_the_kink_correction_leaves(inductance):
    """Drive torque piecewise constant but for the lag: kink + lag = the stencil's error, to
    the lag term's second order (each step taken as the change of the period means)."""
    q, v, tau = _drive(inductance, ke=1e-9)
    truth = _stencil_error(q, v)[10:-10]
    kink, lag = _corrections(q, tau, inductance / R, damping=GAIN * N * 1e-9 / R)
    left = truth - kink[10:-10]  # what the stepped model leaves: the current's lag
    assert _rms(left) > 0.005 * _rms(truth)  # there is a lag to correct
    assert _rms(left - lag[10:-10]) < 0.1 * _rms(left)


@pytest.mark.parametrize("inductance", [0.002, 0.006])
def test_with_back_emf_the_lag_term_is_what_the_inductance_adds(inductance):
    """With the back-EMF the slope term is first order and leaves its own remainder; the
    inductance's share of the stencil's error (the same voltages with L and with L -> 0)
    is what the lag term adds."""
    q0, v0, tau0 = _drive(1e-9)
    q, v, tau = _drive(inductance)
    kink0, lag0 = _corrections(q0, tau0, 0.0)
    kink, lag = _corrections(q, tau, inductance / R)
    effect = (_stencil_error(q, v) - kink)[10:-10] - (_stencil_error(q0, v0) - kink0)[10:-10]
    assert np.all(lag0 == 0.0)
    assert _rms(effect - lag[10:-10]) < 0.1 * _rms(effect)
    assert np.corrcoef(effect[:, 0], lag[10:-10, 0])[0, 1] > 0.99


@pytest.mark.parametrize("r", [0.005, 0.017, 0.1, 0.4])
def test_lag_factor_is_the_first_moment_of_the_lagging_step(r):
    """f(r) T^2 = int_0^T s (d(s) - mean d) ds for d(s) = -exp(-s / tau): by quadrature."""
    tau = r * T
    mean = -tau / T * (1.0 - np.exp(-T / tau))
    moment = quad(lambda s: s * (-np.exp(-s / tau) - mean), 0.0, T, points=[tau])[0]
    assert lag_factor(tau, T) * T**2 == pytest.approx(moment, rel=1e-9)
    assert lag_factor(0.0, T) == 0.0


def test_lag_weights_by_hand():
    V3, first3 = lag_weights(*mom.STENCILS[3])
    assert first3 == 0 and np.allclose(V3, [-0.5, -0.5])
    V5, first5 = lag_weights(*mom.STENCILS[5])
    assert first5 == -1 and np.allclose(V5, np.array([1.0, -7.0, -7.0, 1.0]) / 12.0)
    # the slope term's weights are the same sums with a twelfth of each coefficient
    U3, _ = mom.slope_weights(3)
    assert np.allclose(U3, V3 / 12.0)


def test_no_jump_is_taken_across_a_lost_tick():
    """A lost tick before tick 30: the steps into periods 30 and 31 span it and are left
    out; with the three-point weights (periods k and k + 1) the momentum error changes at
    ticks 29-31, its differences at 29-32, and nowhere else."""
    q, _, tau = _drive(0.002, ticks=60)
    broken = np.zeros(60, dtype=bool)
    broken[30] = True
    whole = lag_correction(tau, q, T, *mom.STENCILS[3], [0.002 / R], [D])
    cut = lag_correction(tau, q, T, *mom.STENCILS[3], [0.002 / R], [D], broken)
    assert np.flatnonzero(np.any(whole != cut, axis=1)).tolist() == [29, 30, 31, 32]


@pytest.mark.parametrize("points", [3, 5])
def test_the_rows_carry_the_lag_term_with_either_stencil(points, monkeypatch):
    """condition_momentum's impulse rows with the YAML's inductance and with none differ,
    for the three- and the five-point stencil: the term is applied with either."""
    from guardid.dynamics import build_model
    from guardid.identify.equation import drive_gain

    desc = load_robot("guard")
    model = build_model(desc)
    t = np.arange(1200) * T
    noise = np.random.default_rng(5).uniform(-1.0, 1.0, (2, len(t)))
    q1, _, tau1 = _drive(0.002, volts=6.0 * np.sin(1.9 * t) + 4.0 * np.sin(7.0 * t) + noise[0])
    q2, _, tau2 = _drive(0.002, volts=5.0 * np.sin(2.6 * t) + 3.0 * np.sin(5.0 * t) + noise[1])
    q = np.hstack([q1, 0.05 * q2])
    current = np.hstack([tau1, tau2]) / drive_gain(desc)
    kw = {"gain": drive_gain(desc), "cutoff_hz": 2.0, "stiction_threshold": 1e-6,
          "points": points, "decimate": 1}  # fmt: skip
    _, _, y_with = mom.condition_momentum(t, q, current, model, **kw)
    monkeypatch.setattr(mom, "electrical_time_constants", lambda d: np.zeros(len(d.joints)))
    _, _, y_without = mom.condition_momentum(t, q, current, model, **kw)
    assert np.abs(y_with - y_without).max() > 1e-4 * np.abs(y_with).max()


def test_time_constants_from_the_description():
    tau_e = electrical_time_constants(load_robot("guard"))
    assert np.allclose(tau_e, [0.002 / 8.0, 0.002 / 8.0])
