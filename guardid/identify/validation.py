"""Neutral validation: several parameter sets scored on the same rows of the same runs.

Every parameter set is scored under one conditioning (the same cut-off, rows and filter for
all), per run:

* the headline: the stacked relative rms error over all joints,
  e = rms(tau - tau_model) / rms(tau), every joint's rows in one vector;
* per joint: the rms error in the joint's unit (N m, N, or A in current units), and the
  relative error rms_j(tau - tau_model) / rms_j(tau) only where the joint's effort is not
  negligible (rms_j(tau) >= :data:`PASSIVE_FRACTION` x the largest joint's): a passive
  joint (commanded torque zero, as in an underactuated pendulum) is named as such.

A parameter set is a params file's method (``a.yaml:LS``), or a *reference values file* of
base-parameter values typed in by a user (docs/VALIDATION.md)::

    guardid-reference: 1
    label: DFKI published           # optional, default the file name
    robot: dfki_double_pendulum     # optional; checked against the robot when given
    friction: {model: atan, velocity_scale: 0.01}   # optional: the set's friction shape
    values: {ZZ1R: 0.1107, MX1R: 0.3491, MX2R: 0.1111, ZZ2R: 0.02392, Ia2: 0.002757}

Base parameters a reference file leaves out take the robot description's values (listed).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace

import numpy as np

from guardid.conditioning.options import ConditioningOptions
from guardid.dynamics import build_model
from guardid.errors import ConfigError
from guardid.robot.description import FRICTION_MODELS

PASSIVE_FRACTION = 0.05
"""A joint whose effort rms is below this fraction of the largest joint's is passive [-]."""


@dataclass
class ParameterSet:
    """Named base-parameter values (``values``: name -> SI value) for ``description``."""

    label: str
    values: dict[str, float]
    description: object
    defaulted: list[str] = field(default_factory=list)


@dataclass
class Score:
    """One parameter set on one run: stacked relative error [-], per joint rms error [joint
    unit] (n,) and relative error (n,) (NaN for a passive joint or one without rows), rows
    used; ``rowless`` (n,) the joints none of whose rows was usable (the momentum form cuts
    a joint that never moves, or is stuck or on a stop throughout): not scored."""

    label: str
    run: str
    stacked: float
    rms: np.ndarray
    relative: np.ndarray
    passive: np.ndarray
    rows: int
    ref2: float = 0.0  # sum of tau^2 over the rows (to stack runs)
    rowless: np.ndarray | None = None


def joint_units(description, current_units: bool = False) -> list[str]:
    """Effort unit per joint: 'N m' (revolute), 'N' (prismatic), 'A' in current units."""
    if current_units:
        return ["A"] * len(description.joints)
    return ["N" if j.type == "prismatic" else "N m" for j in description.joints]


def with_friction(description, friction: dict | None, where: str):
    """``description`` with every joint's friction shape replaced (model, velocity_scale)."""
    if not friction:
        return description
    if not isinstance(friction, dict):
        raise ConfigError(f"{where}: expected a mapping {{model, velocity_scale}}")
    unknown = set(friction) - {"model", "velocity_scale"}
    if unknown:
        raise ConfigError(f"{where}.{sorted(unknown)[0]}: unknown (known: model, velocity_scale)")
    model = friction.get("model", "sign")
    if model not in FRICTION_MODELS or model == "stribeck":
        raise ConfigError(f"{where}.model: expected sign, tanh or atan, got {model!r}")
    scale = friction.get("velocity_scale")
    if model != "sign" and (not isinstance(scale, (int, float)) or scale <= 0):
        raise ConfigError(f"{where}.velocity_scale: expected a positive number [rad/s or m/s]")
    joints = [
        j if j.friction is None else replace(
            j, friction=replace(j.friction, model=model,
                                velocity_scale=None if model == "sign" else float(scale))
        )
        for j in description.joints
    ]  # fmt: skip
    return replace(description, joints=joints)


def base_names(description) -> tuple[str, ...]:
    """All base parameter names of ``description``'s model."""
    return tuple(build_model(description).base.names)


def reference_set(path, description) -> ParameterSet:
    """A reference values file (module docstring) for ``description``."""
    data = _yaml(path)
    if data.get("guardid-reference") != 1:
        raise ConfigError(f"{path}: guardid-reference: expected 1 (a reference values file)")
    unknown = set(data) - {"guardid-reference", "label", "robot", "friction", "values"}
    if unknown:
        raise ConfigError(f"{path}: {sorted(unknown)[0]}: unknown key")
    robot = data.get("robot")
    if robot is not None and robot != description.name:
        raise ConfigError(f"{path}: robot: {robot}, but the runs are {description.name}")
    desc = with_friction(description, data.get("friction"), f"{path}: friction")
    values = data.get("values")
    if not isinstance(values, dict) or not values:
        raise ConfigError(f"{path}: values: expected a mapping of base parameter: value")
    names = base_names(desc)
    out = {}
    for name, value in values.items():
        if name not in names:
            raise ConfigError(f"{path}: values.{name}: not a base parameter of "
                              f"{description.name} ({', '.join(names)})")  # fmt: skip
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise ConfigError(f"{path}: values.{name}: expected a number, got {value!r}")
        out[name] = float(value)
    model = build_model(desc)
    nominal = dict(zip(names, model.base.values(model.params), strict=True))
    from guardid.identify.equation import free_columns

    identified = {model.base.names[i] for i in free_columns(model, desc)}
    defaulted = [n for n in names if n not in out and n in identified]
    out.update({n: float(nominal[n]) for n in names if n not in out})
    label = str(data.get("label") or path)
    return ParameterSet(label, out, desc, defaulted)


def params_sets(path, params: dict, description) -> list[ParameterSet]:
    """One :class:`ParameterSet` per method of a params file written by identify."""
    names = [p["name"] for p in params["base_parameters"]]
    model = build_model(description)
    nominal = dict(zip(model.base.names, model.base.values(model.params), strict=True))
    missing = [n for n in names if n not in nominal]
    if missing:
        raise ConfigError(f"{path}: base_parameters: {missing[0]} is not a base parameter of "
                          f"{description.name}")  # fmt: skip
    out = []
    for m, entry in params["methods"].items():
        theta = entry.get("values") if isinstance(entry, dict) else None
        if not isinstance(theta, list) or len(theta) != len(names):
            raise ConfigError(f"{path}: methods.{m}.values: expected {len(names)} numbers")
        values = dict(nominal)  # parameters identification does not estimate keep the YAML's
        values.update({n: float(v) for n, v in zip(names, theta, strict=True)})
        out.append(ParameterSet(f"{path}:{m.upper()}", values, description))
    return out


def score_sets(rows_per_run, sets, run_names, current_units=False, preds=None) -> list[Score]:
    """Score every set on every run.

    ``rows_per_run``: per run the conditioned signals (``q, qd, qdd, tau, mask``) under the
    one conditioning; the usable rows (``mask``) are scored. ``preds`` (a dict, optional)
    receives (run name, set label) -> the predicted effort of the scored rows (M, n).
    """
    from guardid.identify.rows import predicted_effort

    out = []
    models = {}  # one model per description (its base parameters cost a QR each build)
    for cond, name in zip(rows_per_run, run_names, strict=True):
        m = cond.mask
        tau = cond.tau[m]
        # rows per joint (the momentum form zeroes a joint's cut rows)
        jm = getattr(cond, "joint_mask", None)
        used = jm[m].sum(0) if jm is not None else np.full(tau.shape[1], len(tau))
        rowless = used == 0
        n_j = np.maximum(used, 1)
        rms_tau = np.sqrt(np.sum(tau**2, axis=0) / n_j)
        passive = (rms_tau < PASSIVE_FRACTION * rms_tau.max()) & ~rowless
        for s in sets:
            if id(s.description) not in models:
                models[id(s.description)] = build_model(s.description)
            model = models[id(s.description)]
            theta = np.array([s.values[n] for n in model.base.names])
            pred = predicted_effort(cond, model, theta)
            if preds is not None:
                preds[(name, s.label)] = pred
            r = tau - pred
            rms = np.sqrt(np.sum(r**2, axis=0) / n_j)
            rel = np.where(passive | rowless, np.nan, rms / np.where(rms_tau > 0, rms_tau, 1.0))
            stacked = float(np.sqrt(np.mean(r**2)) / np.sqrt(np.mean(tau**2)))
            out.append(Score(s.label, name, stacked, rms, rel, passive, int(m.sum()),
                             float(np.sum(tau**2)), rowless))  # fmt: skip
    return out


def table(scores, description, current_units=False) -> str:
    """Per run, one line per parameter set: stacked error, then per joint rms (relative)."""
    units = joint_units(description, current_units)
    joints = [j.name for j in description.joints]
    width = max(len(s.label) for s in scores) + 2
    lines = []
    for run in dict.fromkeys(s.run for s in scores):
        mine = [s for s in scores if s.run == run]
        lines.append(f"run {run} ({mine[0].rows} rows)")
        head = f"  {'parameter set':{width}s} {'stacked':>8s}"
        for j, u in zip(joints, units, strict=True):
            head += f"  {j + ' rms [' + u + '] (rel.)':>28s}"
        lines.append(head)
        for s in mine:
            line = f"  {s.label:{width}s} {100 * s.stacked:7.2f}%"
            for k in range(len(joints)):
                rel = "passive" if s.passive[k] else f"{100 * s.relative[k]:.2f} %"
                cell = f"{s.rms[k]:.4g} ({rel})"
                if s.rowless is not None and s.rowless[k]:
                    cell = "no usable row"
                line += f"  {cell:>28s}"
            lines.append(line)
    return "\n".join(lines)


def _yaml(path) -> dict:
    from guardid.identify.report import read_yaml

    data = read_yaml(path)
    if not isinstance(data, dict):
        raise ConfigError(f"{path}: expected a mapping")
    return data


def load_sets(path, description) -> list[ParameterSet]:
    """Parameter sets of ``path``: a params file (one per method) or a reference file."""
    from guardid.identify.report import read_params

    data = _yaml(path)
    if "guardid-reference" in data:
        return [reference_set(path, description)]
    data = read_params(path)
    if not data["methods"]:
        raise ConfigError(f"{path}: methods: empty (no estimate to score; rerun guardid identify)")
    return params_sets(path, data, description)


def not_finite(parameter_set) -> str | None:
    """Why ``parameter_set`` cannot be scored or run (its file, method and the first
    parameter whose value is not finite: an untrusted fit written with ``--force``), or
    None when every value is finite."""
    bad = [n for n, v in parameter_set.values.items() if not math.isfinite(float(v))]
    if not bad:
        return None
    path, _, method = parameter_set.label.rpartition(":")
    return (f"{path}: methods.{method.lower()}: {bad[0]} = {parameter_set.values[bad[0]]!r} is "
            "not finite (a fit that could not be trusted, written with --force?)")  # fmt: skip


def finite_sets(sets) -> tuple[list[ParameterSet], list[str]]:
    """(the sets whose values are all finite, why each other one is left out); a one-line
    ConfigError when none is left."""
    reasons = [(s, not_finite(s)) for s in sets]
    kept = [s for s, reason in reasons if reason is None]
    why = [reason for _, reason in reasons if reason is not None]
    if sets and not kept:
        raise ConfigError(f"{why[0]}: no parameter set to score or run")
    return kept, why


def first_params(paths):
    """(path, data) of the first params file among ``paths`` (not a reference file), or ()."""
    from guardid.identify.report import read_params

    for path in paths:
        if "guardid-reference" not in _yaml(path):
            return (path, read_params(path))
    return ()


def stored_robot(path, data):
    """The robot a params file was identified for: its stored description (a
    ChainDescription), else its robot name (older files)."""
    from guardid.robot.loader import parse_robot

    raw = data.get("robot_description")
    if raw is None:
        return data["robot"]
    return parse_robot(raw, f"{path}: robot_description", source=str(path))


def stored_conditioning(path, data) -> ConditioningOptions:
    """The conditioning a params file was identified under (older files: cutoff_hz and
    parallel_filter_hz at the top level)."""
    if "conditioning" in data:
        return ConditioningOptions.from_dict(data["conditioning"], f"{path}: conditioning")
    return ConditioningOptions(
        cutoff_hz=data.get("cutoff_hz"),
        parallel_filter_hz=data.get("parallel_filter_hz"),
        equation="acceleration",
    )


def validate_runs(runs, names, description, sets, options, current_units=False, keep=None,
                  current_zero: str = "subtract") -> str:  # fmt: skip
    """The ``guardid validate`` report: every set on every run under ``options``, the logs'
    current sensors' zeros taken off or not as ``current_zero`` says (``subtract``,
    ``ignore``: :func:`~guardid.identify.current_zero.subtract_zeros`).

    ``keep`` (a dict, optional) receives what the HTML report draws: ``conds`` (per run),
    ``scores``, ``preds`` ((run, label) -> predicted effort) and ``head``.
    """
    from guardid.identify.checks import call_naming_logs
    from guardid.identify.current_zero import subtract_zeros
    from guardid.identify.prepare import current_on_adc_levels
    from guardid.identify.rows import stacked_rows
    from guardid.identify.segments import split_runs

    torque = bool(runs[0].torque)
    runs = [current_on_adc_levels(r, description) for r in runs]  # as identify fitted them
    runs, zeros = subtract_zeros(runs, description, current_zero)  # as identify does
    split = split_runs(runs, options.cutoff_hz, description=description)  # segments as runs
    if split.gaps or split.jumps:
        runs, names = split.runs, [r.path for r in split.runs]
    arrays = [_run_tuple(r) for r in runs]
    kw = {"in_current_units": current_units, "effort_is_torque": torque}
    if options.cutoff_hz is None:
        chosen = call_naming_logs(names, stacked_rows, arrays, description, options, **kw)
        head = f"conditioning: {chosen.cond.notes[0]}"
        options = chosen.options
    else:
        head = f"conditioning: cut-off {options.cutoff_hz:g} Hz (the first params file's or given)"
    if options.parallel_filter_hz:
        head += f", parallel filter {options.parallel_filter_hz:g} Hz"
    conds = [
        call_naming_logs([name], stacked_rows, [a], description, options, **kw).cond
        for a, name in zip(arrays, names, strict=True)
    ]
    preds = {} if keep is not None else None
    scores = score_sets(conds, sets, [str(n) for n in names], current_units, preds=preds)
    if keep is not None:
        keep.update(conds=conds, scores=scores, preds=preds, head=head, names=list(names))
    lines = [head + "; the same rows for every parameter set"]
    lines += [f"warning: {w}" for w in split.lines(options.cutoff_hz)]
    lines += [*zeros.lines, *(f"warning: {w}" for w in zeros.warnings)]
    for s in sets:
        if s.defaulted:
            lines.append(f"{s.label}: not given, the robot description's values: "
                         + ", ".join(s.defaulted))  # fmt: skip
    lines.append(table(scores, description, current_units))
    if len(runs) > 1:
        lines.append("all runs, stacked relative rms error:")
        for s in sets:
            mine = [x for x in scores if x.label == s.label]
            num = sum(x.stacked**2 * x.ref2 for x in mine)
            den = sum(x.ref2 for x in mine)
            lines.append(f"  {s.label}: {100 * np.sqrt(num / den):.2f} %")
    return "\n".join(lines)


def _run_tuple(run):
    qd = getattr(run, "qd", None)
    return (run.t, run.q, run.current) if qd is None else (run.t, run.q, run.current, qd)
