"""Optimised excitation for the guard robot and the ``guardid excite`` command."""

from __future__ import annotations

import re

import numpy as np
import pytest
from click.testing import CliRunner

from guardid.cli import main
from guardid.dynamics import build_model
from guardid.excitation import (
    FourierTrajectory,
    JointLimits,
    limit_usage,
    load_trajectory,
    optimise_fourier,
    regressor_cond,
)
from guardid.excitation.limits import fixed
from guardid.excitation.presets import robot_schroeder, robot_sines
from guardid.robot import load_robot


@pytest.fixture(scope="module")
def guard():
    desc = load_robot("guard")
    return desc, build_model(desc)


@pytest.fixture(scope="module")
def optimised(guard):
    desc, model = guard
    lines = []
    result = optimise_fourier(
        model, desc, harmonics=5, base_freq=0.1, seed=0, progress=lines.append
    )
    return result, lines


def _assert_within_limits(traj, desc, dt=1e-3):
    """Every limit of the description holds on a dt grid over a full period."""
    t = np.arange(0.0, traj.period + dt / 2, dt)
    q, qd, qdd = traj.states(t)
    for j, joint in enumerate(desc.joints):
        lim = joint.limits
        assert np.abs(qd[:, j]).max() <= lim.velocity
        assert np.abs(qdd[:, j]).max() <= lim.acceleration
        if lim.position is not None:
            assert lim.position[0] <= q[:, j].min() and q[:, j].max() <= lim.position[1]


def test_optimised_cond_and_limits(guard, optimised):
    desc, model = guard
    result, lines = optimised
    traj = result.trajectory
    assert isinstance(traj, FourierTrajectory) and traj.period == pytest.approx(10.0)
    assert result.cond <= result.start_cond / 3
    assert result.cond < min(result.guess_conds)  # better than every seeded guess
    assert result.cond == pytest.approx(regressor_cond(model, traj))
    # its run time is a figure of bench/bench_excitation.py, not asserted here
    _assert_within_limits(traj, desc)
    _assert_within_limits(result.start_trajectory, desc)
    assert all(u.within for u in limit_usage(traj, desc))
    assert lines and lines[0].startswith("start 1/4 iteration 0: cond")


def test_optimised_starts_and_ends_at_rest(optimised):
    traj = optimised[0].trajectory
    t = np.array([0.0, traj.period])
    np.testing.assert_allclose(traj.positions(t), 0.0, atol=1e-12)
    np.testing.assert_allclose(traj.velocities(t), 0.0, atol=1e-12)
    np.testing.assert_allclose(traj.accelerations(t), 0.0, atol=1e-12)


def test_optimisation_is_deterministic(guard, optimised):
    desc, model = guard
    again = optimise_fourier(model, desc, seed=0, starts=1)
    first = optimise_fourier(model, desc, seed=0, starts=1)
    np.testing.assert_array_equal(again.trajectory.a, first.trajectory.a)
    assert again.start_cond == optimised[0].start_cond


def test_start_pose_elsewhere(guard):
    desc, model = guard
    start = np.radians([30.0, 10.0])
    result = optimise_fourier(model, desc, harmonics=3, start=start, seed=2, starts=1)
    np.testing.assert_allclose(result.trajectory.positions(0.0)[0], start, atol=1e-12)
    _assert_within_limits(result.trajectory, desc)


@pytest.mark.parametrize("make", [robot_sines, robot_schroeder])
def test_presets_fit_the_limits(guard, make):
    desc, _ = guard
    traj = make(desc, 5, 0.1, np.zeros(2))
    _assert_within_limits(traj, desc)
    # scaled up to the (5 % margin) limits on at least one quantity per joint
    shrunk = JointLimits.of(desc, 0.05)
    for j, u in enumerate(limit_usage(traj, desc)):
        ratios = [u.velocity_peak / shrunk.vel[j], u.acceleration_peak / shrunk.acc[j]]
        if u.position_limit is not None:
            ratios += [u.position_used[1] / shrunk.hi[j], u.position_used[0] / shrunk.lo[j]]
        assert max(ratios) == pytest.approx(1.0, abs=1e-3)


def test_cli_end_to_end(tmp_path):
    out = tmp_path / "traj.yaml"
    args = ["excite", "--robot", "guard", "--harmonics", "5", "--base-freq", "0.1", "--seed", "0"]
    result = CliRunner().invoke(main, [*args, "--starts", "2", "-o", str(out)])
    assert result.exit_code == 0, result.output
    text = result.output
    assert "condition number: " in text and "starting guess " in text
    assert "joint pan: position unlimited, used " in text
    assert "joint tilt: position -10.0..35.0 deg used " in text
    assert "% of limit; acceleration " in text
    rest = re.search(r"starts and ends \(after each whole period\) at rest at \((.*)\) deg", text)
    assert rest, text
    np.testing.assert_allclose([float(x) for x in rest[1].split(",")], [0.0, 0.0], atol=0.05)
    assert "-0.0" not in text  # no signed zero in what a user reads
    traj = load_trajectory(out)
    assert isinstance(traj, FourierTrajectory) and traj.harmonics == 5
    cond = float(text.split("condition number: ")[1].split()[0])
    model = build_model(load_robot("guard"))
    assert cond == pytest.approx(regressor_cond(model, traj), rel=1e-3)


@pytest.mark.parametrize("kind", ["sines", "schroeder"])
def test_cli_other_kinds(tmp_path, kind):
    out = tmp_path / "t.yaml"
    result = CliRunner().invoke(main, ["excite", "--kind", kind, "-o", str(out)])
    assert result.exit_code == 0, result.output
    assert "not at rest at t = 0" in result.output
    assert load_trajectory(out).kind == kind


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["--robot", "nosuch"], "nosuch: no such robot"),
        (["--robot", "flexlink"], "serial-chain"),
        (["--start", "0,50"], "start pose: joint tilt at 50.0 deg is outside"),
        (["--start", "0"], "--start: expected 2"),
        (["--harmonics", "1"], "at least 2"),
    ],
)
def test_cli_errors_are_one_line(tmp_path, args, message):
    result = CliRunner().invoke(main, ["excite", *args, "--no-optimise", "-o", str(tmp_path / "x")])
    assert result.exit_code == 2
    assert message in result.output
    assert result.output.startswith("guardid: error: ") and result.output.count("\n") == 1
    assert "Traceback" not in result.output


@pytest.mark.parametrize(
    ("value", "text"),
    [(-1e-17, "0.0"), (-0.0, "0.0"), (-0.049, "0.0"), (-0.051, "-0.1"), (0.06, "0.1"),
     (-7.7, "-7.7"), (32.68, "32.7")],
)  # fmt: skip
def test_printed_degrees_have_no_signed_zero(value, text):
    """Numbers that round to zero print unsigned; others keep their sign and digit."""
    assert fixed(value) == text
