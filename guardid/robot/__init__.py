"""Robot description: one YAML file says what a robot is (schema: docs/ROBOT_YAML.md)."""

from guardid.robot.description import (
    DH,
    PID,
    STANDARD_NAMES,
    ChainDescription,
    Drive,
    Encoder,
    FlexibleLinkDescription,
    Friction,
    JointDescription,
    Limits,
    LinkDescription,
    ParameterRange,
    Rotor,
    Sensor,
)
from guardid.robot.loader import DEFAULT_VOLTAGE_SENSOR, load_robot, parse_robot, shipped_path

__all__ = [
    "DH",
    "PID",
    "STANDARD_NAMES",
    "ChainDescription",
    "Drive",
    "Encoder",
    "FlexibleLinkDescription",
    "Friction",
    "JointDescription",
    "Limits",
    "LinkDescription",
    "ParameterRange",
    "Rotor",
    "Sensor",
    "DEFAULT_VOLTAGE_SENSOR",
    "load_robot",
    "parse_robot",
    "shipped_path",
]
