"""Read a robot from a URDF plus its side YAML (docs/URDF.md) into a ChainDescription.

The URDF (read with ``yourdfpy``, imported only here) gives the kinematics (a serial chain
of revolute / continuous / prismatic joints; fixed joints merge their child link into the
moving body), each body's mass, COM and inertia, position and velocity limits and
``<dynamics damping friction>``. The side YAML ``<stem>.guardid.yaml`` gives what URDF has
no field for (drives, rotor inertia, friction offset, sensors, PID gains, acceleration
limits, sample period, gravity). Both are turned into the robot YAML's mapping and parsed by
:func:`guardid.robot.loader.parse_robot`: the URDF path makes the same description object.

Kinematics -> standard DH at q = 0 (all in the URDF root link's frame): z_{j-1} is joint
j's axis; for j < n, x_j runs along the common normal from axis j to axis j+1 (intersecting
axes: +-z_{j-1} x z_j, the sign nearer the URDF child link's x axis; parallel axes: the
normal through the URDF joint j origin); the last frame has a = alpha = 0 and x along the
last URDF link's x axis; frame 0 sits at joint 1's origin with x along the first URDF
link's x axis. Every link's proximal frame (where base parameters are expressed) then
coincides with the URDF joint frame wherever the DH convention lets it, so a URDF written
by ``guardid export`` reads back with the same base parameters.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import yaml

from guardid.errors import ConfigError

SIDE_SUFFIX = ".guardid.yaml"
_MOVING = ("revolute", "continuous", "prismatic")
_TOL = 1e-9


def side_path(urdf_path) -> Path:
    """``robot.urdf`` -> ``robot.guardid.yaml`` beside it."""
    p = Path(urdf_path)
    return p.with_name(p.stem + SIDE_SUFFIX)


def load_urdf(path) -> dict:
    """The robot-YAML mapping of a URDF and its side YAML (ConfigError naming the file)."""
    path = Path(path)
    side_file = side_path(path)
    side = _read_side(side_file)
    robot = _read_urdf(path)
    chain, bodies = _serial_chain(robot, path.name)
    frames, dh_rows = _dh_frames(chain, path.name)
    joints_side = side.get("joints") or {}
    links_side = side.get("links") or {}
    _unknown(joints_side, {j.name for j in chain}, side_file.name, "joints")
    _unknown(links_side, {j.child for j in chain}, side_file.name, "links")
    joints, links = [], []
    for k, joint in enumerate(chain):
        extra = dict(joints_side.get(joint.name) or {})
        joints.append(_joint_entry(joint, dh_rows[k], extra, side_file.name))
        mass, com, inertia = _body_in_frame(bodies[k + 1], frames[k + 1])
        entry = {
            "name": joint.child,
            "mass": mass,
            "com": com.tolist(),
            "inertia": inertia.tolist(),
        }
        known = (links_side.get(joint.child) or {}).get("known_zero")
        if known:
            entry["known_zero"] = known
        links.append(entry)
    g_root = np.asarray(side.get("gravity", [0.0, 0.0, -9.81]), dtype=float)
    if g_root.shape != (3,):
        raise ConfigError(f"{side_file.name}: gravity: expected 3 numbers")
    out = {
        "name": side.get("name", robot.name or path.stem),
        "model": "serial_chain",
        "gravity": (frames[0][:3, :3].T @ g_root).tolist(),
        "joints": joints,
        "links": links,
    }
    if "sample_period" in side:
        out["sample_period"] = side["sample_period"]
    return out


def _read_side(side_file: Path) -> dict:
    if not side_file.is_file():
        return {}
    try:
        data = yaml.safe_load(side_file.read_text(encoding="utf-8"))
    except yaml.YAMLError as exc:
        raise ConfigError(f"{side_file.name}: invalid YAML ({exc.__class__.__name__})") from None
    if data is None:
        return {}
    if not isinstance(data, dict):
        raise ConfigError(f"{side_file.name}: <top>: expected a mapping")
    allowed = {"guardid-urdf", "name", "sample_period", "gravity", "joints", "links"}
    for key in data:
        if key not in allowed:
            raise ConfigError(
                f"{side_file.name}: {key}: unknown key (allowed: {', '.join(sorted(allowed))})"
            )
    for key in ("joints", "links"):
        if data.get(key) is not None and not isinstance(data[key], dict):
            raise ConfigError(f"{side_file.name}: {key}: expected a mapping by name")
    return data


def _unknown(section: dict, names: set, filename: str, key: str) -> None:
    for name in section:
        if name not in names:
            raise ConfigError(
                f"{filename}: {key}.{name}: no such moving {key[:-1]} in the URDF "
                f"(have: {', '.join(sorted(names))})"
            )


def _read_urdf(path: Path):
    if not path.is_file():
        raise ConfigError(f"{path}: no such robot file")
    try:
        import yourdfpy  # heavy (trimesh, lxml): only when a URDF is read, an extra
    except ImportError:
        raise ConfigError(
            f"{path.name}: reading a URDF needs yourdfpy: pip install 'guardid[urdf]'"
        ) from None

    try:
        urdf = yourdfpy.URDF.load(str(path), build_scene_graph=False, load_meshes=False)
    except Exception as exc:  # lxml / yourdfpy raise many kinds on malformed XML
        first = str(exc).splitlines()[0] if str(exc) else exc.__class__.__name__
        raise ConfigError(f"{path.name}: not a readable URDF ({first})") from None
    return urdf.robot


def _serial_chain(robot, filename: str):
    """(moving joints in order, bodies): body k = [(link, T_link_in_root)] moved by joint k."""
    children: dict[str, list] = {}
    parents = set()
    for j in robot.joints:
        children.setdefault(j.parent, []).append(j)
        parents.add(j.child)
    roots = [lk.name for lk in robot.links if lk.name not in parents]
    if len(roots) != 1:
        raise ConfigError(f"{filename}: expected one root link, found {len(roots)}")
    links = {lk.name: lk for lk in robot.links}
    chain, bodies = [], [[]]

    def moving_below(name: str) -> bool:
        return any(j.type in _MOVING or moving_below(j.child) for j in children.get(name, []))

    def walk(name: str, tf: np.ndarray) -> None:
        bodies[-1].append((links[name], tf))
        below = [j for j in children.get(name, []) if j.type in _MOVING or moving_below(j.child)]
        if len(below) > 1:
            raise ConfigError(
                f"{filename}: link {name}: branches into {', '.join(j.name for j in below)}: "
                "only a serial chain is supported"
            )
        for j in children.get(name, []):
            if j.type == "fixed" and j not in below:
                walk_fixed(j.child, tf @ _origin(j))
        for j in below:
            origin = tf @ _origin(j)
            if j.type == "fixed":
                walk(j.child, origin)
                continue
            if j.type not in _MOVING:
                raise ConfigError(f"{filename}: joint {j.name}: type {j.type} is not supported")
            if j.mimic is not None:
                raise ConfigError(f"{filename}: joint {j.name}: mimic joints are not supported")
            chain.append(_Joint(j, origin))
            bodies.append([])
            walk(j.child, origin)

    def walk_fixed(name: str, tf: np.ndarray) -> None:
        bodies[-1].append((links[name], tf))
        for j in children.get(name, []):
            walk_fixed(j.child, tf @ _origin(j))

    walk(roots[0], np.eye(4))
    if not chain:
        raise ConfigError(f"{filename}: no revolute, continuous or prismatic joint")
    return chain, bodies


def _origin(joint) -> np.ndarray:
    return np.eye(4) if joint.origin is None else np.asarray(joint.origin, dtype=float)


class _Joint:
    """One moving URDF joint with its frame in the root frame at q = 0."""

    def __init__(self, j, tf: np.ndarray):
        self.name, self.child, self.raw = j.name, j.child, j
        self.type = "prismatic" if j.type == "prismatic" else "revolute"
        axis = np.array([1.0, 0.0, 0.0]) if j.axis is None else np.asarray(j.axis, dtype=float)
        self.axis = tf[:3, :3] @ (axis / np.linalg.norm(axis))
        self.point = tf[:3, 3].copy()
        self.x_hint = tf[:3, 0].copy()


def _perp(v: np.ndarray, z: np.ndarray, fallback: np.ndarray) -> np.ndarray:
    """Unit vector: v with its z component removed (fallback's if v is along z)."""
    for cand in (v, fallback, np.array([1.0, 0.0, 0.0]), np.array([0.0, 1.0, 0.0])):
        p = cand - np.dot(cand, z) * z
        if np.linalg.norm(p) > 1e-6:
            return p / np.linalg.norm(p)
    raise AssertionError("unreachable")


def _frame(origin, x, z) -> np.ndarray:
    out = np.eye(4)
    out[:3, 0], out[:3, 2] = x, z
    out[:3, 1] = np.cross(z, x)
    out[:3, 3] = origin
    return out


def _angle(u, v, about) -> float:
    return float(np.arctan2(np.dot(np.cross(u, v), about), np.dot(u, v)))


def _dh_frames(chain, filename: str):
    """DH frames 0..n (4, 4) in the root frame at q = 0 and rows (a, alpha, d, theta)."""
    n = len(chain)
    z0 = chain[0].axis
    x0 = _perp(chain[0].x_hint, z0, z0)
    frames = [_frame(chain[0].point, x0, z0)]
    rows = []
    for j in range(n):
        prev = frames[-1]
        o_prev, x_prev, z_prev = prev[:3, 3], prev[:3, 0], prev[:3, 2]
        here = chain[j]
        if j == n - 1:
            d = float(np.dot(here.point - o_prev, z_prev))
            x = _perp(here.x_hint, z_prev, x_prev)
            origin, z, a, alpha = o_prev + d * z_prev, z_prev, 0.0, 0.0
        else:
            nxt = chain[j + 1]
            z = nxt.axis
            cross = np.cross(z_prev, z)
            if np.linalg.norm(cross) > 1e-9:
                # closest points of the lines o_prev + s z_prev and nxt.point + t z
                w = o_prev - nxt.point
                b = float(np.dot(z_prev, z))
                den = 1.0 - b * b
                s = (b * np.dot(z, w) - np.dot(z_prev, w)) / den
                t = (np.dot(z, w) - b * np.dot(z_prev, w)) / den
                foot, origin = o_prev + s * z_prev, nxt.point + t * z
                d = float(s)
            else:  # parallel: the normal through the URDF joint's origin
                d = float(np.dot(here.point - o_prev, z_prev))
                foot = o_prev + d * z_prev
                origin = nxt.point + np.dot(foot - nxt.point, z) * z
            normal = origin - foot
            a = float(np.linalg.norm(normal))
            if a > _TOL:
                x = normal / a
            elif np.linalg.norm(cross) > 1e-9:
                x = cross / np.linalg.norm(cross)
                if np.dot(x, here.x_hint) < 0:
                    x = -x
            else:
                x = _perp(here.x_hint, z_prev, x_prev)
                a = 0.0
            alpha = _angle(z_prev, z, x)
        theta = _angle(x_prev, x, z_prev)
        frames.append(_frame(origin, x, z))
        rows.append({"a": a, "alpha": alpha, "d": d, "theta": theta})
    return frames, rows


def _body_in_frame(parts, frame: np.ndarray):
    """(mass [kg], COM (3,), inertia about the COM (3, 3)) of a body's links in ``frame``."""
    mass, first, second = 0.0, np.zeros(3), np.zeros((3, 3))
    for link, tf in parts:
        inertial = link.inertial
        if inertial is None or not inertial.mass:
            continue
        m = float(inertial.mass)
        itf = tf @ (np.eye(4) if inertial.origin is None else np.asarray(inertial.origin, float))
        rot, c = itf[:3, :3], itf[:3, 3]
        i_c = np.zeros((3, 3)) if inertial.inertia is None else np.asarray(inertial.inertia, float)
        mass += m
        first += m * c
        second += rot @ i_c @ rot.T + m * (np.dot(c, c) * np.eye(3) - np.outer(c, c))
    if mass <= 0.0:
        return 0.0, np.zeros(3), np.zeros((3, 3))
    com = first / mass
    i_com = second - mass * (np.dot(com, com) * np.eye(3) - np.outer(com, com))
    rot, o = frame[:3, :3], frame[:3, 3]
    i_f = rot.T @ i_com @ rot
    return mass, rot.T @ (com - o), 0.5 * (i_f + i_f.T)


def _joint_entry(joint, dh: dict, extra: dict, side_name: str) -> dict:
    raw = joint.raw
    limit = raw.limit
    accel = extra.pop("acceleration", None)
    velocity = extra.pop("velocity", None)
    if velocity is None:
        velocity = None if limit is None else limit.velocity
    position = None
    if raw.type != "continuous" and limit is not None and limit.lower is not None:
        position = [float(limit.lower), float(limit.upper)]
    if accel is None:
        raise ConfigError(
            f"{side_name}: joints.{joint.name}.acceleration: missing (URDF has no "
            "acceleration limit)"
        )
    if velocity is None:
        raise ConfigError(f"{side_name}: joints.{joint.name}.velocity: missing (no URDF <limit>)")
    entry = {
        "name": joint.name,
        "type": joint.type,
        "dh": dh,
        "limits": {"position": position, "velocity": velocity, "acceleration": accel},
        "drive": extra.pop("drive", None),
    }
    if "friction" in extra:
        entry["friction"] = extra.pop("friction")
    elif raw.dynamics is not None and (raw.dynamics.damping or raw.dynamics.friction):
        entry["friction"] = {
            "viscous": float(raw.dynamics.damping or 0.0),
            "coulomb": float(raw.dynamics.friction or 0.0),
        }
    else:
        entry["friction"] = None
    entry.update(extra)  # rotor, encoder, sensors, pid: the robot YAML's keys (checked there)
    return entry
