"""Payload on the last link: a point mass (optionally with its own inertia) from a time on."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class PayloadChange:
    """From ``time`` [s] on, the last link carries ``mass`` [kg] at ``com`` [m].

    ``com`` is in the last link's standard-DH frame; ``inertia`` (3, 3) [kg m^2] is the
    payload's own inertia about its centre of mass (default: point mass). Each change
    replaces the previous payload (mass 0 removes it); q and qd are continuous across it.
    """

    time: float
    mass: float
    com: tuple[float, float, float] = (0.0, 0.0, 0.0)
    inertia: tuple | None = None


def payload_params(params: np.ndarray, names: list[str], n_links: int, change) -> np.ndarray:
    """Standard parameters ``params`` with the payload added to link ``n_links``."""
    c = np.asarray(change.com, dtype=float)
    m = float(change.mass)
    i_c = np.zeros((3, 3)) if change.inertia is None else np.asarray(change.inertia, float)
    i_o = i_c + m * (np.dot(c, c) * np.eye(3) - np.outer(c, c))
    delta = {
        "XX": i_o[0, 0], "XY": i_o[0, 1], "XZ": i_o[0, 2], "YY": i_o[1, 1], "YZ": i_o[1, 2],
        "ZZ": i_o[2, 2], "MX": m * c[0], "MY": m * c[1], "MZ": m * c[2], "M": m,
    }  # fmt: skip
    out = np.array(params, dtype=float)
    for key, value in delta.items():
        out[names.index(f"{key}{n_links}")] += value
    return out


def base_values(description, change=None) -> dict[str, float]:
    """The robot's base parameters {name: value} [SI], with ``change``'s payload if given
    (the truth an online estimator tracking that payload should reach)."""
    from guardid.dynamics import build_model

    model = build_model(description)
    params = model.params
    if change is not None:
        params = payload_params(params, list(model.param_names), len(description.links), change)
    return dict(zip(model.base.names, model.base.values(params), strict=True))
