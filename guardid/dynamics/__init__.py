"""Dynamics models: serial chains (ChainModel), seed 000's flexible link, seed 001's planar arm.

Every model offers n_dof, joint_names, param_names, params, regressor, inverse_dynamics,
mass_matrix, bias, forward_dynamics, base, base_regressor, known_torque, mass_matrix_1, bias_1
(docs/CONTRACTS.md).
"""

from __future__ import annotations

from guardid.dynamics.base import BaseParameters
from guardid.dynamics.chain import ChainModel
from guardid.dynamics.flexlink import FlexibleLinkModel
from guardid.dynamics.planar import PlanarPaperModel
from guardid.robot.description import ChainDescription, FlexibleLinkDescription


def build_model(description) -> ChainModel | FlexibleLinkModel:
    """Model for a description from guardid.robot.load_robot (or a shipped name / path)."""
    if isinstance(description, str):
        from guardid.robot import load_robot

        description = load_robot(description)
    if isinstance(description, FlexibleLinkDescription):
        return FlexibleLinkModel(description)
    if isinstance(description, ChainDescription):
        return ChainModel(description)
    raise TypeError(f"not a robot description: {type(description).__name__}")


__all__ = ["BaseParameters", "ChainModel", "FlexibleLinkModel", "PlanarPaperModel", "build_model"]
