"""Do the logs fit the robot and each other? One-line refusals before any fitting.

* a guardid log names its robot in its header and its joints in its column names: the
  description must have that name and those joints (``--robot planar2`` on a guard log);
  the log's columns are then taken in the description's joint order (by name, whatever
  their order in the file), and its angles must be its encoder counts times the
  description's scale (:func:`check_angles`);
* several logs must be different recordings: the same file twice, or two files with the
  same samples, would count every row twice and shrink every standard deviation by sqrt(2);
* ``validate``: the parameters must belong to the logs' robot.
"""

from __future__ import annotations

import os

import numpy as np

from guardid.errors import ConfigError, GuardidError


def _joints(description) -> tuple[str, ...]:
    joints = getattr(description, "joints", None)
    if joints is not None:
        return tuple(j.name for j in joints)
    return tuple(getattr(description, "joint_names", ()))


def check_log_robot(run, description, robot_from: str):
    """Refuse when a guardid log's header robot or joints differ from ``description``; then
    put the run's per-joint arrays in the description's joint order (in place: the columns
    were found by name, in the file's order) and check its angles against its encoder
    counts (:func:`check_angles`). Returns ``run``.

    ``robot_from`` says where the description came from, e.g. ``--robot planar2``."""
    named = run.robot_name
    if named and str(named) != description.name:
        raise ConfigError(
            f"{run.path}: a log of robot {named}, but {robot_from} describes robot "
            f"{description.name} (give the log's robot)"
        )
    period = getattr(description, "sample_period", None)
    if run.sample_period_s is not None and run.counts is not None and period:
        if abs(run.sample_period_s - period) > 0.01 * period:
            raise ConfigError(
                f"{run.path}: header: sample_period_s {run.sample_period_s:g} s, but robot "
                f"{description.name} ({robot_from}) has sample_period {period:g} s (its "
                "motors' and PID's period: give the robot the log was captured on, or "
                "correct its sample_period)"
            )
    joints = _joints(description)
    if run.joint_names is None:
        return run
    logged = tuple(run.joint_names)
    robot = f"robot {description.name}'s joints ({', '.join(joints)}) from {robot_from}"
    for name in logged:
        if name not in joints:
            raise ConfigError(
                f"{run.path}: column counts_{name}: joint {name} is not one of {robot}"
            )
    for name in joints:
        if name not in logged:
            raise ConfigError(f"{run.path}: no column counts_{name}: {robot} include {name}")
    order = [logged.index(name) for name in joints]
    reordered = order != list(range(len(order)))  # in the file's order already: no copies
    for key in ("q", "current", "voltage", "setpoint", "counts", "qd") if reordered else ():
        value = getattr(run, key, None)
        if value is not None and np.ndim(value) == 2:
            setattr(run, key, np.asarray(value)[:, order])
    run.joint_names = joints
    check_angles(run, description)
    check_sensor_ranges(run, description)
    return run


SENT_QUANTUM = 0.5e-3
"""Half the unit in which the firmware sends a current or voltage (whole mA or mV, rounded)
[A | V]: a reading at the ADC's end may be reported that much beyond the range."""


def check_sensor_ranges(run, description) -> None:
    """Refuse a guardid log (one with counts) holding a current or voltage beyond what the
    described sensor reads: its ADC spans +-range [A | V]; the margin is one ADC step (2
    range / 2^adc_bits) and the firmware's rounding to whole mA or mV (:data:`SENT_QUANTUM`).
    Names the column, the data row (1 = the first) and the range: a corrupt value (1e300 A)
    would otherwise reach the fit."""
    if run.counts is None or getattr(description, "joints", None) is None:
        return
    for key, unit, column in (("current", "A", "i"), ("voltage", "V", "v")):
        values = getattr(run, key, None)
        if values is None or np.size(values) == 0:
            continue
        values = np.asarray(values, dtype=float)
        for j, joint in enumerate(description.joints):
            sensor = getattr(joint, f"{key}_sensor")
            if sensor is None:
                continue
            most = sensor.range * (1.0 + 2.0 / 2**sensor.adc_bits) + SENT_QUANTUM
            bad = np.flatnonzero(np.abs(values[:, j]) > most)
            if bad.size:
                k = int(bad[0])
                raise ConfigError(
                    f"{run.path}: column {column}_{joint.name}_{unit}, data row {k + 1}: "
                    f"{values[k, j]:.6g} {unit}, beyond the {key} sensor's range +-"
                    f"{sensor.range:g} {unit} (robot {description.name}'s description): a "
                    "corrupt value, or another sensor than the description's"
                )


ANGLE_TOLERANCE_COUNTS = 1e-3
"""Largest difference between a logged angle and its encoder count times the description's
scale, in counts [-]: the writer prints angles to 1e-9 rad, some 1e5 times finer than a
count of the shipped encoders (2.6e-4 rad), so a float round trip stays far below it, and
a swapped or edited value, off by at least a count, far above."""


def check_angles(run, description) -> None:
    """Refuse a guardid log whose angles q_<joint>_rad [rad] are not its counts_<joint> x
    2 pi / (encoder counts per rev x gear ratio) of ``description`` (columns swapped or
    edited under unchanged names, or a log of another encoder), naming the first column and
    data row (1 = the first) where they differ by more than :data:`ANGLE_TOLERANCE_COUNTS`."""
    if run.counts is None or getattr(description, "joints", None) is None:
        return
    q, counts = np.asarray(run.q, dtype=float), np.asarray(run.counts, dtype=float)
    for j, joint in enumerate(description.joints):
        if joint.encoder is None:
            continue
        per_count = 2.0 * np.pi / joint.counts_per_joint_rev  # [rad]
        off = np.abs(q[:, j] - counts[:, j] * per_count)
        bad = np.flatnonzero(~(off <= ANGLE_TOLERANCE_COUNTS * per_count))
        if bad.size:
            k = int(bad[0])
            raise ConfigError(
                f"{run.path}: column q_{joint.name}_rad, data row {k + 1}: {q[k, j]:.9g} rad, "
                f"but counts_{joint.name} {counts[k, j]:.0f} x {per_count:.6g} rad (robot "
                f"{description.name}'s encoder) = {counts[k, j] * per_count:.9g} rad (columns "
                "swapped or edited?)"
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


RATE_TOLERANCE = 0.01
"""Runs stacked into one fit may differ this much in median sample period [-] (jittery
foreign logs); beyond, they are refused (:func:`check_same_rate`)."""


def check_same_rate(runs) -> None:
    """Refuse runs of different sample periods in one fit: the filter's window, the row
    spacing and the window over which the rows share their noise are counted in samples
    from the first run's period, so another run's would be off (identify them apart)."""
    timed = [(r, float(np.median(np.diff(np.asarray(r.t, dtype=float))))) for r in runs
             if len(r.t) > 1]  # fmt: skip
    for run, period in timed[1:]:
        first, first_period = timed[0]
        if abs(period - first_period) > RATE_TOLERANCE * first_period:
            raise ConfigError(
                f"{run.path}: a sample period of {period:.6g} s, {first.path}'s is "
                f"{first_period:.6g} s: logs of different rates are not stacked into one fit "
                "(identify them apart)"
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


def naming_logs(exc: GuardidError, logs) -> GuardidError:
    """``exc`` (raised while conditioning or fitting ``logs``) with the logs named in front
    when its message names none of them (e.g. "only 0 usable rows after conditioning")."""
    names = [str(x) for x in logs]
    text = str(exc)
    if any(name in text for name in names):
        return exc
    return type(exc)(f"{', '.join(names)}: {text}")


def call_naming_logs(logs, fn, *args, **kwargs):
    """``fn(*args, **kwargs)``; a :class:`GuardidError` it raises names ``logs``
    (:func:`naming_logs`)."""
    try:
        return fn(*args, **kwargs)
    except GuardidError as exc:
        raise naming_logs(exc, logs) from None
