"""A robot description carrying a set of standard parameters (the identified robot)."""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from guardid.robot.description import ChainDescription, Friction


def description_with(description: ChainDescription, names, values) -> ChainDescription:
    """``description`` with its links, rotor inertias and friction set to standard parameters.

    ``names`` / ``values`` (p,) as :class:`guardid.dynamics.ChainModel`'s param_names [SI];
    a link's mass must be > 0. Rotor: a drive's ``rotor_inertia`` (motor side) becomes
    Ia / N^2, a mechanical rotor's ``inertia`` likewise. Returns a new description.
    """
    v = dict(zip(names, np.asarray(values, dtype=float), strict=True))
    links = []
    for k, link in enumerate(description.links):
        xx, xy, xz, yy, yz, zz, mx, my, mz, m = (
            v[f"{s}{k + 1}"] for s in ("XX", "XY", "XZ", "YY", "YZ", "ZZ", "MX", "MY", "MZ", "M")
        )
        c = np.array([mx, my, mz]) / m
        i_o = np.array([[xx, xy, xz], [xy, yy, yz], [xz, yz, zz]])
        i_c = i_o - m * (np.dot(c, c) * np.eye(3) - np.outer(c, c))
        links.append(replace(link, mass=float(m), com=c, inertia=0.5 * (i_c + i_c.T)))
    joints = []
    for j, joint in enumerate(description.joints):
        ia = v.get(f"Ia{j + 1}")
        if ia is not None and joint.drive is not None:
            joint = replace(
                joint, drive=replace(joint.drive, rotor_inertia=ia / joint.drive.gear_ratio**2)
            )
        elif ia is not None and joint.rotor is not None:
            joint = replace(
                joint, rotor=replace(joint.rotor, inertia=ia / joint.rotor.gear_ratio**2)
            )
        if joint.friction is not None:
            fr = joint.friction
            joint = replace(
                joint,
                friction=Friction(
                    v[f"Fv{j + 1}"],
                    v[f"Fc{j + 1}"],
                    v[f"Fo{j + 1}"] if fr.offset_modelled else 0.0,
                    offset_modelled=fr.offset_modelled,
                ),
            )
        joints.append(joint)
    return replace(description, links=tuple(links), joints=tuple(joints))
