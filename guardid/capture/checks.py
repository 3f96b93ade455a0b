"""What a capture checks before anything moves: the trajectory against the robot
description, and the robot's INFO (handshake answer) against the same description."""

from __future__ import annotations

import math

import numpy as np

from guardid.errors import ConfigError
from guardid.excitation.limits import first_violation
from guardid.protocol import ENUMS

#: INFO capabilities a capture relies on (bits of ``INFO.capabilities``).
NEEDED_CAPABILITIES = ("current_sense", "voltage_sense", "setpoint_buffer", "watchdog")


def counts_per_rad(description) -> np.ndarray:
    """(n,) encoder counts per joint radian (the description's
    :attr:`~guardid.robot.description.JointDescription.counts_per_rad`)."""
    return np.array([j.counts_per_rad for j in description.joints])


def _robot_name(description) -> str:
    return str(description.source or description.name)


def check_trajectory(trajectory, description, duration_s: float, source: str) -> None:
    """ConfigError unless ``trajectory`` has the description's joints (their names, in
    order, when the trajectory names them) and stays within
    their position, velocity and acceleration limits over ``duration_s`` [s] (one period
    suffices for a periodic trajectory), on the 1 ms grid ``guardid excite`` checks."""
    n_traj, n_robot = trajectory.n_joints, len(description.joints)
    if n_traj != n_robot:
        names = ", ".join(j.name for j in description.joints)
        raise ConfigError(
            f"{source}: has {n_traj} joint{'s' * (n_traj != 1)}, robot {description.name} "
            f"has {n_robot} ({names}); nothing moved"
        )
    names = getattr(trajectory, "joint_names", None)
    robot_names = [j.name for j in description.joints]
    if names is not None and list(names) != robot_names:
        raise ConfigError(
            f"{source}: joints: {', '.join(names)}, robot {description.name} has "
            f"{', '.join(robot_names)} (in this order); nothing moved"
        )
    bad = first_violation(trajectory, description, horizon_s=duration_s)
    if bad is not None:
        raise ConfigError(
            f"{source}: {bad.describe()} (robot {_robot_name(description)}); nothing moved"
        )


def check_info(info: dict, description, port: str) -> None:
    """ConfigError unless the robot's INFO agrees with the description: joint count,
    encoder counts per joint revolution, tick period [s] = sample period, and the
    capabilities a capture needs."""
    where = f"the robot on {port} reports"
    robot = _robot_name(description)
    n = len(description.joints)
    if info["joint_count"] != n:
        raise ConfigError(f"{robot}: describes {n} joints, {where} {info['joint_count']}")
    expected = [int(round(c * 2 * math.pi)) for c in counts_per_rad(description)]
    got = [int(c) for c in info["counts_per_rev"]]
    for joint, want, have in zip(description.joints, expected, got, strict=True):
        if want != have:
            raise ConfigError(
                f"{robot}: joint {joint.name}: {want} encoder counts per joint revolution "
                f"(counts_per_rev x gear_ratio), {where} {have}"
            )
    tick_s = float(info["tick_period"])
    if abs(tick_s - description.sample_period) > 0.5e-6:  # INFO carries whole microseconds
        raise ConfigError(
            f"{robot}: sample_period {description.sample_period * 1e3:g} ms, "
            f"{where} a tick period of {tick_s * 1e3:g} ms"
        )
    bits = ENUMS["capability"]
    missing = [c for c in NEEDED_CAPABILITIES if not info["capabilities"] >> bits[c] & 1]
    if missing:
        raise ConfigError(f"port {port}: the robot lacks {', '.join(missing)} (INFO capabilities)")


def check_feedforward_capability(info: dict, port: str) -> None:
    """ConfigError unless the robot's INFO has the feedforward capability (SETPOINT_FF,
    protocol version 2): older firmware is captured without --feedforward."""
    if not info["capabilities"] >> ENUMS["capability"]["feedforward"] & 1:
        raise ConfigError(
            f"port {port}: the robot's firmware (protocol version {info['protocol_version']}) "
            "lacks the feedforward capability (INFO capabilities bit "
            f"{ENUMS['capability']['feedforward']}); update it, or capture without "
            "--feedforward; nothing moved"
        )
