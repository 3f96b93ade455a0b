"""Mechanical-only rotor (YAML ``rotor``): schema errors and the coupled rotor's mass matrix."""

from __future__ import annotations

import copy

import numpy as np
import pytest
import yaml

from guardid.dynamics import build_model
from guardid.errors import ConfigError
from guardid.robot import parse_robot, shipped_path

BASE = yaml.safe_load(shipped_path("dfki_double_pendulum").read_text())


def _with(joint: int, **changes):
    data = copy.deepcopy(BASE)
    for key, value in changes.items():
        if value is None:
            data["joints"][joint].pop(key, None)
        else:
            data["joints"][joint][key] = value
    return data


@pytest.mark.parametrize(
    ("joint", "changes", "message"),
    [
        (1, {"rotor": {"gear_ratio": 6, "inertia": 1e-4, "coupling": 2}},
         "joints[1].rotor.coupling: expected -1, 0 or 1, got 2"),
        (1, {"rotor": {"gear_ratio": 0, "inertia": 1e-4}},
         "joints[1].rotor.gear_ratio: must be > 0"),
        (1, {"rotor": {"gear_ratio": 6}}, "joints[1].rotor.inertia: missing required key"),
        (1, {"rotor": {"gear_ratio": 6, "inertia": -1.0}}, "joints[1].rotor.inertia: must be >= 0"),
        (1, {"rotor": {"gear_ratio": 6, "inertia": 1e-4, "kt": 0.1}},
         "joints[1].rotor.kt: unknown key"),
        (0, {"rotor": {"gear_ratio": 6, "inertia": 1e-4, "coupling": 1}},
         "joints[0].rotor.coupling: the first joint's motor sits on the base"),
        (0, {"dh": {"a": 0.3, "alpha": 1.5707963, "d": 0.0, "theta": 0.0}},
         "joints[1].rotor.coupling: needs every earlier joint axis parallel"),
    ],
)  # fmt: skip
def test_rotor_errors_are_one_line(joint, changes, message):
    with pytest.raises(ConfigError) as exc:
        parse_robot(_with(joint, **changes), "dfki.yaml")
    text = str(exc.value)
    assert "\n" not in text and text.startswith("dfki.yaml: " + message), text


def test_rotor_and_drive_are_exclusive():
    drive = {"gear_ratio": 6, "efficiency": 1, "resistance": 1, "inductance": 0, "kt": 0.1,
             "ke": 0.1, "rotor_inertia": 1e-4, "supply_voltage": 24, "pwm_bits": 10}  # fmt: skip
    with pytest.raises(ConfigError, match=r"joints\[1\]\.rotor: the joint has a drive"):
        parse_robot(_with(1, drive=drive), "dfki.yaml")


@pytest.mark.parametrize("coupling", [-1, 0, 1])
def test_rotor_mass_matrix(coupling):
    """Rotor 2 on link 1 spinning at q1' + s N q2' adds J [1, sN; sN, N^2] to M (s = +-1);
    uncoupled: N^2 J on M22 only. Fast and generic evaluators agree."""
    n, j = 6.0, 1e-4
    rotor = {"gear_ratio": n, "inertia": j, "coupling": coupling}
    with_rotor = build_model(parse_robot(_with(1, rotor=rotor)))
    without = build_model(parse_robot(_with(1, rotor=None)))
    q = np.array([[0.3, -1.2]])
    diff = with_rotor.mass_matrix(q)[0] - without.mass_matrix(q)[0]
    s = float(coupling)
    if coupling == 0:
        expected = np.array([[0.0, 0.0], [0.0, n * n * j]])
    else:
        expected = j * np.array([[1.0, s * n], [s * n, n * n]])
    np.testing.assert_allclose(diff, expected, atol=1e-15)
    np.testing.assert_allclose(with_rotor.mass_matrix_1(q[0]), with_rotor.mass_matrix(q)[0])
    qd, qdd = np.array([[1.0, -2.0]]), np.array([[3.0, 4.0]])
    y = with_rotor.regressor(q, qd, qdd) @ with_rotor.params
    np.testing.assert_allclose(y, with_rotor.inverse_dynamics(q, qd, qdd), atol=1e-12)
