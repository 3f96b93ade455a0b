"""The side YAML beside a URDF: what a robot description has that URDF has no field for.

Format (``<name>.guardid.yaml`` beside ``<name>.urdf``; docs/URDF.md): ``guardid-urdf: 1``,
``name``, ``sample_period`` [s], ``gravity`` [m/s^2] in the URDF root link's frame, and per
joint (by URDF joint name) ``acceleration`` limit, ``drive`` / ``rotor`` (with the rotor
inertia), ``friction`` (with the offset), ``encoder``, sensors, ``pid``; per link (by the
URDF link name of the moving body) ``known_zero``. The same keys as the robot YAML.
"""

from __future__ import annotations

from dataclasses import asdict

from guardid.robot.urdf import side_path

__all__ = ["side_dict", "side_path"]


def side_dict(description, gravity_in_root) -> dict:
    """The side YAML mapping of a description (gravity [m/s^2] in the exported root frame)."""
    joints = {}
    for joint in description.joints:
        entry: dict = {"acceleration": float(joint.limits.acceleration)}
        entry["drive"] = None if joint.drive is None else _plain(asdict(joint.drive))
        if joint.rotor is not None:
            entry["rotor"] = _plain(asdict(joint.rotor))
        if joint.friction is None:
            entry["friction"] = None
        else:
            fr = joint.friction
            entry["friction"] = {
                "viscous": float(fr.viscous),
                "coulomb": float(fr.coulomb),
                "offset": float(fr.offset) if fr.offset_modelled else None,
            }
        for key in ("encoder", "current_sensor", "voltage_sensor", "pid"):
            value = getattr(joint, key)
            entry[key] = None if value is None else _plain(asdict(value))
        joints[joint.name] = entry
    links = {link.name: {"known_zero": list(link.known_zero)} for link in description.links}
    return {
        "guardid-urdf": 1,
        "name": description.name,
        "sample_period": float(description.sample_period),
        "gravity": [float(x) for x in gravity_in_root],
        "joints": joints,
        "links": links,
    }


def _plain(d: dict) -> dict:
    return {k: (float(v) if isinstance(v, float) else v) for k, v in d.items()}
