"""Simulation error (``guardid validate --simulate``): parameter sets replayed through the
closed loop with a log's setpoints and scored against its measured joint angles.

Each set's base parameters drive :func:`guardid.closedloop.simulate.simulate` (the
firmware's fixed-point PID with the robot YAML's ``pid:`` gains, the motors, stick/slip
friction, the rigid body of the set), from the log's first row: the position in the middle
of its encoder count, the velocity of the first ticks, the PID's output and integral from
the voltages the log reports for the first rows
(:func:`~guardid.closedloop.simulate.start_integral`). The simulated angles are read
through the simulated encoder (whole counts, as the log's angles are), so a replay that
matches the robot scores zero; the error per joint is given in degrees and in encoder
counts, rms and max over the run's rows.

A foreign log (no ``sp_*`` setpoint columns or no tick column) or a robot without ``pid:``,
a drive or an encoder on a joint cannot be replayed: one line (exit 2).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from guardid.errors import ConfigError, GuardidError


@dataclass(frozen=True)
class ReplayScore:
    """One parameter set replayed on one run: per joint (n,) rms and max |error| in degrees
    and in encoder counts; ``failed``: why it could not be simulated ('' when it was)."""

    label: str
    run: str
    rows: int
    rms_deg: np.ndarray
    max_deg: np.ndarray
    rms_counts: np.ndarray
    max_counts: np.ndarray
    failed: str = ""


def counts_per_rad(description) -> np.ndarray:
    """Encoder counts per joint radian (n,): counts_per_rev (x4 in quadrature) x gear / 2 pi."""
    from guardid.plant.joints import joint_constants

    return np.array([jc.counts_per_rad for jc in joint_constants(description, True, True)])


def check_replayable(run, description, option: str = "--simulate") -> None:
    """One-line ConfigError unless ``run`` has setpoints and ticks and every joint of
    ``description`` a drive, an encoder and ``pid:``."""
    from guardid.closedloop.simulate import check_simulable

    if run.setpoint is None or np.size(run.setpoint) == 0 or run.ticks is None:
        raise ConfigError(
            f"{option}: {run.path}: the log has no setpoints (sp_<joint> columns and a tick "
            "column of a guardid capture log): a replay is driven by what the robot was told "
            "to track"
        )
    try:
        check_simulable(description)
    except GuardidError as exc:
        raise ConfigError(str(exc).replace("--method iv/didim", option)) from None


def replay(run, description, values: dict) -> np.ndarray:
    """Simulated joint angles [rad] (N, n) of ``run`` with base parameter ``values`` (name
    -> SI value): the simulated encoder's whole counts, as the log's angles are.
    NotSimulable / SimulationDiverged (GuardidError) when the set cannot be simulated."""
    from guardid.closedloop.rows import start_of
    from guardid.closedloop.simulate import simulate
    from guardid.dynamics import build_model

    model = build_model(description)
    theta = np.array([values[n] for n in model.base.names], dtype=float)
    q0, qd0, u0, following = start_of(run, description)
    q = simulate(description, model, theta, run.ticks, run.setpoint, q0, qd0, u0, following)
    cpr = counts_per_rad(description)
    return np.floor(q * cpr) / cpr


def score(label, run_name, q_sim, q_meas, cpr) -> ReplayScore:
    """The :class:`ReplayScore` of simulated angles ``q_sim`` against ``q_meas`` (N, n) [rad]
    with ``cpr`` (n,) encoder counts per radian."""
    err = np.asarray(q_sim, dtype=float) - np.asarray(q_meas, dtype=float)
    rms = np.sqrt(np.mean(err**2, axis=0))
    peak = np.max(np.abs(err), axis=0)
    return ReplayScore(label, run_name, len(err), np.degrees(rms), np.degrees(peak), rms * cpr,
                       peak * cpr)  # fmt: skip


def replay_sets(runs, names, description, sets, keep=None) -> list[ReplayScore]:
    """Every set (:class:`~guardid.identify.validation.ParameterSet`) replayed on every run;
    a set that cannot be simulated on a run is scored NaN with the reason. ``keep`` (a
    dict, optional) receives (run name, label) -> simulated angles (N, n) [rad]."""
    for run in runs:
        check_replayable(run, description)
    cpr = counts_per_rad(description)
    out = []
    for run, name in zip(runs, names, strict=True):
        for s in sets:
            try:
                q_sim = replay(run, description, s.values)
            except GuardidError as exc:
                nan = np.full(len(cpr), np.nan)
                out.append(ReplayScore(s.label, str(name), len(run.q), nan, nan, nan, nan,
                                       failed=str(exc)))  # fmt: skip
                continue
            if keep is not None:
                keep[(str(name), s.label)] = q_sim
            out.append(score(s.label, str(name), q_sim, run.q, cpr))
    return out


def table(scores, description) -> str:
    """Per run, one line per set: per joint rms and max error in degrees and counts."""
    joints = [j.name for j in description.joints]
    width = max(len(s.label) for s in scores) + 2
    lines = ["simulation error: each set replayed in closed loop with the log's setpoints from "
             "its first state; simulated minus measured joint angle (encoder counts)"]  # fmt: skip
    for run in dict.fromkeys(s.run for s in scores):
        mine = [s for s in scores if s.run == run]
        lines.append(f"run {run} ({mine[0].rows} rows)")
        head = f"  {'parameter set':{width}s}"
        for j in joints:
            head += f"  {j + ' rms/max [deg]':>22s} {'[counts]':>15s}"
        lines.append(head)
        for s in mine:
            if s.failed:
                lines.append(f"  {s.label:{width}s}  not simulable: {s.failed}")
                continue
            line = f"  {s.label:{width}s}"
            for k in range(len(joints)):
                deg = f"{s.rms_deg[k]:.3g} / {s.max_deg[k]:.3g}"
                cnt = f"{s.rms_counts[k]:.3g} / {s.max_counts[k]:.3g}"
                line += f"  {deg:>22s} {cnt:>15s}"
            lines.append(line)
    return "\n".join(lines)


def yaml_set(description):
    """The robot YAML's own values as a :class:`~guardid.identify.validation.ParameterSet`
    labelled 'robot YAML'."""
    from guardid.dynamics import build_model
    from guardid.identify.validation import ParameterSet

    model = build_model(description)
    values = dict(zip(model.base.names, (float(x) for x in model.base.values(model.params)),
                      strict=True))  # fmt: skip
    return ParameterSet("robot YAML", values, description)
