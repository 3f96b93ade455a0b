"""Identification path: the equation the rows take, chosen before any run is conditioned
(docs/CONTRACTS.md, "guardid.identify", step 3).

Takes the robot description, the runs (t [s], q, effort[, qd]) and the
:class:`~guardid.conditioning.options.ConditioningOptions`; gives the equation form
(:func:`resolve_equation`: the momentum form, :mod:`guardid.identify.momentum_rows`, or
the acceleration form, :mod:`guardid.identify.acceleration_rows`), the identified
base-parameter columns (:func:`free_columns`, :func:`friction_columns`), the effort's gain
to torque [N m/A] (:func:`effort_gain`), the joints' position limits [rad | m] and the
friction models' smoothness, which both forms use, and :class:`FormRows`, what a form hands
to the stacking stage (:mod:`guardid.identify.rows`).
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np

from guardid.conditioning import momentum as mom
from guardid.conditioning.filters import DEFAULT_ORDER, is_uniform
from guardid.conditioning.options import ConditioningOptions
from guardid.dynamics import ChainModel
from guardid.errors import GuardidError
from guardid.estimators import ColumnNoise
from guardid.identify.cutoff import CutoffChoice


@dataclass
class FormRows:
    """One equation form's rows of every run, before they are stacked.

    ``conds``: per run its conditioned signals (usable rows ``mask``); ``A``: per run
    (M_i, n, b') the usable rows' identified base-regressor columns; ``y``: per run (M_i, n)
    the effort minus the known torque [N m | N | effort unit]; ``options``: the options
    used, every automatic choice resolved; ``choice``: the cut-off's choice (None when
    given); ``first_notes`` / ``last_notes``: notes put before / after the runs' own
    (cut-off, equation form, parallel filter; the quantisation's); ``column_noise``: the
    encoder rounding's noise in the columns (the momentum form) or None; ``keep_runs``:
    the stacked rows keep ``conds`` (the momentum form: what
    :func:`~guardid.identify.momentum_rows.momentum_rows_of` needs); ``lag_ticks``: rows
    this many ticks apart or closer share their noise (the momentum form's causal filter),
    0 when the rows' errors are taken as independent; ``offset_columns``: per run (M_i, n,
    n) the usable rows' friction-offset column of each joint (the momentum form, when every
    joint has one; else None).
    """

    conds: list
    A: list
    y: list
    options: ConditioningOptions
    choice: CutoffChoice | None = None
    first_notes: list[str] = field(default_factory=list)
    last_notes: list[str] = field(default_factory=list)
    column_noise: ColumnNoise | None = None
    keep_runs: bool = False
    lag_ticks: int = 0
    offset_columns: list | None = None


def momentum_unsuitable(runs, model, effort_is_torque, options) -> str:
    """Why the momentum form is not the automatic choice for these runs ('' when it is)."""
    if not isinstance(model, ChainModel):
        return "not a serial chain"
    if effort_is_torque:
        return "measured torque samples: the momentum form needs period means of the current"
    if options.parallel_filter_hz or options.friction_filter:
        return "a parallel or friction filter was asked for"
    for run in runs:
        t = np.asarray(run[0], dtype=float)
        steps = np.diff(t)
        ticks = steps / np.median(steps)
        if not is_uniform(t) and np.any(np.abs(ticks - np.round(ticks)) > 1e-6):
            return "uneven time stamps"
    return ""


def resolve_equation(options, runs, model, effort_is_torque):
    """(options with the equation form and the filter order resolved, why that form)."""
    eq = options.equation
    why = momentum_unsuitable(runs, model, effort_is_torque, options) if eq is None else ""
    if eq is None:
        eq = "acceleration" if why else "momentum"
        why = why or "the default for motor-current logs on a tick grid"
    else:
        why = "asked for"
        if eq == "momentum" and not isinstance(model, ChainModel):
            raise GuardidError("equation momentum: only for serial chains (give acceleration)")
        if eq == "momentum" and (options.parallel_filter_hz or options.friction_filter):
            raise GuardidError("equation momentum: no parallel or friction filter (its one "
                               "filter is on both sides already)")  # fmt: skip
    order = options.order
    if order is None:
        order = mom.DEFAULT_ORDER if eq == "momentum" else DEFAULT_ORDER
    return replace(options, equation=eq, order=int(order)), why


def free_columns(model, description) -> list[int]:
    """Indices of the identified base parameters (friction offsets declared absent with
    ``offset: null`` are left out)."""
    fixed = {
        f"Fo{j + 1}"
        for j, joint in enumerate(description.joints)
        if joint.friction is not None and not getattr(joint.friction, "offset_modelled", True)
    }
    return [i for i, name in enumerate(model.base.names) if name not in fixed]


def drive_gain(description) -> np.ndarray:
    """Current-to-torque gain (n,) [N m/A]; 1 for a joint without drive (torque source)."""
    gains = []
    for j in description.joints:
        d = j.drive
        gains.append(1.0 if d is None else d.gear_ratio * d.efficiency * d.kt)
    return np.array(gains)


def smooth_friction_joints(description) -> np.ndarray:
    """(n,) bool: joints whose friction model is smooth at zero velocity."""
    return np.array(
        [j.friction is not None and j.friction.model != "sign" for j in description.joints]
    )


def smooth_or_frictionless_joints(description) -> np.ndarray:
    """(n,) bool: joints without friction or with a friction model smooth at zero velocity
    (their rows near zero velocity are kept by default)."""
    return np.array([j.friction is None or j.friction.model != "sign" for j in description.joints])


def friction_columns(model, free) -> list[int]:
    """Positions (among the identified columns) of the Coulomb and Stribeck columns of the
    joints with a smooth friction model (a sign model's rows near reversals are dropped:
    its jump is never inside the rows, and a stuck joint does not follow it anyway)."""
    names = [model.base.names[i] for i in free]
    smooth = {
        str(j + 1)
        for j, joint in enumerate(model.description.joints)
        if joint.friction is not None and joint.friction.model != "sign"
    }
    return [i for i, n in enumerate(names) if n.startswith(("Fc", "Fs")) and n[2:] in smooth]


def position_limits(description) -> np.ndarray | None:
    """(n, 2) joint position limits [rad | m] of ``description`` (NaN where none), or None
    when no joint has one."""
    rows = []
    for j in description.joints:
        pos = j.limits.position if j.limits is not None else None
        rows.append((np.nan, np.nan) if pos is None else (float(pos[0]), float(pos[1])))
    out = np.array(rows, dtype=float)
    return None if np.all(np.isnan(out)) else out


def effort_gain(description, in_current_units, effort_is_torque):
    """(n,) gain [N m/A | -] that turns the effort into joint torque: None in current units
    (y stays in the effort's unit), 1 for measured torque, else :func:`drive_gain`."""
    if in_current_units:
        return None
    return np.ones(len(description.joints)) if effort_is_torque else drive_gain(description)
