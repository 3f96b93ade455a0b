"""Do the logs fit the robot and each other? One-line refusals before any fitting.

* a guardid log names its robot in its header and its joints in its column names: the
  description must have that name and those joints (``--robot planar2`` on a guard log);
* several logs must be different recordings: the same file twice, or two files with the
  same samples, would count every row twice and shrink every standard deviation by sqrt(2);
* ``validate``: the parameters must belong to the logs' robot.
"""

from __future__ import annotations

import os

import numpy as np

from guardid.errors import ConfigError


def _joints(description) -> tuple[str, ...]:
    joints = getattr(description, "joints", None)
    if joints is not None:
        return tuple(j.name for j in joints)
    return tuple(getattr(description, "joint_names", ()))


def check_log_robot(run, description, robot_from: str) -> None:
    """Refuse when a guardid log's header robot or joints differ from ``description``.

    ``robot_from`` says where the description came from, e.g. ``--robot planar2``."""
    named = run.robot_name
    if named and str(named) != description.name:
        raise ConfigError(
            f"{run.path}: a log of robot {named}, but {robot_from} describes robot "
            f"{description.name} (give the log's robot)"
        )
    joints = _joints(description)
    if run.joint_names is not None and tuple(run.joint_names) != joints:
        raise ConfigError(
            f"{run.path}: the log's joints ({', '.join(run.joint_names)}) are not robot "
            f"{description.name}'s ({', '.join(joints)}) from {robot_from}"
        )


def _same_file(a: str, b: str) -> bool:
    try:
        return os.path.samefile(a, b)
    except OSError:
        return False


def _same_samples(a, b) -> bool:
    return all(
        np.array_equal(np.asarray(getattr(a, k)), np.asarray(getattr(b, k)))
        for k in ("t", "q", "current")
    )


def check_distinct(runs) -> None:
    """Refuse a log given twice (the same file, or a copy with the same samples)."""
    for k, run in enumerate(runs):
        for earlier in runs[:k]:
            what = "the same file as" if _same_file(run.path, earlier.path) else None
            if what is None and _same_samples(run, earlier):
                what = "the same samples as"
            if what:
                raise ConfigError(
                    f"{run.path}: {what} {earlier.path}; a log given twice would count its "
                    "rows twice and shrink the standard deviations by sqrt(2)"
                )


def check_params_robot(params_path, params: dict, description, robot_opt) -> None:
    """``validate``: the params file's robot must be the one of --robot / the logs."""
    named = params.get("robot")
    if named and str(named) != description.name:
        source = f"--robot {robot_opt} is" if robot_opt else "the logs are of"
        raise ConfigError(
            f"{params_path}: robot: parameters of robot {named}, but {source} "
            f"robot {description.name}"
        )


def check_cutoff(cutoff_hz, runs) -> None:
    """``--cutoff`` [Hz] must lie below every run's Nyquist frequency (half its median
    sample rate)."""
    if cutoff_hz is None:
        return
    for run in runs:
        t = np.asarray(run.t, dtype=float)
        if len(t) < 2:
            continue
        nyquist = 0.5 / float(np.median(np.diff(t)))
        if not cutoff_hz < nyquist:
            raise ConfigError(
                f"--cutoff: {cutoff_hz:g} Hz is not below {run.path}'s Nyquist frequency "
                f"{nyquist:.4g} Hz"
            )
