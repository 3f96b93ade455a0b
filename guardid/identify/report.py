"""Present an :class:`Identification`: the text table, params.yaml, and the optional plot."""

from __future__ import annotations

import math

import yaml

from guardid.errors import ConfigError
from guardid.yaml_load import safe_load


def friction_summary(description) -> str:
    """'friction: shoulder tanh(qd / 0.01 rad/s), ...' (the model each joint's Coulomb term has)."""
    parts = []
    for j in description.joints:
        f = j.friction
        if f is None:
            continue
        unit = "m/s" if j.type == "prismatic" else "rad/s"
        if f.model == "sign":
            shape = "sign(qd)"
        else:
            fn = "atan" if f.model == "atan" else "tanh"
            shape = f"{fn}(qd / {f.velocity_scale:g} {unit})"
        if f.model == "stribeck":
            shape += f" + Stribeck exp(-(qd / {f.stribeck_velocity:g} {unit})^2) {shape}"
        parts.append(f"{j.name} {shape}")
    return "friction (Coulomb term): " + ", ".join(parts) if parts else ""


def effort_units(result, description) -> str:
    """'N m' / 'N' / 'N m, N' per joint kind, or the current units."""
    if result.torque_unit != "N m":
        return "A (current units)"
    kinds = ["N" if j.type == "prismatic" else "N m" for j in description.joints]
    if len(set(kinds)) == 1:
        return kinds[0]
    return ", ".join(f"{j.name} {k}" for j, k in zip(description.joints, kinds, strict=True))


SPREAD_NOTE = (
    "MLP ~: the spread of the network's output over the rows (its standard deviation over "
    "the samples), not an uncertainty of the estimate"
)
"""What an MLP's "~" (table) and ``output_spread`` (params.yaml) are."""


def table(result, methods, description=None) -> str:
    """Base parameters per method: estimate, +- std where known (MLP: ~ its output's spread,
    :data:`SPREAD_NOTE`), and the description's value; then the conditioning (cut-off and
    why, rows used and dropped) and the friction model."""
    head = f"{'parameter':10s} {'YAML':>10s}"
    from guardid.closedloop import STD_NOT_HONEST

    for m in methods:
        label = m.upper() if result.results[m].converged else f"{m.upper()} (not converged)"
        if m in STD_NOT_HONEST:  # its std fails the Monte Carlo: said in the header
            label += " (std not honest)"
        head += f" {label:>21s}"
    lines = []
    if result.cutoff_reason:
        lines.append(result.cutoff_reason)
    if result.rows_summary:
        lines.append(result.rows_summary)
    if description is not None and friction_summary(description):
        lines.append(friction_summary(description))
    lines.append(head)
    for k, name in enumerate(result.names):
        line = f"{name:10s} {result.nominal[k]:10.4g}"
        for m in methods:
            r = result.results[m]
            if r.std is not None:
                cell = f"{r.theta[k]:.4g} +- {r.std[k]:.2g}"
            elif r.output_spread is not None:
                cell = f"{r.theta[k]:.4g} ~ {r.output_spread[k]:.2g}"
            else:
                cell = f"{r.theta[k]:.4g}"
            line += f" {cell:>21s}"
        lines.append(line)
    unit = "N m" if result.torque_unit == "N m" else "A (current units)"
    if description is not None:
        unit = effort_units(result, description)
    fit = _percents(result, methods, "d_tau")
    stacked = _percents(result, methods, "d_stacked")
    lines.append(
        f"rows {result.rows}, cut-off {result.cutoff_hz:.3g} Hz, cond(A) {result.cond:.4g}, "
        f"effort in {unit}; d_tau {fit}; stacked error {stacked}"
    )
    if getattr(result, "current_zero", None) is not None:
        lines += result.current_zero.lines
    if any(result.results[m].output_spread is not None for m in methods):
        lines.append(SPREAD_NOTE)
    for motor in result.motors:
        lines.append(
            f"motor {motor.joint}: R {motor.resistance:.4g} +- {motor.resistance_std:.2g} ohm, "
            f"Ke {motor.ke:.5g} +- {motor.ke_std:.2g} V s/rad"
        )
    return "\n".join(lines)


def to_yaml_dict(result, description, log_path) -> dict:
    """The params.yaml content: per method values (and std), names, formulas, settings."""
    from guardid.closedloop import STD_NOT_HONEST

    out = {
        "guardid-params": 1,
        "robot": description.name,
        "log": str(log_path),
        "torque_unit": result.torque_unit,
        "cutoff_hz": result.cutoff_hz,
        "conditioning": result.conditioning.to_dict(),
        "cond": result.cond,
        "rows": result.rows,
        "base_parameters": [
            {"name": n, "formula": f, "yaml_value": float(v)}
            for n, f, v in zip(result.names, result.formulas, result.nominal, strict=True)
        ],
        "methods": {},
    }
    for m, r in result.results.items():
        entry = {"values": [float(x) for x in r.theta], "d_tau": float(r.d_tau),
                 "stacked_error": float(r.d_stacked), "converged": bool(r.converged)}  # fmt: skip
        if r.std is not None:
            entry["std"] = [float(x) for x in r.std]
        if r.output_spread is not None:  # not a std: nothing that reads "std" may take it
            entry["output_spread"] = [float(x) for x in r.output_spread]
            entry["output_spread_is"] = SPREAD_NOTE.removeprefix("MLP ~: ")
        if "quantisation_bootstrap" in r.settings:  # guardid.uncertainty: values corrected
            entry["quantisation_bootstrap"] = r.settings["quantisation_bootstrap"]
        if "repeating_residual" in r.settings:  # its std counts an error repeating per period
            entry["repeating_residual"] = r.settings["repeating_residual"]
        if m in STD_NOT_HONEST:
            entry["std_honest"] = False
            entry["std_note"] = STD_NOT_HONEST[m]
        out["methods"][m] = entry
    if result.motors:
        out["motors"] = [
            {
                "joint": mo.joint,
                "resistance_ohm": mo.resistance,
                "resistance_std": mo.resistance_std,
                "ke_v_s_per_rad": mo.ke,
                "ke_std": mo.ke_std,
            }
            for mo in result.motors
        ]
    if result.current_zero is not None:
        out["current_zero"] = result.current_zero.to_dict(description)
    raw = robot_mapping(description)
    if raw is not None:
        out["robot_description"] = raw
    return out


def robot_mapping(description) -> dict | None:
    """The robot description's YAML mapping (from its source file), or None."""
    source = getattr(description, "source", "")
    if not source:
        return None
    try:
        with open(source, encoding="utf-8") as f:
            return safe_load(f)
    except (OSError, yaml.YAMLError):
        return None


def _percents(result, methods, field: str) -> str:
    """``LS 0.85 %, WLS 0.85 %``: a method without the figure (NaN, e.g. the consistent fit,
    scored elsewhere) is left out rather than printed as nan."""
    values = ((m, 100 * getattr(result.results[m], field)) for m in methods)
    return ", ".join(f"{m.upper()} {v:.2f} %" for m, v in values if math.isfinite(v)) or "-"


def read_yaml(path):
    """A YAML file's content; one-line errors naming the file (unreadable, not UTF-8 text,
    invalid YAML)."""
    try:
        with open(path, encoding="utf-8") as f:
            return safe_load(f)
    except OSError as exc:
        raise ConfigError(f"{path}: cannot read: {exc.strerror}") from None
    except UnicodeDecodeError as exc:
        raise ConfigError(f"{path}: byte {exc.start}: not UTF-8 text") from None
    except yaml.YAMLError as exc:
        raise ConfigError(f"{path}: invalid YAML: {str(exc).splitlines()[0]}") from None


def read_params(path) -> dict:
    """Load params.yaml written by ``guardid identify`` (one-line errors naming the key)."""
    data = read_yaml(path)
    if not isinstance(data, dict) or data.get("guardid-params") != 1:
        raise ConfigError(f"{path}: guardid-params: not a params file written by guardid identify")
    for key in ("robot", "base_parameters", "methods"):
        if key not in data:
            raise ConfigError(f"{path}: {key}: missing")
    base = data["base_parameters"]
    if not isinstance(base, list) or not all(isinstance(p, dict) and "name" in p for p in base):
        raise ConfigError(f"{path}: base_parameters: expected a list of mappings with a name")
    methods = data["methods"]
    if not isinstance(methods, dict) or not all(
        isinstance(m, dict) and isinstance(m.get("values"), list) for m in methods.values()
    ):
        raise ConfigError(f"{path}: methods: expected method: {{values: [...]}} entries")
    for name, entry in methods.items():
        for key in ("values", "std"):
            seq = entry.get(key)
            if key == "std" and seq is None:
                continue
            if not isinstance(seq, list):
                raise ConfigError(f"{path}: methods.{name}.{key}: expected a list of numbers")
            for k, x in enumerate(seq):
                if isinstance(x, bool) or not isinstance(x, (int, float)):
                    raise ConfigError(f"{path}: methods.{name}.{key}[{k}]: {x!r} is not a number")
    return data
