"""Common interface of excitation trajectories and their YAML files.

A trajectory maps a time array ``t`` [s] of shape (N,) to joint positions, velocities and
accelerations of shape (N, n) [rad, rad/s, rad/s^2], all evaluated analytically. It is
periodic with :attr:`Trajectory.period` [s]; :attr:`Trajectory.duration` [s] is a whole
number of periods. A YAML file holds one trajectory: a mapping with a ``kind:`` key
(``fourier``, ``schroeder``, ``sines``), the kind's coefficients as plain floats and lists,
and an optional free-form ``info:`` mapping (provenance; ignored when loading).
"""

from __future__ import annotations

import math
from abc import ABC, abstractmethod
from pathlib import Path
from typing import ClassVar

import numpy as np
import yaml

from guardid.errors import ConfigError
from guardid.yaml_load import safe_load

KINDS: dict[str, type[Trajectory]] = {}


class Trajectory(ABC):
    """Periodic joint trajectory; subclasses register themselves under their ``kind``."""

    kind: ClassVar[str] = ""
    periods: int = 1

    def __init_subclass__(cls, **kwargs):
        super().__init_subclass__(**kwargs)
        if cls.kind:
            KINDS[cls.kind] = cls

    # ---------------------------------------------------------------- evaluation
    @property
    @abstractmethod
    def n_joints(self) -> int:
        """Number of joints n."""

    @property
    @abstractmethod
    def period(self) -> float:
        """Period [s] of the trajectory (math.inf if it has none)."""

    @property
    def duration(self) -> float:
        """Length [s] of the run: ``periods`` whole periods."""
        return self.periods * self.period

    @abstractmethod
    def positions(self, t) -> np.ndarray:
        """Joint positions (N, n) [rad] at times t (N,) [s]."""

    @abstractmethod
    def velocities(self, t) -> np.ndarray:
        """Joint velocities (N, n) [rad/s] at times t (N,) [s]."""

    @abstractmethod
    def accelerations(self, t) -> np.ndarray:
        """Joint accelerations (N, n) [rad/s^2] at times t (N,) [s]."""

    @property
    @abstractmethod
    def centre(self) -> np.ndarray:
        """Pose (n,) [rad] about which :meth:`scaled` scales the motion."""

    @abstractmethod
    def scaled(self, factors) -> Trajectory:
        """Copy with each joint's motion about :attr:`centre` scaled by factors (n,) [-]."""

    def states(self, t) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(q, qd, qdd), each (N, n), at times t (N,) [s]."""
        return self.positions(t), self.velocities(t), self.accelerations(t)

    # ---------------------------------------------------------------- YAML
    @abstractmethod
    def to_dict(self) -> dict:
        """Plain mapping (floats, ints, strings, lists) with a ``kind`` key."""

    @classmethod
    @abstractmethod
    def from_dict(cls, data: dict, source: str = "<trajectory>") -> Trajectory:
        """Inverse of :meth:`to_dict`; errors name ``source`` and the key."""

    def save(self, path, info: dict | None = None) -> None:
        """Write the trajectory (and an optional ``info`` mapping) as YAML to ``path``."""
        data = self.to_dict()
        if info:
            data["info"] = _plain(info)
        text = yaml.safe_dump(data, sort_keys=False, default_flow_style=None, width=100)
        Path(path).write_text(text)

    @classmethod
    def load(cls, path) -> Trajectory:
        """Read a trajectory YAML file; any kind when called on Trajectory itself."""
        data = read_yaml(path)
        source = str(path)
        traj = trajectory_from_dict(data, source)
        if cls is not Trajectory and not isinstance(traj, cls):
            raise ConfigError(f"{source}: kind: expected {cls.kind!r}, got {traj.kind!r}")
        return traj


def read_yaml(path) -> dict:
    """The top-level mapping of a YAML file, or ConfigError naming the file."""
    try:
        text = Path(path).read_text()
    except OSError as exc:
        raise ConfigError(f"{path}: cannot read: {exc.strerror or exc}") from None
    try:
        data = safe_load(text)
    except yaml.YAMLError as exc:
        mark = getattr(exc, "problem_mark", None)
        where = f" at line {mark.line + 1}" if mark is not None else ""
        raise ConfigError(f"{path}: invalid YAML{where}") from None
    if not isinstance(data, dict):
        raise ConfigError(f"{path}: expected a mapping with a 'kind' key at the top level")
    return data


def trajectory_from_dict(data: dict, source: str = "<trajectory>") -> Trajectory:
    """Build the trajectory of ``data['kind']``."""
    if not isinstance(data, dict):
        raise ConfigError(f"{source}: expected a mapping with a 'kind' key")
    kind = data.get("kind")
    if kind is None:
        raise ConfigError(f"{source}: kind: missing (one of {', '.join(KINDS)})")
    if kind not in KINDS:
        raise ConfigError(f"{source}: kind: unknown {kind!r} (one of {', '.join(KINDS)})")
    return KINDS[kind].from_dict(data, source)


def load_trajectory(path) -> Trajectory:
    """Read any trajectory YAML file (see module docstring)."""
    return Trajectory.load(path)


# -------------------------------------------------------------------- validation helpers
class Fields:
    """Typed access to a mapping's keys with one-line ConfigErrors naming source and key."""

    def __init__(self, data: dict, source: str, allowed: tuple[str, ...]):
        self.data = data
        self.source = source
        for key in data:
            if key not in allowed and key not in ("kind", "info"):
                self.fail(str(key), f"unknown key (expected {', '.join(allowed)})")

    def fail(self, key: str, what: str):
        raise ConfigError(f"{self.source}: {key}: {what}")

    def has(self, key: str) -> bool:
        return self.data.get(key) is not None

    def raw(self, key: str, default=None, required: bool = True):
        if key not in self.data or self.data[key] is None:
            if required and default is None:
                self.fail(key, "missing")
            return default
        return self.data[key]

    def number(self, key: str, default=None, positive: bool = False) -> float:
        value = self.raw(key, default)
        out = _to_float(value)
        if out is None:
            self.fail(key, f"expected a number, got {value!r}")
        if positive and not out > 0:
            self.fail(key, f"must be > 0, got {out!r}")
        return out

    def integer(self, key: str, default=None, minimum: int = 1) -> int:
        value = self.raw(key, default)
        if isinstance(value, bool) or not isinstance(value, int) or value < minimum:
            self.fail(key, f"expected an integer >= {minimum}, got {value!r}")
        return int(value)

    def vector(self, key: str, length: int | None = None, default=None) -> np.ndarray:
        value = self.raw(key, default)
        return self._vector(key, value, length)

    def rows(self, key: str, n_rows: int | None = None, lengths=None) -> list[np.ndarray]:
        """A list of number lists; ``lengths`` (per row) checks each row's length."""
        value = self.raw(key)
        if not isinstance(value, list) or not value:
            self.fail(key, "expected a list with one list of numbers per joint")
        if n_rows is not None and len(value) != n_rows:
            self.fail(key, f"expected {n_rows} rows (one per joint), got {len(value)}")
        out = []
        for i, row in enumerate(value):
            want = None if lengths is None else lengths[i]
            out.append(self._vector(f"{key}[{i}]", row, want))
        return out

    def names(self, n: int) -> list[str] | None:
        """Optional ``joints`` key: a list of n joint names."""
        if not self.has("joints"):
            return None
        names = self.raw("joints")
        if not isinstance(names, list) or len(names) != n:
            self.fail("joints", f"expected a list of {n} joint names")
        if not all(isinstance(x, str) for x in names):
            self.fail("joints", f"expected a list of {n} joint names")
        return names

    def _vector(self, key: str, value, length: int | None) -> np.ndarray:
        if not isinstance(value, list) or not value:
            self.fail(key, f"expected a non-empty list of numbers, got {value!r}")
        nums = [_to_float(v) for v in value]
        for i, v in enumerate(nums):
            if v is None:
                self.fail(f"{key}[{i}]", f"expected a number, got {value[i]!r}")
        if length is not None and len(nums) != length:
            self.fail(key, f"expected {length} values, got {len(nums)}")
        return np.array(nums, dtype=float)


def _to_float(value) -> float | None:
    if isinstance(value, bool) or not isinstance(value, int | float):
        return None
    value = float(value)
    return value if math.isfinite(value) else None


def _plain(value):
    """Convert numpy scalars/arrays inside nested containers to plain Python for YAML."""
    if isinstance(value, dict):
        return {str(k): _plain(v) for k, v in value.items()}
    if isinstance(value, list | tuple | np.ndarray):
        return [_plain(v) for v in value]
    if isinstance(value, np.generic):
        return value.item()
    return value


def floats(array) -> list:
    """Nested plain-float lists from an array (for to_dict)."""
    return np.asarray(array, dtype=float).tolist()


def time_array(t) -> np.ndarray:
    """Time argument as a 1-D float array (N,) [s]."""
    return np.atleast_1d(np.asarray(t, dtype=float)).ravel()
