"""A twin: the robot as identified, to simulate (``guardid simulate --params``,
``sim://guard?params=params.yaml``).

The base parameters of one set (a method of a params file, or a reference values file)
determine the rigid body's dynamics completely: M(q) and the bias torque come from the base
regressor (:class:`guardid.closedloop.simulate.BaseDynamics`, as the closed-loop methods
and ``validate --simulate`` use), so no full standard parameter set is needed. Each
joint's friction takes the set's Fv, Fc, Fo (the static level stays the YAML's); motors,
encoders, sensors, limits and PID gains stay the robot YAML's. The set is refused (one
line) when it is not a physical robot's anywhere in the joints' travel: a mass matrix not
positive definite, negative damping, or an inertia too small to integrate
(:func:`~guardid.closedloop.simulate.stiffness_substeps` on a grid of positions).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from guardid.errors import ConfigError

GRID = 13
"""Positions per joint where the twin's mass matrix is checked (within the limits, or
over one turn for an unlimited joint)."""


@dataclass(frozen=True)
class Twin:
    """What the plant needs to run the identified robot: ``description`` (the YAML with
    the set's friction), ``model`` (:class:`~guardid.closedloop.simulate.BaseDynamics`),
    ``substeps`` (RK4 steps per tick), ``label`` (the set's)."""

    description: object
    model: object
    substeps: int
    label: str


def travel_grid(description) -> np.ndarray:
    """(GRID^n, n) joint positions [rad] covering each joint's travel."""
    axes = []
    for j in description.joints:
        pos = j.limits.position if j.limits is not None else None
        lo, hi = (pos[0], pos[1]) if pos else (-math.pi, math.pi)
        axes.append(np.linspace(lo, hi, GRID))
    mesh = np.meshgrid(*axes, indexing="ij")
    return np.stack([m.ravel() for m in mesh], axis=1)


def pick_set(path, description, method: str | None):
    """The :class:`~guardid.identify.validation.ParameterSet` of ``path`` for ``method``
    (a params file's method name, any case; default: its first method)."""
    from guardid.identify.validation import load_sets

    sets = load_sets(path, description)
    if method is None:
        return _finite(sets[0])
    for s in sets:
        if s.label.rsplit(":", 1)[-1].lower() == method.lower():
            return _finite(s)
    known = ", ".join(s.label.rsplit(":", 1)[-1].lower() for s in sets)
    raise ConfigError(f"{path}: method {method!r}: not in the file (known: {known})")


def _finite(chosen):
    """``chosen`` (a ParameterSet) when its values are finite, else a one-line ConfigError."""
    from guardid.identify.validation import not_finite

    why = not_finite(chosen)
    if why is not None:
        raise ConfigError(f"{why}: no robot to simulate (give another --method)")
    return chosen


def _check_robot(path, description, option: str) -> None:
    """One-line ConfigError when the params file ``path`` was identified for another robot
    than ``description`` (its ``robot:``; a reference values file has none)."""
    from guardid.identify.validation import first_params

    stored = first_params([path])
    named = stored[1].get("robot") if stored else None
    if named and str(named) != description.name:
        raise ConfigError(
            f"{path}: robot: parameters of robot {named}, but {option} would run them on robot "
            f"{description.name} (give --robot {named}'s description)"
        )


def load_twin(path, description, method: str | None = None, option: str = "params") -> Twin:
    """The :class:`Twin` of ``description`` with the base parameters of ``path`` (a params
    file or a reference values file); one-line ConfigError naming ``option`` and the file
    when the robot cannot be simulated or the set is not a physical robot's."""
    from guardid.closedloop.simulate import (
        BaseDynamics,
        NotSimulable,
        check_simulable,
        estimated_description,
        stiffness_substeps,
    )
    from guardid.dynamics import build_model
    from guardid.errors import GuardidError

    try:
        check_simulable(description)
    except GuardidError as exc:
        raise ConfigError(str(exc).replace("--method iv/didim", option)) from None
    _check_robot(path, description, option)
    chosen = pick_set(path, description, method)
    model = build_model(description)
    names = tuple(model.base.names)
    theta = np.array([chosen.values[n] for n in names], dtype=float)
    try:
        substeps = stiffness_substeps(description, model, theta, travel_grid(description))
    except NotSimulable as exc:
        raise ConfigError(f"{option}: {chosen.label}: not a robot to simulate: {exc}") from None
    twin_desc = estimated_description(description, names, theta)
    return Twin(twin_desc, BaseDynamics(model, theta), substeps, chosen.label)
