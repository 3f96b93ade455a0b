"""Plant physics against independent truth: energy, scipy references, motors, stiction."""

import math

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from guardid.dynamics import build_model
from guardid.plant import PayloadChange, Plant
from guardid.robot import load_robot

DESC = load_robot("guard")
MODEL = build_model(DESC)


def _potential(q, params=None):
    """Gravity potential [J] from link COM positions by standard-DH forward kinematics."""
    t = np.eye(4)
    energy = 0.0
    for k, (joint, link) in enumerate(zip(DESC.joints, DESC.links, strict=True)):
        dh = joint.dh
        th, ca, sa = q[k] + dh.theta, math.cos(dh.alpha), math.sin(dh.alpha)
        ct, st = math.cos(th), math.sin(th)
        a = np.array([[ct, -st * ca, st * sa, dh.a * ct], [st, ct * ca, -ct * sa, dh.a * st],
                      [0, sa, ca, dh.d], [0, 0, 0, 1]])  # fmt: skip
        t = t @ a
        mass, com = link.mass, link.com
        if params is not None:  # first moments and mass from a parameter vector
            n = MODEL.param_names
            mass = params[n.index(f"M{k + 1}")]
            com = np.array([params[n.index(f"{s}{k + 1}")] for s in ("MX", "MY", "MZ")]) / mass
        p = t[:3, :3] @ com + t[:3, 3]
        energy -= mass * float(DESC.gravity @ p)
    return energy


def _energy(q, qd, params=None):
    m = MODEL.mass_matrix(q, params)[0]
    qd = np.asarray(qd)
    return 0.5 * qd @ m @ qd + _potential(q, params)


def _free_plant(**kw):
    return Plant(DESC, model=MODEL, friction=False, limits=False, open_circuit=True,
                 noise=False, q0=[0.0, 0.3], qd0=[1.0, 0.5], **kw)  # fmt: skip


def _reference(t_end, x0, switch=None):
    """Tight solve_ivp of M^-1 (-bias); ``switch`` = (time, params) for a payload change."""

    def f(params):
        def rhs(t, x):
            m = MODEL.mass_matrix_1(x[:2], params)
            return np.concatenate([x[2:], np.linalg.solve(m, -MODEL.bias_1(x[:2], x[2:], params))])

        return rhs

    kw = dict(method="DOP853", rtol=1e-10, atol=1e-12, dense_output=True)
    if switch is None:
        return solve_ivp(f(MODEL.params), (0, t_end), x0, **kw).sol
    tc, p2 = switch
    s1 = solve_ivp(f(MODEL.params), (0, tc), x0, **kw)
    s2 = solve_ivp(f(p2), (tc, t_end), s1.y[:, -1], **kw)
    return lambda t: s1.sol(t) if t <= tc else s2.sol(t)


def test_energy_conserved_and_matches_reference_open_circuit():
    plant = _free_plant()
    e0 = _energy([0.0, 0.3], [1.0, 0.5])
    samples = [plant.step([0.0, 0.0]) for _ in range(int(round(10.0 / plant.dt)))]
    drift = max(abs(_energy(s.q, s.qd) - e0) for s in samples) / abs(e0)
    assert drift < 1e-5
    ref = _reference(10.0, [0.0, 0.3, 1.0, 0.5])
    err = max(np.abs(np.array(s.q) - ref(s.time)[:2]).max() for s in samples)
    assert err < 1e-5


def test_payload_change_at_exact_time():
    tc = 2.5 * DESC.sample_period
    change = PayloadChange(tc, 1.0, (0.1, 0.05, 0.0))
    with_p = _free_plant(payload=[change])
    without = _free_plant()
    a = [with_p.step([0.0, 0.0]) for _ in range(40)]
    b = [without.step([0.0, 0.0]) for _ in range(40)]
    assert a[:2] == b[:2]  # identical up to the change
    assert a[2].q != b[2].q
    ref = _reference(a[-1].time, [0.0, 0.3, 1.0, 0.5], switch=(tc, with_p.params[1]))
    for s in a:
        assert np.abs(np.array(s.q) - ref(s.time)[:2]).max() < 1e-8
    # the change too early or too late by half a tick is clearly detectable
    for shift in (-0.5, 0.5):
        alt = _reference(a[-1].time, [0.0, 0.3, 1.0, 0.5],
                         switch=(tc + shift * DESC.sample_period, with_p.params[1]))  # fmt: skip
        assert np.abs(np.array(a[-1].q) - alt(a[-1].time)[:2]).max() > 1e-5
    # the payload's own mass shows up in the model's parameters
    n = MODEL.param_names
    assert with_p.params[1][n.index("M2")] == pytest.approx(MODEL.params[n.index("M2")] + 1.0)


def test_no_load_speeds_match_paper():
    rpm = 60.0 / (2 * math.pi)
    pan = Plant(DESC, model=MODEL, noise=False)
    for _ in range(int(4.0 / pan.dt)):
        s = pan.step([12.0, 4.2])
    assert s.qd[0] * rpm == pytest.approx(10.0, rel=0.15)
    # tilt: limits off, measured where gravity has no moment (COM straight above the axis)
    tilt = Plant(DESC, model=MODEL, noise=False, limits=False, q0=[0.0, -0.2])
    q_level = math.pi / 2 - math.atan2(0.02, 0.12)
    while True:
        s = tilt.step([0.0, 12.0])
        if s.q[1] >= q_level:
            break
    assert s.time > 2.0  # well past the mechanical transient (~65 ms)
    assert s.qd[1] * rpm == pytest.approx(5.0, rel=0.15)


def test_stiction_holds_exactly_below_coulomb_and_moves_above():
    # joint 1: stall torque kt V / R = 0.875 N m/V * V vs Fc = 0.6 N m
    # joint 2 held against gravity (~7.3 N m) by 4.2 V (7.35 N m), within +-0.9 N m
    below = Plant(DESC, model=MODEL, noise=False, q0=[0.3, 0.1])
    for _ in range(200):
        s = below.step([0.6, 4.2])
    assert s.q == (0.3, 0.1) and s.qd == (0.0, 0.0)
    above = Plant(DESC, model=MODEL, noise=False, q0=[0.3, 0.1])
    for _ in range(200):
        s = above.step([0.8, 4.2])
    assert s.q[0] > 0.31 and s.q[1] == 0.1
    # reversing drive: the joint stops, sticks and the friction balances the motor
    for _ in range(100):
        s = above.step([-0.3, 4.2])
    assert s.qd[0] == 0.0 and above.state.held[0]


def test_tilt_falls_onto_its_lower_stop_and_is_driven_onto_the_upper_one():
    """Stops from the robot description: unpowered, gravity (~7.3 N m) takes the tilt down
    onto -10 deg and it rests there; 12 V takes it up onto +35 deg."""
    lo, hi = DESC.joints[1].limits.position
    plant = Plant(DESC, model=MODEL, noise=False, q0=[0.0, 0.1])
    for _ in range(200):  # 3 s
        s = plant.step([0.0, 0.0])
    assert s.q[1] == lo and s.qd[1] == 0.0 and plant.state.held[1]
    for _ in range(200):
        s = plant.step([0.0, 12.0])
    assert s.q[1] == hi and s.qd[1] == 0.0 and plant.state.held[1]


def test_locked_rotor_mean_current_is_analytic():
    plant = Plant(DESC, model=MODEL, noise=False, q0=[0.0, 0.1])
    s = plant.step([0.6, 4.2])
    for j, v in enumerate(s.voltage_true):
        tau, period = 0.002 / 8.0, DESC.sample_period
        expect = v / 8.0 * (1 - tau / period * (1 - math.exp(-period / tau)))
        assert s.current_true[j] == pytest.approx(expect, rel=1e-12)
        assert s.i[j] == pytest.approx(v / 8.0 * (1 - math.exp(-period / tau)), rel=1e-12)
    s = plant.step([0.6, 4.2])
    assert s.current_true[0] == pytest.approx(s.voltage_true[0] / 8.0, rel=1e-9)


def _full_electrical_reference(volts, x0, period):
    """Stiff model with the current as a state (Radau, rtol 1e-10), friction off."""
    kt = np.array([j.drive.gear_ratio * j.drive.efficiency * j.drive.kt for j in DESC.joints])
    ke = np.array([j.drive.gear_ratio * j.drive.ke for j in DESC.joints])
    r, ind = 8.0, 0.002

    def rhs(t, x, v):
        q, qd, i = x[:2], x[2:4], x[4:6]
        qdd = np.linalg.solve(MODEL.mass_matrix_1(q), kt * i - MODEL.bias_1(q, qd))
        return np.concatenate([qd, qdd, (v - r * i - ke * qd) / ind, i])

    x, out = np.array([*x0, 0.0, 0.0, 0.0, 0.0]), []
    for v in volts:
        x[6:] = 0.0
        sol = solve_ivp(rhs, (0, period), x, method="Radau", rtol=1e-10, atol=1e-12,
                        args=(np.array(v),))  # fmt: skip
        x = sol.y[:, -1]
        out.append((x[:2], x[2:4], x[4:6], x[6:] / period))
    return out


def test_reduced_electrical_model_matches_stiff_reference():
    plant = Plant(DESC, model=MODEL, friction=False, limits=False, noise=False, q0=[0.0, 0.2])
    samples = [plant.step([6 * math.sin(0.1 * k) + 3 * math.cos(0.37 * k),
                           5 + 4 * math.sin(0.13 * k)]) for k in range(40)]  # fmt: skip
    ref = _full_electrical_reference([s.voltage_true for s in samples], [0.0, 0.2, 0.0, 0.0],
                                     DESC.sample_period)  # fmt: skip
    for s, (q, qd, i, i_mean) in zip(samples, ref, strict=True):
        assert np.abs(np.array(s.q) - q).max() < 2e-6
        assert np.abs(np.array(s.qd) - qd).max() < 5e-5
        assert np.abs(np.array(s.i) - i).max() < 1e-4
        assert np.abs(np.array(s.current_true) - i_mean).max() < 3e-4  # ADC step 3.9 mA
