"""Robot description loading and validation (guardid.robot)."""

from __future__ import annotations

import copy
import math

import numpy as np
import pytest
import yaml

from guardid.errors import ConfigError
from guardid.robot import (
    DEFAULT_VOLTAGE_SENSOR,
    ChainDescription,
    FlexibleLinkDescription,
    load_robot,
    shipped_path,
)


@pytest.fixture()
def guard_data():
    return yaml.safe_load(shipped_path("guard").read_text())


def _load(tmp_path, data, name="guard.yaml"):
    path = tmp_path / name
    path.write_text(yaml.safe_dump(data))
    return load_robot(path)


def _error(tmp_path, data) -> str:
    with pytest.raises(ConfigError) as info:
        _load(tmp_path, data)
    msg = str(info.value)
    assert "\n" not in msg
    assert msg.startswith("guard.yaml: ")
    return msg


def test_guard_defaults():
    d = load_robot("guard")
    assert isinstance(d, ChainDescription)
    assert d.sample_period == 0.015
    np.testing.assert_array_equal(d.gravity, [0, 0, -9.81])
    j1, j2 = d.joints
    assert j1.dh.d == 0.45 and math.isclose(j1.dh.alpha, math.pi / 2) and j2.dh.a == 0.10
    assert j1.limits.position is None
    lo, hi = j2.limits.position
    assert math.isclose(math.degrees(lo), -10) and math.isclose(math.degrees(hi), 35)
    assert (j1.drive.gear_ratio, j2.drive.gear_ratio) == (500, 1000)
    for j in (j1, j2):
        dr = j.drive
        assert (dr.efficiency, dr.resistance, dr.inductance, dr.kt, dr.ke) == (
            0.7,
            8.0,
            0.002,
            0.02,
            0.02,
        )
        assert (dr.rotor_inertia, dr.supply_voltage, dr.pwm_bits) == (2e-6, 12.0, 8)
        assert j.encoder.counts_per_rev == 48 and j.encoder.quadrature
        assert (j.current_sensor.range, j.current_sensor.adc_bits) == (2.0, 10)
        assert j.current_sensor.noise == 0.008
        assert (j.voltage_sensor.range, j.voltage_sensor.noise) == (15.0, 0.01)
        assert (j.pid.kp, j.pid.ki, j.pid.kd) == (40.0, 10.0, 1.0)
        # velocity limits below the no-load speed V / (ke N)
        assert j.limits.velocity < dr.supply_voltage / (dr.ke * dr.gear_ratio)
    assert (j1.friction.viscous, j1.friction.coulomb) == (0.8, 0.6)
    assert (j2.friction.viscous, j2.friction.coulomb) == (1.2, 0.9)
    l1, l2 = d.links
    assert l1.mass == 1.5 and l2.mass == 3.5
    np.testing.assert_array_equal(l1.com, [0, -0.1, 0])
    np.testing.assert_array_equal(l2.com, [0.12, 0.02, 0])
    np.testing.assert_array_equal(np.diag(l2.inertia), [0.004, 0.3, 0.3])


def test_other_shipped_files():
    p = load_robot("planar2")
    assert p.sample_period == 0.001 and p.joints[0].drive is None
    assert p.joints[0].friction is None and p.joints[0].voltage_sensor is None
    f = load_robot("flexlink")
    assert isinstance(f, FlexibleLinkDescription)
    assert (f.mass, f.l1, f.l2, f.stiffness, f.hub_inertia) == (3.0, 1.0, 0.5, 2.0, 2.0)
    assert [f.parameters[k].nominal for k in ("alpha", "gamma", "k")] == [1.0, 2.0, 2.4]


def test_load_by_path_and_defaults(tmp_path, guard_data):
    data = copy.deepcopy(guard_data)
    del data["sample_period"], data["gravity"], data["joints"][0]["voltage_sensor"]
    data["links"][0]["inertia"] = [[0.02, 0, 0], [0, 0.02, 0], [0, 0, 0.02]]
    d = _load(tmp_path, data)
    assert d.sample_period == 0.015 and d.joints[0].voltage_sensor == DEFAULT_VOLTAGE_SENSOR
    np.testing.assert_array_equal(d.links[0].inertia, 0.02 * np.eye(3))


def test_missing_file():
    with pytest.raises(ConfigError, match="nosuch.yaml"):
        load_robot("nosuch.yaml")


def test_unknown_key(tmp_path, guard_data):
    guard_data["joints"][1]["drive"]["gear_ration"] = 3
    msg = _error(tmp_path, guard_data)
    assert "joints[1].drive.gear_ration: unknown key" in msg


def test_unknown_top_key(tmp_path, guard_data):
    guard_data["gravit"] = [0, 0, -9.81]
    assert "gravit: unknown key" in _error(tmp_path, guard_data)


def test_missing_key(tmp_path, guard_data):
    del guard_data["links"][1]["mass"]
    assert "links[1].mass: missing required key" in _error(tmp_path, guard_data)


def test_mistyped_value(tmp_path, guard_data):
    guard_data["joints"][1]["drive"]["gear_ratio"] = "abc"
    msg = _error(tmp_path, guard_data)
    assert msg == "guard.yaml: joints[1].drive.gear_ratio: expected a number, got 'abc'"


def test_mistyped_int_and_choice(tmp_path, guard_data):
    data = copy.deepcopy(guard_data)
    data["joints"][0]["encoder"]["counts_per_rev"] = 4.5
    assert "joints[0].encoder.counts_per_rev: expected an integer" in _error(tmp_path, data)
    guard_data["joints"][0]["type"] = "spherical"
    assert "joints[0].type: expected one of revolute, prismatic" in _error(tmp_path, guard_data)


@pytest.mark.parametrize(
    ("edit", "expect"),
    [
        (lambda d: d["links"][0].__setitem__("mass", 0.0), "links[0].mass: must be > 0"),
        (
            lambda d: d["joints"][0]["drive"].__setitem__("efficiency", 1.2),
            "joints[0].drive.efficiency: must be <= 1",
        ),
        (
            lambda d: d["joints"][0]["drive"].__setitem__("efficiency", 0.0),
            "joints[0].drive.efficiency: must be > 0",
        ),
        (
            lambda d: d["joints"][1]["limits"].__setitem__("position", [0.5, -0.1]),
            "joints[1].limits.position: lower limit",
        ),
        (
            lambda d: d["links"][1]["inertia"].__setitem__("xx", -0.1),
            "links[1].inertia: inertia tensor is not positive semi-definite",
        ),
        (
            lambda d: d["links"][1]["inertia"].__setitem__("xx", 0.7),
            "links[1].inertia: principal moments violate the triangle inequality",
        ),
        (
            lambda d: d["links"][1].__setitem__("inertia", [[1, 0.1, 0], [0, 1, 0], [0, 0, 1]]),
            "links[1].inertia: inertia tensor is not symmetric",
        ),
        (
            lambda d: d["joints"][0]["limits"].__setitem__("velocity", -1),
            "joints[0].limits.velocity: must be > 0",
        ),
        (
            lambda d: d["links"][1].__setitem__("known_zero", ["MX"]),
            "links[1].known_zero: MX is listed as zero",
        ),
    ],
)
def test_bad_physics(tmp_path, guard_data, edit, expect):
    edit(guard_data)
    assert expect in _error(tmp_path, guard_data)


def test_bad_model_and_lengths(tmp_path, guard_data):
    data = copy.deepcopy(guard_data)
    data["model"] = "tree"
    assert "model: expected one of serial_chain, flexible_link" in _error(tmp_path, data)
    guard_data["links"].pop()
    assert "links: expected a list of 2 items, got 1" in _error(tmp_path, guard_data)


def test_flexlink_validation(tmp_path):
    data = yaml.safe_load(shipped_path("flexlink").read_text())
    data["parameters"]["k"]["nominal"] = 9.0
    path = tmp_path / "flex.yaml"
    path.write_text(yaml.safe_dump(data))
    with pytest.raises(ConfigError, match=r"^flex.yaml: parameters.k.nominal: 9 is outside"):
        load_robot(path)
