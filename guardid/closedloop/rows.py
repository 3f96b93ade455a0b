"""The simulated closed loop's regressor on the measured identification rows.

The simulated positions of each run go through the measured run's conditioning
(:func:`guardid.identify.acceleration_run.condition_run` with the resolved options: the
same cut-off, filter, decimation and friction-column filter; no fallback), and the rows the
measured run kept (its mask) are taken, so that Z lines up with the measured A row for row.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from guardid.closedloop.simulate import (
    MassBasis,
    NotSimulable,
    SimulationDiverged,
    check_simulable,
    simulate,
    stiffness_substeps,
)
from guardid.errors import GuardidError
from guardid.identify.acceleration_run import condition_run

START_ROWS = 40
"""Rows after the first (0.6 s on the guard) whose reported voltages give the PID's
integral at the first row [-]."""


@dataclass
class ClosedLoopRuns:
    """Per run: ``runs`` (t [s], q [rad], effort[, qd]) as given to identification,
    ``ticks`` (N,), ``setpoints`` [rad] (N, n), ``starts`` the simulation's start
    (:func:`start_of` of the run)."""

    runs: list
    ticks: list
    setpoints: list
    starts: list


def check_inputs(methods, description, setpoints, ticks) -> None:
    """One-line GuardidError when a closed-loop method is asked for and the log has no
    setpoints or ticks, or the robot cannot be simulated in closed loop."""
    wanted = [m for m in methods if m in ("iv", "didim")]
    if not wanted:
        return
    label = "--method " + ",".join(wanted)
    sps = setpoints if isinstance(setpoints, (list, tuple)) else [setpoints]
    tks = ticks if isinstance(ticks, (list, tuple)) else [ticks]
    if any(s is None or np.size(s) == 0 for s in sps):
        raise GuardidError(
            f"{label}: the log has no setpoints (sp_<joint> columns of a guardid capture "
            "log): the closed-loop simulation is driven by what the robot was told to track"
        )
    if any(t is None for t in tks):
        raise GuardidError(f"{label}: the log has no tick column: the closed loop needs it")
    try:
        check_simulable(description)
    except GuardidError as exc:
        raise GuardidError(str(exc).replace("--method iv/didim", label)) from None


class RunDiverged(GuardidError):
    """The simulation of one run diverged or could not start: ``run`` (1-based), ``of``
    runs, ``time_s`` [s] from the run's first row (None: refused before the first step)."""

    def __init__(self, run: int, of: int, exc: GuardidError) -> None:
        self.run, self.of = run, of
        self.time_s = getattr(exc, "time_s", None)
        where = f"run {run} of {of}" if of > 1 else "the run"
        super().__init__(f"{where}: {exc}")


def _full(model, free, theta_free):
    theta = model.base.values(model.params).copy()
    theta[free] = theta_free
    return theta


def physical_check(data: ClosedLoopRuns, description, model, free):
    """``problem(theta_free)`` -> None, or why the closed loop cannot be simulated with it:
    :func:`~guardid.closedloop.simulate.stiffness_substeps` at every measured position and
    setpoint of every run (the places the simulated motion goes)."""
    visited = MassBasis(model, np.vstack([np.asarray(x, dtype=float)
                                          for run, sp in zip(data.runs, data.setpoints, strict=True)
                                          for x in (run[1], sp)]))  # fmt: skip

    def problem(theta_free):
        try:
            stiffness_substeps(description, model, _full(model, free, theta_free), visited)
        except NotSimulable as exc:
            return str(exc)
        return None

    return problem


def regressor_builder(data: ClosedLoopRuns, description, model, free, rows, flags):
    """``regressor_of(theta_free)`` -> Z (M, n, b') on ``rows``' kept rows (see module).

    ``rows``: the measured :class:`~guardid.identify.rows.Rows`; ``flags``:
    (in_current_units, effort_is_torque)."""
    used = rows.options
    if used.parallel_filter_hz:
        raise GuardidError(
            "--method iv/didim: not with the parallel filter (give --parallel-filter 0)"
        )
    used = replace(used, decimate=rows.cond.decimation)
    base = model.base.values(model.params)
    mask = rows.cond.mask

    def regressor_of(theta_free):
        theta = base.copy()
        theta[free] = theta_free
        parts = []
        for k, (run, tk, sp, start) in enumerate(zip(data.runs, data.ticks, data.setpoints,
                                                     data.starts, strict=True)):  # fmt: skip
            try:
                q_sim = simulate(description, model, theta, tk, sp, *start)
            except (SimulationDiverged, NotSimulable) as exc:
                raise RunDiverged(k + 1, len(data.runs), exc) from None
            t, _, effort, *_ = run
            _, A_all, *_ = condition_run(
                (t, q_sim, effort), description, used, used.cutoff_hz, *flags, model, free,
                used.friction_filter, fallback=False,
            )  # fmt: skip
            parts.append(A_all)
        Z = np.concatenate(parts)
        if len(Z) != len(mask):
            raise GuardidError(
                f"--method iv/didim: the simulated run conditioned to {len(Z)} samples, "
                f"the measured one to {len(mask)}"
            )
        return Z[mask]

    return regressor_of


def start_state(run, ticks, voltage, half_count):
    """(q0 [rad], qd0 [rad/s], u0 [V] or None): the first row's position (the middle of its
    encoder count, ``half_count`` (n,) [rad]), the velocity of the first tick and the
    voltage the log reports for the period after the first row (the PID's output at the
    first row; when the next row was lost, the period before the first row's instead: a
    later period's is further off)."""
    t, q = np.asarray(run[0], dtype=float), np.asarray(run[1], dtype=float)
    qd0 = (q[1] - q[0]) / (t[1] - t[0])
    u0 = None
    if voltage is not None and np.size(voltage) > 0:
        next_tick = ticks is None or int(ticks[1]) - int(ticks[0]) == 1
        # the row after was lost: the period before the first row is the closest output
        u0 = np.asarray(voltage)[1 if next_tick else 0]
    return q[0] + half_count, qd0, u0


def start_of(run, description):
    """(q0 [rad] (n,), qd0 [rad/s] (n,), u0 [V] (n,) or None, following or None): the first
    row's state of ``run`` (a :class:`~guardid.log.Run`) as
    :func:`~guardid.closedloop.simulate.simulate` takes it: :func:`start_state`, the velocity
    to second order where three rows are one tick apart, and, where the run has its counts
    and voltages, the counts and next voltages of its first rows one tick apart (at most
    :data:`START_ROWS` + 1), from which the PID's integral at the first row is fitted.
    Without them a log that starts far from its first setpoint (the PID saturated) starts
    its simulation on a wrong integral: several degrees off the log in its first seconds."""
    from guardid.plant.joints import joint_constants

    cpr = np.array([jc.counts_per_rad for jc in joint_constants(description, True, True)])
    q0, qd0, u0 = start_state((run.t, run.q, run.current), run.ticks, run.voltage, 0.5 / cpr)
    steps = np.diff(np.asarray(run.ticks[: START_ROWS + 2], dtype=np.int64))
    gaps = np.flatnonzero(steps != 1)
    k = int(gaps[0]) if gaps.size else len(steps)  # rows whose next period the log reports
    if k >= 2:  # three rows one tick apart: the velocity at the first, to second order
        t, q = np.asarray(run.t, dtype=float), np.asarray(run.q, dtype=float)
        qd0 = (-3.0 * q[0] + 4.0 * q[1] - q[2]) / (t[2] - t[0])
    following = None
    if run.voltage is not None and run.counts is not None and k >= 2:
        following = (np.asarray(run.counts[:k], dtype=np.int64), np.asarray(run.voltage[1 : k + 1]))
    return q0, qd0, u0, following
