"""Load and validate a robot description YAML (schema: docs/ROBOT_YAML.md)."""

from __future__ import annotations

from importlib import resources
from pathlib import Path

import numpy as np
import yaml

from guardid.errors import ConfigError
from guardid.robot.description import (
    DH,
    FRICTION_MODELS,
    PID,
    STANDARD_NAMES,
    ChainDescription,
    Drive,
    Encoder,
    FlexibleLinkDescription,
    Friction,
    JointDescription,
    Limits,
    LinkDescription,
    ParameterRange,
    Rotor,
    Sensor,
)
from guardid.robot.validate import Checker
from guardid.yaml_load import safe_load

SHIPPED = ("guard", "planar2", "flexlink", "dfki_double_pendulum")
DEFAULT_SAMPLE_PERIOD = 0.015  # s
DEFAULT_GRAVITY = (0.0, 0.0, -9.81)  # m/s^2
DEFAULT_VOLTAGE_SENSOR = Sensor(range=15.0, adc_bits=10, noise=0.01)  # V, bits, V
"""Voltage sensor assumed for a joint with a drive when ``voltage_sensor`` is omitted."""


def shipped_path(name: str) -> Path:
    """Path of a shipped robot file, e.g. ``shipped_path('guard')``."""
    return Path(str(resources.files("guardid") / "robots" / f"{name}.yaml"))


def load_robot(spec: str | Path) -> ChainDescription | FlexibleLinkDescription:
    """Load a robot by shipped name (:data:`SHIPPED`), YAML file path or URDF path (with its
    side YAML ``<stem>.guardid.yaml``, :mod:`guardid.robot.urdf`).

    Raises ConfigError (one line: ``<file>: <key path>: <problem>``) on any invalid content.
    """
    spec_str = str(spec)
    if spec_str.lower().endswith(".urdf"):  # URDF + side YAML (docs/URDF.md)
        from guardid.robot.urdf import load_urdf, side_path

        path = Path(spec_str)
        filename = f"{path.name} (+ {side_path(path).name})"
        return parse_robot(load_urdf(path), filename, source=str(path))
    if spec_str in SHIPPED:
        path = shipped_path(spec_str)
    else:
        path = Path(spec_str)
        if not path.is_file():
            raise ConfigError(
                f"{spec_str}: no such robot file (shipped robots: {', '.join(SHIPPED)})"
            )
    try:
        text = path.read_text(encoding="utf-8")
    except UnicodeDecodeError as exc:
        raise ConfigError(
            f"{path.name}: byte {exc.start}: not UTF-8 text (a robot description is YAML)"
        ) from None
    except OSError as exc:
        raise ConfigError(f"{path.name}: cannot read: {exc.strerror or exc}") from None
    try:
        data = safe_load(text)
    except RecursionError:
        raise ConfigError(f"{path.name}: invalid YAML (nested too deeply)") from None
    except yaml.YAMLError as exc:
        line = getattr(getattr(exc, "problem_mark", None), "line", None)
        where = f"line {line + 1}" if line is not None else "<yaml>"
        msg = f"{path.name}: {where}: invalid YAML ({exc.__class__.__name__})"
        raise ConfigError(msg) from None
    return parse_robot(data, path.name, source=str(path))


def parse_robot(data, filename: str = "<robot>", source: str = ""):
    """Validate an already-parsed YAML mapping; ``filename`` is used in error messages."""
    ck = Checker(filename)
    if not isinstance(data, dict):
        ck.fail("", "expected a mapping at the top level")
    model = ck.string(data.get("model", "serial_chain"), "model", ("serial_chain", "flexible_link"))
    if model == "flexible_link":
        return _parse_flexlink(ck, data, source)
    return _parse_chain(ck, data, source)


def _parse_chain(ck: Checker, data: dict, source: str) -> ChainDescription:
    ck.mapping(data, "", ("name", "joints", "links"), ("model", "sample_period", "gravity"))
    name = ck.string(data["name"], "name")
    period = ck.number(
        data.get("sample_period", DEFAULT_SAMPLE_PERIOD), "sample_period", positive=True
    )
    gravity = np.array(ck.vector(data.get("gravity", list(DEFAULT_GRAVITY)), "gravity", 3))
    joints_raw = ck.sequence(data["joints"], "joints")
    if not joints_raw:
        ck.fail("joints", "at least one joint is required")
    links_raw = ck.sequence(data["links"], "links", len(joints_raw))
    joints = tuple(_joint(ck, j, f"joints[{i}]", i) for i, j in enumerate(joints_raw))
    _check_joint_names(ck, [j.name for j in joints], "joints[{}].name")
    _check_rotor_coupling(ck, joints)
    links = tuple(_link(ck, v, f"links[{i}]", i) for i, v in enumerate(links_raw))
    return ChainDescription(
        name=name, joints=joints, links=links, gravity=gravity, sample_period=period, source=source
    )


_NOT_IN_A_NAME = (",", "\n", "\r", '"')
"""Characters a joint name may not hold: it becomes part of the log's comma-separated
column names (q_<joint>_rad, ...)."""


def _check_joint_names(ck: Checker, names, path: str) -> None:
    """Joint names must be unique (the log's columns and the trajectories find joints by
    name) and usable inside a log's column names; ``path`` has a ``{}`` for the index."""
    seen: dict[str, int] = {}
    for i, name in enumerate(names):
        if name in seen:
            ck.fail(path.format(i), f"{name!r} is also joint {seen[name]}'s name (joint names "
                    "must be unique: logs and trajectories find joints by name)")  # fmt: skip
        bad = next((c for c in _NOT_IN_A_NAME if c in name), None)
        if bad is not None or not name or name != name.strip():
            ck.fail(path.format(i), f"{name!r}: a joint name must be non-empty, without commas, "
                    "quotes, line breaks or spaces at its ends (it is part of the log's column "
                    "names)")  # fmt: skip
        seen[name] = i


def _friction(ck: Checker, raw, fp: str) -> Friction:
    opt = ("offset", "model", "velocity_scale", "stribeck", "stribeck_velocity")
    f = ck.mapping(raw, fp, ("viscous", "coulomb"), opt)
    no_offset = "offset" in f and f["offset"] is None  # null: not modelled (0)
    model = ck.string(f.get("model", "sign"), f"{fp}.model", FRICTION_MODELS)
    scale = strib = None
    if model != "sign":
        if f.get("velocity_scale") is None:
            ck.fail(f"{fp}.velocity_scale", f"required by model {model} [rad/s or m/s]")
        scale = ck.number(f["velocity_scale"], f"{fp}.velocity_scale", positive=True)
    elif f.get("velocity_scale") is not None:
        ck.fail(f"{fp}.velocity_scale", "only with model tanh, atan or stribeck")
    if model == "stribeck":
        if f.get("stribeck_velocity") is None:
            ck.fail(f"{fp}.stribeck_velocity", "required by model stribeck [rad/s or m/s]")
        strib = ck.number(f["stribeck_velocity"], f"{fp}.stribeck_velocity", positive=True)
    elif f.get("stribeck") is not None or f.get("stribeck_velocity") is not None:
        ck.fail(f"{fp}.stribeck", "only with model stribeck")
    return Friction(
        ck.number(f["viscous"], f"{fp}.viscous", nonneg=True),
        ck.number(f["coulomb"], f"{fp}.coulomb", nonneg=True),
        0.0 if no_offset else ck.number(f.get("offset", 0.0), f"{fp}.offset"),
        offset_modelled=not no_offset,
        model=model,
        velocity_scale=scale,
        stribeck=ck.number(f.get("stribeck", 0.0), f"{fp}.stribeck", nonneg=True),
        stribeck_velocity=strib,
    )


def _joint(ck: Checker, raw, path: str, index: int) -> JointDescription:
    opt = ("name", "encoder", "current_sensor", "voltage_sensor", "pid", "rotor")
    ck.mapping(raw, path, ("type", "dh", "limits", "drive", "friction"), opt)
    jtype = ck.string(raw["type"], f"{path}.type", ("revolute", "prismatic"))
    name = ck.string(raw.get("name", f"joint{index + 1}"), f"{path}.name")
    d = ck.mapping(raw["dh"], f"{path}.dh", ("a", "alpha", "d", "theta"))
    dh = DH(*(ck.number(d[k], f"{path}.dh.{k}") for k in ("a", "alpha", "d", "theta")))
    drive = _drive(ck, raw["drive"], f"{path}.drive")
    friction = None
    if raw["friction"] is not None:
        friction = _friction(ck, raw["friction"], f"{path}.friction")
    encoder = None
    if raw.get("encoder") is not None:
        ep = f"{path}.encoder"
        e = ck.mapping(raw["encoder"], ep, ("counts_per_rev", "quadrature"))
        encoder = Encoder(
            ck.integer(e["counts_per_rev"], f"{ep}.counts_per_rev"),
            ck.boolean(e["quadrature"], f"{ep}.quadrature"),
        )
    current = _sensor(ck, raw.get("current_sensor"), f"{path}.current_sensor")
    default_v = DEFAULT_VOLTAGE_SENSOR if drive is not None else None
    voltage = (
        _sensor(ck, raw["voltage_sensor"], f"{path}.voltage_sensor")
        if "voltage_sensor" in raw
        else default_v
    )
    pid = None
    if raw.get("pid") is not None:
        pp = f"{path}.pid"
        p = ck.mapping(raw["pid"], pp, ("kp", "ki", "kd"))
        pid = PID(*(ck.number(p[k], f"{pp}.{k}", nonneg=True) for k in ("kp", "ki", "kd")))
    rotor = _rotor(ck, raw.get("rotor"), f"{path}.rotor", drive is not None)
    return JointDescription(
        name,
        jtype,
        dh,
        _limits(ck, raw["limits"], f"{path}.limits"),
        drive,
        friction,
        encoder,
        current,
        voltage,
        pid,
        rotor,
    )


def _rotor(ck: Checker, raw, path: str, has_drive: bool) -> Rotor | None:
    """Mechanical-only rotor {gear_ratio, inertia [kg m^2], coupling -1|0|1} or None."""
    if raw is None:
        return None
    if has_drive:
        ck.fail(path, "the joint has a drive: give the rotor inertia as drive.rotor_inertia")
    ck.mapping(raw, path, ("gear_ratio", "inertia"), ("coupling",))
    coupling = raw.get("coupling", 0)
    if isinstance(coupling, bool) or coupling not in (-1, 0, 1):
        ck.fail(f"{path}.coupling", f"expected -1, 0 or 1, got {coupling!r}")
    return Rotor(
        ck.number(raw["gear_ratio"], f"{path}.gear_ratio", positive=True),
        ck.number(raw["inertia"], f"{path}.inertia", nonneg=True),
        int(coupling),
    )


def _check_rotor_coupling(ck: Checker, joints) -> None:
    """A coupled rotor needs a previous link and every earlier axis parallel to its own."""
    for j, joint in enumerate(joints):
        if joint.rotor is None or joint.rotor.coupling == 0:
            continue
        path = f"joints[{j}].rotor.coupling"
        if j == 0:
            ck.fail(path, "the first joint's motor sits on the base: no previous link to couple")
        if joint.type != "revolute":
            ck.fail(path, "rotor coupling is modelled for revolute joints only")
        bad = [i + 1 for i in range(j) if abs(np.sin(joints[i].dh.alpha)) > 1e-9]
        if bad:
            ck.fail(
                path,
                "needs every earlier joint axis parallel to this one (dh.alpha 0 or pi), "
                f"not so after joint(s) {', '.join(map(str, bad))}",
            )


def _limits(ck: Checker, raw, path: str) -> Limits:
    ck.mapping(raw, path, ("position", "velocity", "acceleration"))
    position = None
    if raw["position"] is not None:
        lo, hi = ck.vector(raw["position"], f"{path}.position", 2)
        if not lo < hi:
            ck.fail(f"{path}.position", f"lower limit {lo:g} must be below upper limit {hi:g}")
        position = (lo, hi)
    return Limits(
        position,
        ck.number(raw["velocity"], f"{path}.velocity", positive=True),
        ck.number(raw["acceleration"], f"{path}.acceleration", positive=True),
    )


_DRIVE_KEYS = (
    "gear_ratio",
    "efficiency",
    "resistance",
    "inductance",
    "kt",
    "ke",
    "rotor_inertia",
    "supply_voltage",
    "pwm_bits",
)


def _drive(ck: Checker, raw, path: str) -> Drive | None:
    if raw is None:
        return None
    ck.mapping(raw, path, _DRIVE_KEYS)
    vals = {}
    for key in _DRIVE_KEYS[:-1]:
        kw = {"nonneg": True} if key in ("inductance", "rotor_inertia") else {"positive": True}
        if key == "efficiency":
            kw = {"lo": 0.0, "hi": 1.0}
        vals[key] = ck.number(raw[key], f"{path}.{key}", **kw)
    vals["pwm_bits"] = ck.integer(raw["pwm_bits"], f"{path}.pwm_bits")
    return Drive(**vals)


def _sensor(ck: Checker, raw, path: str) -> Sensor | None:
    if raw is None:
        return None
    ck.mapping(raw, path, ("range", "adc_bits", "noise"))
    return Sensor(
        ck.number(raw["range"], f"{path}.range", positive=True),
        ck.integer(raw["adc_bits"], f"{path}.adc_bits"),
        ck.number(raw["noise"], f"{path}.noise", nonneg=True),
    )


def _link(ck: Checker, raw, path: str, index: int) -> LinkDescription:
    ck.mapping(raw, path, ("mass", "com", "inertia"), ("name", "known_zero"))
    name = ck.string(raw.get("name", f"link{index + 1}"), f"{path}.name")
    mass = ck.number(raw["mass"], f"{path}.mass", positive=True)
    com = np.array(ck.vector(raw["com"], f"{path}.com", 3))
    inertia = _inertia(ck, raw["inertia"], f"{path}.inertia")
    known = ck.sequence(raw.get("known_zero", []), f"{path}.known_zero")
    known_zero = tuple(
        ck.string(k, f"{path}.known_zero[{i}]", STANDARD_NAMES) for i, k in enumerate(known)
    )
    link = LinkDescription(name, mass, com, inertia, known_zero)
    values = dict(zip(STANDARD_NAMES, link.standard_parameters(), strict=True))
    scale = max(abs(v) for v in values.values())
    for k in known_zero:
        if abs(values[k]) > 1e-9 * scale:
            ck.fail(f"{path}.known_zero", f"{k} is listed as zero but is {values[k]:.6g}")
    return link


def _inertia(ck: Checker, raw, path: str) -> np.ndarray:
    if isinstance(raw, dict):
        ck.mapping(raw, path, ("xx", "yy", "zz"), ("xy", "xz", "yz"))
        g = {
            k: ck.number(raw.get(k, 0.0), f"{path}.{k}")
            for k in ("xx", "yy", "zz", "xy", "xz", "yz")
        }
        mat = np.array(
            [[g["xx"], g["xy"], g["xz"]], [g["xy"], g["yy"], g["yz"]], [g["xz"], g["yz"], g["zz"]]]
        )
    elif isinstance(raw, list):
        rows = ck.sequence(raw, path, 3)
        mat = np.array([ck.vector(r, f"{path}[{i}]", 3) for i, r in enumerate(rows)])
    else:
        ck.fail(path, "expected {xx, yy, zz, xy, xz, yz} or a 3x3 list")
    scale = max(np.abs(mat).max(), 1e-300)
    if np.abs(mat - mat.T).max() > 1e-12 * scale:
        ck.fail(path, "inertia tensor is not symmetric")
    if np.linalg.eigvalsh(mat).min() < -1e-12 * scale:
        ck.fail(path, "inertia tensor is not positive semi-definite")
    d = np.diag(mat)
    for i in range(3):
        if d[i] > d[(i + 1) % 3] + d[(i + 2) % 3] + 1e-12 * scale:
            ck.fail(path, "principal moments violate the triangle inequality")
    # triangle inequality on principal moments (basis independent)
    ev = np.linalg.eigvalsh(mat)
    if ev[2] > ev[0] + ev[1] + 1e-12 * scale:
        ck.fail(path, "principal moments violate the triangle inequality")
    return mat


def _parse_flexlink(ck: Checker, data: dict, source: str) -> FlexibleLinkDescription:
    req = ("name", "model", "mass", "l1", "l2", "stiffness", "hub_inertia", "parameters")
    ck.mapping(data, "", req, ("sample_period", "initial_state", "joint_names"))
    vals = {
        k: ck.number(data[k], k, positive=True)
        for k in ("mass", "l1", "l2", "stiffness", "hub_inertia")
    }
    params = {}
    praw = ck.mapping(data["parameters"], "parameters", ("alpha", "gamma", "k"))
    for key in ("alpha", "gamma", "k"):
        pp = f"parameters.{key}"
        r = ck.mapping(praw[key], pp, ("nominal", "lo", "hi"))
        nominal, lo, hi = (ck.number(r[k], f"{pp}.{k}") for k in ("nominal", "lo", "hi"))
        if not lo < hi:
            ck.fail(pp, f"lo {lo:g} must be below hi {hi:g}")
        if not lo <= nominal <= hi:
            ck.fail(f"{pp}.nominal", f"{nominal:g} is outside [{lo:g}, {hi:g}]")
        params[key] = ParameterRange(nominal, lo, hi)
    x0 = np.array(ck.vector(data.get("initial_state", [0.0, 0.0, 0.0, 0.0]), "initial_state", 4))
    names = ck.sequence(data.get("joint_names", ["hub", "flex"]), "joint_names", 2)
    names = tuple(ck.string(n, f"joint_names[{i}]") for i, n in enumerate(names))
    _check_joint_names(ck, names, "joint_names[{}]")
    period = ck.number(data.get("sample_period", 0.0005), "sample_period", positive=True)
    return FlexibleLinkDescription(
        name=ck.string(data["name"], "name"),
        mass=vals["mass"],
        l1=vals["l1"],
        l2=vals["l2"],
        stiffness=vals["stiffness"],
        hub_inertia=vals["hub_inertia"],
        parameters=params,
        initial_state=x0,
        sample_period=period,
        joint_names=names,
        source=source,
    )
