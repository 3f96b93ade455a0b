"""Excitation trajectories: analytic derivatives, rest constraints, YAML files and their errors."""

from __future__ import annotations

import math

import numpy as np
import pytest
import yaml

from guardid.errors import ConfigError
from guardid.excitation import (
    FourierTrajectory,
    SchroederMultisine,
    SumOfSines,
    Trajectory,
    load_trajectory,
    rest_basis,
    schroeder_phases,
)


def _fourier(seed=1, harmonics=5, start=(0.0, 0.2)):
    z = np.random.default_rng(seed).standard_normal((2, 2 * (harmonics - 1))) * 0.1
    return FourierTrajectory.from_free(z, 0.1, harmonics, start, joint_names=["pan", "tilt"])


def _sines():
    return SumOfSines(
        [[0.3, 0.1], [0.2, 0.05, 0.02]],
        [[0.1, 0.3], [0.2, 0.4, 0.5]],
        [[0.0, 1.0], [0.5, -0.3, 2.0]],
        [0.0, 0.2],
        joint_names=["pan", "tilt"],
    )


def _schroeder():
    return SchroederMultisine([0.1, 0.05], [[0.1, 0.3, 0.5], [0.2, 0.4, 0.6]], [0.0, 0.2])


TRAJECTORIES = [_fourier, _sines, _schroeder, SchroederMultisine.seed000_eq26]


@pytest.mark.parametrize("make", TRAJECTORIES)
def test_analytic_derivatives_match_finite_differences(make):
    traj = make()
    t = np.linspace(0.3, 9.7, 57)
    h = 1e-4  # s; central differences, error ~ h^2 * (w_max)^3 ~ 1e-8
    q = traj.positions
    fd_v = (q(t + h) - q(t - h)) / (2 * h)
    fd_a = (q(t + h) - 2 * q(t) + q(t - h)) / h**2
    np.testing.assert_allclose(traj.velocities(t), fd_v, atol=1e-7)
    np.testing.assert_allclose(traj.accelerations(t), fd_a, atol=1e-5)
    assert traj.positions(t).shape == (t.size, traj.n_joints)


@pytest.mark.parametrize("make", TRAJECTORIES)
def test_periodic(make):
    traj = make()
    t = np.linspace(0.0, 3.0, 31)
    for f in (traj.positions, traj.velocities, traj.accelerations):
        np.testing.assert_allclose(f(t + traj.period), f(t), atol=1e-9)
    assert traj.duration == traj.periods * traj.period


def test_fourier_rest_at_start_and_after_whole_periods():
    traj = _fourier(start=(0.1, -0.05))
    t = np.array([0.0, traj.period, 3 * traj.period])
    np.testing.assert_allclose(traj.positions(t), [[0.1, -0.05]] * 3, atol=1e-12)
    np.testing.assert_allclose(traj.velocities(t), 0.0, atol=1e-12)
    np.testing.assert_allclose(traj.accelerations(t), 0.0, atol=1e-12)


def test_rest_basis_spans_the_constraints():
    h = 5
    basis = rest_basis(h)
    assert basis.shape == (2 * h, 2 * h - 2)
    np.testing.assert_allclose(basis.T @ basis, np.eye(2 * h - 2), atol=1e-12)
    np.testing.assert_allclose(basis[:h].sum(axis=0), 0.0, atol=1e-12)
    np.testing.assert_allclose(np.arange(1, h + 1) @ basis[h:], 0.0, atol=1e-12)


def test_fourier_formula_matches_seed001_eq34():
    traj = FourierTrajectory(0.5, [0.1], [[0.2, -0.1]], [[0.05, 0.3]])
    t = np.array([0.7])
    w = 2 * math.pi * 0.5
    expected = 0.1 + sum(
        a / (w * k) * math.sin(w * k * 0.7) - b / (w * k) * math.cos(w * k * 0.7)
        for k, a, b in ((1, 0.2, 0.05), (2, -0.1, 0.3))
    )
    assert traj.positions(t)[0, 0] == pytest.approx(expected)


def test_seed000_eq26_as_printed():
    u = SchroederMultisine.seed000_eq26()
    t = np.linspace(0.0, 7.0, 50)
    expected = 0.5 * (np.sin(2 * t) + np.sin(2 * t - 2 * np.pi / 3) + np.sin(5 * t - 2 * np.pi))
    np.testing.assert_allclose(u.positions(t)[:, 0], expected, atol=1e-12)
    np.testing.assert_allclose(schroeder_phases(3), [0.0, -2 * np.pi / 3, -2 * np.pi])
    assert u.period == pytest.approx(2 * np.pi)
    assert u.signal == "input"


@pytest.mark.parametrize("make", TRAJECTORIES)
def test_yaml_round_trip(make, tmp_path):
    traj = make()
    path = tmp_path / "traj.yaml"
    traj.save(path, info={"cond": np.float64(3.5)})
    data = yaml.safe_load(path.read_text())
    assert data["kind"] == traj.kind and data["info"] == {"cond": 3.5}
    back = load_trajectory(path)
    assert type(back) is type(traj)
    assert back.to_dict() == traj.to_dict()
    t = np.linspace(0.0, 10.0, 101)
    np.testing.assert_allclose(back.positions(t), traj.positions(t), rtol=0, atol=1e-15)
    assert type(back).load(path).to_dict() == traj.to_dict()


def _write(tmp_path, data) -> str:
    path = tmp_path / "bad.yaml"
    path.write_text(data if isinstance(data, str) else yaml.safe_dump(data))
    return str(path)


def _broken(key, value):
    data = _fourier().to_dict()
    if value is None:
        del data[key]
    else:
        data[key] = value
    return data


@pytest.mark.parametrize(
    ("data", "key"),
    [
        (_broken("kind", None), "kind"),
        (_broken("kind", "spline"), "kind"),
        (_broken("base_freq", None), "base_freq"),
        (_broken("base_freq", -1.0), "base_freq"),
        (_broken("base_freq", "fast"), "base_freq"),
        (_broken("a", [[0.1, 0.2]]), "a"),
        (_broken("b", [[0.1, 0.2], [0.1, 0.2]]), "b[0]"),
        (_broken("q0", [0.0, "x"]), "q0[1]"),
        (_broken("harmonics", 0), "harmonics"),
        (_broken("joints", ["pan"]), "joints"),
        (_broken("colour", "red"), "colour"),
        ({**_sines().to_dict(), "frequencies": [[0.1, -0.3], [0.2, 0.4, 0.5]]}, "frequencies[0]"),
        ({**_schroeder().to_dict(), "signal": "torque"}, "signal"),
        ({**_schroeder().to_dict(), "amplitude": [0.1]}, "amplitude"),
    ],
)
def test_malformed_files_name_file_and_key(tmp_path, data, key):
    path = _write(tmp_path, data)
    with pytest.raises(ConfigError) as err:
        Trajectory.load(path)
    message = str(err.value)
    assert message.startswith(f"{path}: {key}: ")
    assert "\n" not in message


@pytest.mark.parametrize("text", ["kind: [unclosed\n", "- just\n- a list\n", ""])
def test_unreadable_yaml_is_one_line(tmp_path, text):
    path = _write(tmp_path, text)
    with pytest.raises(ConfigError, match=f"^{path}: "):
        load_trajectory(path)


def test_missing_file_and_wrong_kind(tmp_path):
    with pytest.raises(ConfigError, match="nope.yaml: cannot read"):
        load_trajectory(tmp_path / "nope.yaml")
    path = tmp_path / "s.yaml"
    _sines().save(path)
    with pytest.raises(ConfigError, match="kind: expected 'fourier'"):
        FourierTrajectory.load(path)


def test_scaled_keeps_centre():
    traj = _fourier(start=(0.1, 0.2))
    half = traj.scaled([0.5, 2.0])
    t = np.linspace(0, 10, 41)
    np.testing.assert_allclose(half.positions(0.0)[0], [0.1, 0.2], atol=1e-12)
    dq = traj.positions(t) - traj.centre
    np.testing.assert_allclose(half.positions(t) - half.centre, dq * [0.5, 2.0], atol=1e-12)
    np.testing.assert_allclose(_sines().scaled(0.0).positions(t), [[0.0, 0.2]] * t.size)
