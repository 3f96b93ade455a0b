"""Write a serial-chain robot description as MuJoCo MJCF (docs/URDF.md).

Nested bodies in the proximal frames of :mod:`guardid.export.frames` (worldbody = the
description's DH frame 0, ``<option gravity>`` = its gravity vector); per joint ``axis 0 0 1``,
``armature`` = the reflected rotor inertia N^2 J (diagonal of M; a coupled rotor's off-
diagonal terms have no MJCF field and are left out, said in a comment), ``damping`` = Fv,
``frictionloss`` = Fc (a friction offset has no MJCF field: comment), ``range`` from the
position limits. Inertia: ``fullinertia`` about the COM in the body frame.
"""

from __future__ import annotations

import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np

from guardid.export.frames import joint_origins, link_inertial


def _num(x: float) -> str:
    return repr(float(x))


def _vec(v) -> str:
    return " ".join(_num(x) for x in v)


def _quat(rot: np.ndarray) -> np.ndarray:
    """Unit quaternion (w, x, y, z) of a rotation matrix (3, 3)."""
    m = rot
    w = np.sqrt(max(0.0, 1.0 + m[0, 0] + m[1, 1] + m[2, 2])) / 2.0
    x = np.sqrt(max(0.0, 1.0 + m[0, 0] - m[1, 1] - m[2, 2])) / 2.0
    y = np.sqrt(max(0.0, 1.0 - m[0, 0] + m[1, 1] - m[2, 2])) / 2.0
    z = np.sqrt(max(0.0, 1.0 - m[0, 0] - m[1, 1] + m[2, 2])) / 2.0
    x = np.copysign(x, m[2, 1] - m[1, 2])
    y = np.copysign(y, m[0, 2] - m[2, 0])
    z = np.copysign(z, m[1, 0] - m[0, 1])
    return np.array([w, x, y, z])


def mjcf_text(description) -> str:
    """The MJCF document (str) of a serial-chain description (module docstring)."""
    root = ET.Element("mujoco", model=description.name)
    ET.SubElement(root, "compiler", angle="radian", autolimits="true")
    ET.SubElement(root, "option", gravity=_vec(description.gravity))
    parent = ET.SubElement(root, "worldbody")
    for k, (joint, tf) in enumerate(
        zip(description.joints, joint_origins(description), strict=True)
    ):
        link = description.links[k]
        body = ET.SubElement(
            parent, "body", name=link.name, pos=_vec(tf[:3, 3]), quat=_vec(_quat(tf[:3, :3]))
        )
        mass, com, inertia = link_inertial(description, k)
        ET.SubElement(
            body,
            "inertial",
            pos=_vec(com),
            mass=_num(mass),
            fullinertia=_vec(
                [
                    inertia[0, 0],
                    inertia[1, 1],
                    inertia[2, 2],
                    inertia[0, 1],
                    inertia[0, 2],
                    inertia[1, 2],
                ]
            ),
        )
        attrs = {"name": joint.name, "type": "hinge" if joint.type == "revolute" else "slide"}
        attrs["axis"] = "0 0 1"
        if joint.limits.position is not None:
            attrs["range"] = _vec(joint.limits.position)
        if joint.reflected_inertia:
            attrs["armature"] = _num(joint.reflected_inertia)
        if joint.friction is not None:
            attrs["damping"] = _num(joint.friction.viscous)
            attrs["frictionloss"] = _num(joint.friction.coulomb)
        ET.SubElement(body, "joint", **attrs)
        if joint.rotor is not None and joint.rotor.coupling != 0:
            body.append(
                ET.Comment(
                    f" rotor of {joint.name} coupled to the previous link: "
                    "only its diagonal N^2 J is in armature "
                )
            )
        if joint.friction is not None and joint.friction.offset != 0.0:
            body.append(
                ET.Comment(
                    f" friction offset {_num(joint.friction.offset)} N m of {joint.name}: "
                    "no MJCF field (see the side YAML) "
                )
            )
        parent = body
    act = ET.SubElement(root, "actuator")
    for joint in description.joints:
        ET.SubElement(act, "motor", name=f"{joint.name}_torque", joint=joint.name)
    ET.indent(root)
    return ET.tostring(root, encoding="unicode") + "\n"


def write_mjcf(description, path) -> Path:
    """Write the MJCF file ``path``; returns it."""
    path = Path(path)
    path.write_text(mjcf_text(description), encoding="utf-8")
    return path
