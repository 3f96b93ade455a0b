"""Sensor and actuator models of the plant: PWM, ADC, encoder, seeding."""

import dataclasses
import math

import pytest

from guardid.plant import Plant
from guardid.plant.sensors import adc_quantise, adc_step, encoder_counts, pwm_quantise
from guardid.robot import load_robot


def test_pwm_levels_symmetric_and_clipped():
    step = 12.0 / 255
    assert pwm_quantise(0.0, 12.0, 8) == 0.0
    assert pwm_quantise(step * 0.49, 12.0, 8) == 0.0
    assert pwm_quantise(step * 0.51, 12.0, 8) == pytest.approx(step)
    assert pwm_quantise(-5.0, 12.0, 8) == -pwm_quantise(5.0, 12.0, 8)
    assert pwm_quantise(30.0, 12.0, 8) == 12.0
    assert pwm_quantise(-30.0, 12.0, 8) == -12.0
    v = pwm_quantise(3.3, 12.0, 8)
    assert abs(v - 3.3) <= step / 2 and abs(v / step - round(v / step)) < 1e-9


def test_adc_step_rounding_and_clipping():
    lsb = adc_step(2.0, 10)
    assert lsb == 4.0 / 1024
    assert adc_quantise(0.0, 2.0, 10) == 0.0
    assert adc_quantise(0.51 * lsb, 2.0, 10) == lsb
    assert adc_quantise(-0.49 * lsb, 2.0, 10) == 0.0
    assert adc_quantise(5.0, 2.0, 10) == 511 * lsb
    assert adc_quantise(-5.0, 2.0, 10) == -512 * lsb


def test_encoder_formula():
    per_rad = 500 * 48 / (2 * math.pi)
    assert encoder_counts(0.0, per_rad) == 0
    assert encoder_counts(2 * math.pi / 500, per_rad) in (47, 48)  # one motor turn
    assert encoder_counts(-1e-9, per_rad) == -1


def _run(seed, noise=True, n=200):
    p = Plant("guard", seed=seed, noise=noise, q0=[0.0, 0.2])
    return [p.step([6.0 * math.sin(0.05 * k), 4.5 + math.sin(0.07 * k)]) for k in range(n)]


def test_encoder_within_one_count_and_adc_grid():
    per_rad = [500 * 48 / (2 * math.pi), 1000 * 48 / (2 * math.pi)]
    lsb_i, lsb_v = adc_step(2.0, 10), adc_step(15.0, 10)
    for s in _run(3, noise=False):
        for j in (0, 1):
            err = s.q[j] - s.q_sensed[j]
            assert 0.0 <= err < 1.0 / per_rad[j]
            assert s.counts[j] == math.floor(s.q[j] * per_rad[j])
            assert abs(s.current[j] - s.current_true[j]) <= lsb_i / 2 + 1e-15
            assert s.current[j] / lsb_i == pytest.approx(round(s.current[j] / lsb_i), abs=1e-9)
            assert abs(s.voltage[j] - s.voltage_true[j]) <= lsb_v / 2 + 1e-15


def test_seed_determinism_and_noise_level():
    a, b, c = _run(7), _run(7), _run(8)
    assert a == b
    assert [s.current for s in a] != [s.current for s in c]
    assert [s.q for s in a] == [s.q for s in c]  # noise does not touch the physics
    dev = [s.current[0] - s.current_true[0] for s in a]
    sigma = math.sqrt(sum(d * d for d in dev) / len(dev))
    assert 0.005 < sigma < 0.012  # 8 mA noise + 3.9 mA steps


def test_single_channel_encoder_counts_signed_by_voltage():
    desc = load_robot("guard")
    enc = dataclasses.replace(desc.joints[0].encoder, quadrature=False, counts_per_rev=12)
    joints = (dataclasses.replace(desc.joints[0], encoder=enc), desc.joints[1])
    desc = dataclasses.replace(desc, joints=joints)
    p = Plant(desc, noise=False, q0=[0.0, 0.0])
    per_rad = 500 * 12 / (2 * math.pi)
    for _ in range(100):
        s = p.step([12.0, 4.2])
    assert s.counts[0] == math.floor(s.q[0] * per_rad)
    # coasting on after a reversal of the command: edges are counted with the new sign
    for _ in range(3):
        s = p.step([-0.5, 4.2])
    assert s.q[0] > 0.0 and s.counts[0] < math.floor(s.q[0] * per_rad)
