"""Write a serial-chain robot description as URDF plus its side YAML (docs/URDF.md).

Links: ``world`` (z up, gravity -z), a fixed joint to ``base`` (the description's DH frame
0, turned so that its gravity points down), then one link per description link in its
proximal frame (:mod:`guardid.export.frames`) with the link's mass, COM and inertia.
Joints: revolute (``continuous`` without position limits) or prismatic about / along z,
``<limit>`` velocity and effort (a drive's stall torque N eta kt V / R; 1000 for a torque-
driven joint), ``<dynamics damping="Fv" friction="Fc"/>``. What URDF has no field for goes
to the side YAML (:mod:`guardid.export.side`): rotor inertia, friction offset, drives,
sensors, PID gains, acceleration limits, sample period, gravity's magnitude.
"""

from __future__ import annotations

import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import yaml

from guardid.export.frames import gravity_alignment, joint_origins, link_inertial, rpy_from_matrix
from guardid.export.side import side_dict, side_path

TORQUE_DRIVEN_EFFORT = 1000.0
"""URDF effort limit [N m | N] written for a joint without a drive (URDF needs one)."""


def _num(x: float) -> str:
    return repr(float(x))


def _vec(v) -> str:
    return " ".join(_num(x) for x in v)


def _origin(parent: ET.Element, tf: np.ndarray) -> None:
    ET.SubElement(parent, "origin", xyz=_vec(tf[:3, 3]), rpy=_vec(rpy_from_matrix(tf[:3, :3])))


def urdf_text(description) -> str:
    """The URDF document (str) of a serial-chain description (module docstring)."""
    robot = ET.Element("robot", name=description.name)
    ET.SubElement(robot, "link", name="world")
    ET.SubElement(robot, "link", name="base")
    fixed = ET.SubElement(robot, "joint", name="world_to_base", type="fixed")
    ET.SubElement(fixed, "parent", link="world")
    ET.SubElement(fixed, "child", link="base")
    align = np.eye(4)
    align[:3, :3] = gravity_alignment(description.gravity)
    _origin(fixed, align)
    parent = "base"
    for k, (joint, tf) in enumerate(
        zip(description.joints, joint_origins(description), strict=True)
    ):
        link = description.links[k]
        el = ET.SubElement(robot, "link", name=link.name)
        mass, com, inertia = link_inertial(description, k)
        inertial = ET.SubElement(el, "inertial")
        ET.SubElement(inertial, "origin", xyz=_vec(com), rpy="0 0 0")
        ET.SubElement(inertial, "mass", value=_num(mass))
        ET.SubElement(
            inertial,
            "inertia",
            ixx=_num(inertia[0, 0]),
            ixy=_num(inertia[0, 1]),
            ixz=_num(inertia[0, 2]),
            iyy=_num(inertia[1, 1]),
            iyz=_num(inertia[1, 2]),
            izz=_num(inertia[2, 2]),
        )
        limited = joint.limits.position is not None
        jtype = joint.type if (limited or joint.type == "prismatic") else "continuous"
        jel = ET.SubElement(robot, "joint", name=joint.name, type=jtype)
        ET.SubElement(jel, "parent", link=parent)
        ET.SubElement(jel, "child", link=link.name)
        _origin(jel, tf)
        ET.SubElement(jel, "axis", xyz="0 0 1")
        limit = {"effort": _num(_effort(joint)), "velocity": _num(joint.limits.velocity)}
        if limited:
            limit.update(lower=_num(joint.limits.position[0]), upper=_num(joint.limits.position[1]))
        elif joint.type == "prismatic":
            limit.update(lower=_num(-1e3), upper=_num(1e3))
        ET.SubElement(jel, "limit", **limit)
        if joint.friction is not None:
            ET.SubElement(
                jel,
                "dynamics",
                damping=_num(joint.friction.viscous),
                friction=_num(joint.friction.coulomb),
            )
        parent = link.name
    ET.indent(robot)
    return '<?xml version="1.0"?>\n' + ET.tostring(robot, encoding="unicode") + "\n"


def _effort(joint) -> float:
    d = joint.drive
    if d is None:
        return TORQUE_DRIVEN_EFFORT
    return d.gear_ratio * d.efficiency * d.kt * d.supply_voltage / d.resistance


def urdf_texts(description, path) -> tuple[str, str]:
    """(URDF text, side YAML text) of ``description`` for a URDF written to ``path``."""
    g_world = gravity_alignment(description.gravity) @ np.asarray(description.gravity, float)
    side_text = (
        "# guardid side file of "
        + Path(path).name
        + ": what URDF has no field for (docs/URDF.md)\n"
        + yaml.safe_dump(side_dict(description, g_world), sort_keys=False)
    )
    return urdf_text(description), side_text


def write_urdf(description, path) -> tuple[Path, Path]:
    """Write ``path`` (URDF) and its side YAML beside it; returns both paths."""
    path = Path(path)
    side = side_path(path)
    text, side_text = urdf_texts(description, path)
    path.write_text(text, encoding="utf-8")
    side.write_text(side_text, encoding="utf-8")
    return path, side
