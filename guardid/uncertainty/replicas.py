"""Replicas of a guardid log: its closed loop simulated with a parameter set and the log's
setpoints, read through the simulated sensors (whole encoder counts, the ADC's voltage and
current; no sensor noise), as a :class:`~guardid.identify.runs.Run` on the log's ticks."""

from __future__ import annotations

from dataclasses import replace

import numpy as np


def simulated_values(description, names, theta) -> dict:
    """Every base parameter of ``description`` (name -> SI value): ``theta`` (p,) for
    ``names`` (the identified ones), the description's own value for the rest."""
    from guardid.dynamics import build_model

    model = build_model(description)
    values = dict(zip(model.base.names, (float(x) for x in model.base.values(model.params)),
                      strict=True))  # fmt: skip
    values.update(zip(names, (float(x) for x in theta), strict=True))
    return values


def replica_run(run, description, values: dict, phase_counts, supply=None, seed=0):
    """``run`` simulated in closed loop with base parameters ``values`` (name -> SI value),
    its setpoints and its first row's state, started ``phase_counts`` (n,) of an encoder
    count (in [0, 1)) above the bottom of its first count instead of the count's middle;
    ``supply``: the motors' supply (:class:`~guardid.uncertainty.supply.MeasuredSupply`,
    its ripple drawn from ``seed``; None: nominal).
    The replica has the log's ticks, time and setpoints; its angles, counts, voltage and
    current are the simulation's (the first row's voltage and current the log's).
    NotSimulable / SimulationDiverged (GuardidError) when ``values`` cannot be simulated;
    ConfigError when the log has no setpoints or the robot no ``pid:``."""
    from guardid.closedloop.rows import start_of
    from guardid.closedloop.simulate import simulate
    from guardid.dynamics import build_model
    from guardid.replay import check_replayable, counts_per_rad

    check_replayable(run, description, "replica")
    model = build_model(description)
    theta = np.array([values[n] for n in model.base.names], dtype=float)
    cpr = counts_per_rad(description)
    q0, qd0, u0, following = start_of(run, description)
    q0 = np.asarray(q0, dtype=float) + (np.asarray(phase_counts, dtype=float) - 0.5) / cpr
    _, counts, volts, amps = simulate(description, model, theta, run.ticks, run.setpoint, q0,
                                      qd0, u0, following, sensors=True, supply=supply,
                                      seed=seed)  # fmt: skip
    volts[0] = run.voltage[0] if run.voltage is not None else 0.0
    amps[0] = run.current[0]
    # the simulated sensor reads no zero offset: the log's zero is not the replica's
    return replace(run, path=f"{run.path} (replica)", q=counts / cpr, counts=counts,
                   current=amps, voltage=volts, qd=None, current_zero=None)  # fmt: skip
