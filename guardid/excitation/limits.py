"""Joint limits of a robot description, checked on a dense time grid.

Limits come from ``desc.joints[j].limits`` (position (lo, hi) [rad] or None, velocity
[rad/s], acceleration [rad/s^2]). A safety ``margin`` (fraction, e.g. 0.05) shrinks them:
the position range by margin * (hi - lo) at each end, the velocity and acceleration limits
to (1 - margin) times their value.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from guardid.errors import GuardidError
from guardid.excitation.trajectory import Trajectory

DENSE_DT = 1e-3  # s, grid step of the limit checks
SLOW_FRACTION = 0.05  # |qd| below this fraction of the velocity limit counts as slow (stiction)


def fixed(value: float, decimals: int = 1) -> str:
    """``value`` in fixed point with ``decimals`` digits, never signed zero: a value that
    rounds to zero prints as ``0.0``, not ``-0.0`` (output text must not depend on the sign
    of a zero that floating point leaves behind, e.g. -1e-17 rad)."""
    return f"{round(float(value), decimals) + 0.0:.{decimals}f}"


class ExcitationError(GuardidError):
    """An excitation request cannot be met (start pose outside the limits, bad options)."""


@dataclass(frozen=True)
class JointLimits:
    """Limits (n,) arrays: lo, hi [rad] (-inf/inf when unlimited), vel [rad/s], acc [rad/s^2]."""

    names: list[str]
    lo: np.ndarray
    hi: np.ndarray
    vel: np.ndarray
    acc: np.ndarray

    @classmethod
    def of(cls, desc, margin: float = 0.0) -> JointLimits:
        """Limits of a ChainDescription, shrunk by ``margin`` (see module docstring)."""
        lo, hi, vel, acc = [], [], [], []
        for joint in desc.joints:
            lim = joint.limits
            if lim.position is None:
                lo.append(-math.inf)
                hi.append(math.inf)
            else:
                span = lim.position[1] - lim.position[0]
                lo.append(lim.position[0] + margin * span)
                hi.append(lim.position[1] - margin * span)
            vel.append((1.0 - margin) * lim.velocity)
            acc.append((1.0 - margin) * lim.acceleration)
        names = [j.name for j in desc.joints]
        return cls(names, *(np.array(x, dtype=float) for x in (lo, hi, vel, acc)))

    def check_pose(self, pose) -> None:
        """ExcitationError unless pose (n,) [rad] lies within the position limits."""
        for j, q in enumerate(np.asarray(pose, dtype=float)):
            if not self.lo[j] <= q <= self.hi[j]:
                raise ExcitationError(
                    f"start pose: joint {self.names[j]} at {fixed(math.degrees(q))} deg is outside "
                    f"{fixed(math.degrees(self.lo[j]))}..{fixed(math.degrees(self.hi[j]))} deg "
                    "(limits with the safety margin)"
                )


@dataclass(frozen=True)
class JointUsage:
    """How much of one joint's limits a trajectory uses (dense-grid extremes)."""

    name: str
    position_limit: tuple[float, float] | None  # rad
    position_used: tuple[float, float]  # rad
    velocity_peak: float  # rad/s
    velocity_limit: float  # rad/s
    acceleration_peak: float  # rad/s^2
    acceleration_limit: float  # rad/s^2
    slow_fraction: float  # share of the time with |qd| < SLOW_FRACTION * velocity limit

    @property
    def velocity_ratio(self) -> float:
        return self.velocity_peak / self.velocity_limit

    @property
    def acceleration_ratio(self) -> float:
        return self.acceleration_peak / self.acceleration_limit

    @property
    def within(self) -> bool:
        """True when no limit is exceeded."""
        ok = self.velocity_ratio <= 1.0 and self.acceleration_ratio <= 1.0
        if self.position_limit is not None:
            lo, hi = self.position_limit
            ok = ok and lo <= self.position_used[0] and self.position_used[1] <= hi
        return ok

    def describe(self) -> str:
        """One line, e.g. 'joint tilt: position -10.0..35.0 deg used -8.1..31.2 deg; ...'."""
        used = "{}..{} deg".format(*map(fixed, np.degrees(self.position_used)))
        if self.position_limit is None:
            pos = f"position unlimited, used {used}"
        else:
            lo, hi = map(fixed, np.degrees(self.position_limit))
            pos = f"position {lo}..{hi} deg used "
            pos += used
        return (
            f"joint {self.name}: {pos}; velocity {100 * self.velocity_ratio:.0f} % of limit; "
            f"acceleration {100 * self.acceleration_ratio:.0f} %"
        )


def dense_times(traj: Trajectory, dt: float = DENSE_DT, horizon_s: float | None = None):
    """Times [s] every dt over one period including both ends (60 s if aperiodic), or
    over ``horizon_s`` [s] when given and shorter than the period."""
    horizon = traj.period if math.isfinite(traj.period) else 60.0
    if horizon_s is not None and (horizon_s < horizon or not math.isfinite(traj.period)):
        horizon = horizon_s
    steps = max(int(math.ceil(horizon / dt)), 1)
    return np.linspace(0.0, horizon, steps + 1)


def dense_states(traj: Trajectory, dt: float = DENSE_DT, horizon_s: float | None = None):
    """(t, (q, qd, qdd)) on :func:`dense_times`: the grid every limit check here uses."""
    t = dense_times(traj, dt, horizon_s)
    return t, traj.states(t)


def limit_usage(traj: Trajectory, desc, dt: float = DENSE_DT) -> list[JointUsage]:
    """Per joint usage of the description's (unshrunk) limits on a grid of step dt [s]."""
    _, (q, qd, qdd) = dense_states(traj, dt)
    out = []
    for j, joint in enumerate(desc.joints):
        lim = joint.limits
        vmax = np.abs(qd[:, j])
        out.append(
            JointUsage(
                name=joint.name,
                position_limit=None if lim.position is None else tuple(lim.position),
                position_used=(float(q[:, j].min()), float(q[:, j].max())),
                velocity_peak=float(vmax.max()),
                velocity_limit=float(lim.velocity),
                acceleration_peak=float(np.abs(qdd[:, j]).max()),
                acceleration_limit=float(lim.acceleration),
                slow_fraction=float(np.mean(vmax < SLOW_FRACTION * lim.velocity)),
            )
        )
    return out


@dataclass(frozen=True)
class LimitViolation:
    """Where a trajectory first leaves a joint's limits: ``kind`` position, velocity or
    acceleration; ``limit`` the bound crossed and ``value`` the trajectory's value there
    [rad, rad/s or rad/s^2]; ``time_s`` [s] from the trajectory's start."""

    joint: str
    kind: str
    limit: float
    value: float
    time_s: float

    def describe(self) -> str:
        """One line naming the joint, the limit, the value and the time (degrees)."""
        unit = {"position": "deg", "velocity": "deg/s", "acceleration": "deg/s^2"}[self.kind]
        return (
            f"joint {self.joint}: {self.kind} {math.degrees(self.value):.1f} {unit} at "
            f"t = {self.time_s:.3f} s is beyond its limit {math.degrees(self.limit):.1f} {unit}"
        )


def first_violation(
    traj: Trajectory, desc, horizon_s: float | None = None, dt: float = DENSE_DT
) -> LimitViolation | None:
    """The earliest crossing of the description's (unshrunk) limits on the dense grid of
    :func:`limit_usage` (over ``horizon_s`` [s] if shorter than a period), or None."""
    t, (q, qd, qdd) = dense_states(traj, dt, horizon_s)
    found: list[LimitViolation] = []
    for j, joint in enumerate(desc.joints):
        lim = joint.limits
        v, a = qd[:, j], qdd[:, j]
        cases = [
            ("velocity", v, np.abs(v) > lim.velocity, lim.velocity),
            ("acceleration", a, np.abs(a) > lim.acceleration, lim.acceleration),
        ]
        if lim.position is not None:
            lo, hi = lim.position
            qj = q[:, j]
            cases += [("position", qj, qj > hi, hi), ("position", qj, qj < lo, lo)]
        for kind, values, over, bound in cases:
            if over.any():
                k = int(np.argmax(over))  # first sample beyond the bound
                if kind != "position":
                    bound = math.copysign(bound, values[k])
                found.append(LimitViolation(joint.name, kind, bound, float(values[k]), float(t[k])))
    return min(found, key=lambda v: v.time_s, default=None)


def fit_factors(traj: Trajectory, limits: JointLimits, dt: float = DENSE_DT) -> np.ndarray:
    """Largest per-joint scale (n,) of the motion about traj.centre that keeps ``limits``."""
    t = dense_times(traj, dt)
    q, qd, qdd = traj.states(t)
    c = traj.centre
    factors = np.full(traj.n_joints, math.inf)
    for j in range(traj.n_joints):
        cand = [_ratio(limits.vel[j], np.abs(qd[:, j]).max())]
        cand.append(_ratio(limits.acc[j], np.abs(qdd[:, j]).max()))
        cand.append(_ratio(limits.hi[j] - c[j], q[:, j].max() - c[j]))
        cand.append(_ratio(c[j] - limits.lo[j], c[j] - q[:, j].min()))
        factors[j] = min(cand)
    return factors


def fit_to_limits(traj: Trajectory, limits: JointLimits, dt: float = DENSE_DT, grow=False):
    """Copy of traj scaled per joint to just fit ``limits`` (only shrinking unless grow)."""
    factors = fit_factors(traj, limits, dt)
    if not grow:
        factors = np.minimum(factors, 1.0)
    factors = np.where(np.isfinite(factors), factors, 1.0)
    return traj.scaled(factors)


def _ratio(room: float, used: float) -> float:
    if used <= 0.0:
        return math.inf
    return max(room, 0.0) / used
