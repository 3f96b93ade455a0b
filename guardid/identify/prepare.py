"""Identification path, first step: runs -> the runs (segments) that are conditioned.

Takes :class:`~guardid.identify.runs.Run` objects (t [s], q [rad | m], effort [A | N m | N],
...) and the robot description; gives the runs as :func:`guardid.identify.pipeline.identify`
conditions them (:func:`prepared_runs`): a guardid log's columns in the description's joint
order, its motor currents on the ADC's levels, split at long gaps into segments
(:mod:`guardid.identify.segments`); and per run the signals (t, q, effort[, qd]) the rows
stage takes (:func:`run_signals`).
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from guardid.errors import GuardidError
from guardid.identify.checks import check_log_robot, check_same_rate
from guardid.identify.segments import split_runs


def prepared_runs(runs, description, options=None):
    """(runs, Split or None, zeros): what :func:`~guardid.identify.pipeline.identify`
    conditions ``runs`` as: each guardid log's columns in ``description``'s joint order,
    its currents on the ADC's levels and less the current sensors' zero its footer gives
    (as ``options.current_zero`` says: :func:`~guardid.identify.current_zero.subtract_zeros`;
    ``zeros`` its :class:`~guardid.identify.current_zero.ZerosRead`), the runs split at
    their long gaps (unless the caller split them). For callers that condition the same
    runs again (the consistent fit). ``options``: the
    :class:`~guardid.identify.pipeline.IdentifyOptions` (its conditioning's cut-off sets the
    longest gap bridged; None: all automatic)."""
    from guardid.identify.current_zero import ZerosRead, subtract_zeros

    runs = [_in_joint_order(r, description) for r in runs]
    if not runs:
        return runs, None, ZerosRead()
    runs = [current_on_adc_levels(r, description) for r in runs]
    check_same_rate(runs)
    mode = options.current_zero if options is not None else "subtract"
    runs, zeros = subtract_zeros(runs, description, mode)
    conditioning = options.conditioning if options is not None else None
    cutoff_hz = conditioning.cutoff_hz if conditioning is not None else None
    return (*split_at_gaps(runs, cutoff_hz, description), zeros)


def current_on_adc_levels(run, description, in_place: bool = False):
    """``run`` with its motor currents on each joint's ADC levels when they are those levels
    as the telemetry rounds them (:func:`~guardid.conditioning.units.current_on_adc_levels`:
    the rounding's error follows the motion and does not shrink with the log's length); a
    joint whose values are not is left as it is. A copy with a new current array, or, with
    ``in_place``, ``run`` itself changed (for a caller that owns the run's arrays, so that
    every later stage, the tracker's replay included, reads the same currents). Levels
    come back as they are: a second call changes nothing and copies nothing. The footer's
    current sensors' zero of a joint put on its levels is read off them the same way
    (:func:`~guardid.identify.current_zero.zero_on_levels`)."""
    from guardid.conditioning.units import current_on_adc_levels as on_levels
    from guardid.identify.current_zero import KEYS, zero_on_levels
    from guardid.protocol.codec import SPEC

    joints = getattr(description, "joints", None)
    if run.torque or joints is None or run.current is None:
        return run
    (unit,) = [f.scale for f in SPEC.by_name("TELEMETRY").fields if f.name == "current"]
    current = run.current
    zeros = {k: getattr(run, k, None) for k in KEYS}
    for j, joint in enumerate(joints):
        sensor = joint.current_sensor
        if sensor is None or j >= current.shape[1]:
            continue
        levels = on_levels(current[:, j], sensor.range, sensor.adc_bits, unit)
        if levels is None:
            continue
        for k, zero in zeros.items():
            if zero and joint.name in zero and not zero[joint.name].get("on_levels"):
                # the zeros read at rest the same way (guardid.identify.current_zero)
                zeros[k] = {**zero, joint.name: zero_on_levels(zero[joint.name], sensor, unit)}
        if np.array_equal(levels, current[:, j]):
            continue
        if current is run.current and not (in_place and current.flags.writeable):
            current = np.array(current)
        current[:, j] = levels
    if current is run.current and all(zeros[k] is getattr(run, k, None) for k in KEYS):
        return run
    if in_place:
        run.current = current
        for k, zero in zeros.items():
            setattr(run, k, zero)
        return run
    return replace(run, current=current, **zeros)


def _in_joint_order(run, description):
    """``run`` with its per-joint columns in ``description``'s joint order, its angles
    checked against its counts (:func:`~guardid.identify.checks.check_log_robot`; a copy,
    the robot's name not compared), when a guardid log's columns name other joints or
    another order (``load_run`` keeps the file's order)."""
    joints = getattr(description, "joints", None)
    if run.joint_names is None or joints is None:
        return run
    if tuple(run.joint_names) == tuple(j.name for j in joints):
        return run
    return replace(check_log_robot(replace(run, robot_name=None), description,
                                   "the description given"), robot_name=run.robot_name)  # fmt: skip


def split_at_gaps(runs, cutoff_hz, description=None):
    """(runs, Split or None): the runs split at their long gaps and their jumps
    (:func:`~guardid.identify.segments.split_runs`, the limit from ``cutoff_hz`` [Hz], the
    given cut-off, or when None the first run's harmonic; the jumps against
    ``description``'s drives), unless the caller split them already (a segment among them:
    ``Run.source`` set) or none has a long gap or a jump. GuardidError when no segment is
    left."""
    if any(getattr(r, "source", None) for r in runs):
        return runs, None
    split = split_runs(runs, cutoff_hz, runs[0].highest_harmonic_hz, description)
    if not split.split:
        return runs, None
    if not split.runs:
        raise GuardidError("; ".join(split.lines()))
    return split.runs, split


def effort_is_torque(runs) -> bool:
    """Whether the runs' effort is measured torque; GuardidError when they mix."""
    if not runs:
        raise GuardidError("identify: no runs")
    kinds = {bool(r.torque) for r in runs}
    if len(kinds) > 1:
        raise GuardidError(f"{runs[-1].path}: mixes measured torque and motor current with "
                           f"{runs[0].path}")  # fmt: skip
    return kinds.pop()


def run_signals(run, runs):
    """(t, q, effort[, qd]) of a run for the rows; qd only when every run has it."""
    if all(r.qd is not None for r in runs):
        return run.t, run.q, run.current, run.qd
    return run.t, run.q, run.current
