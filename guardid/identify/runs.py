"""Read a run for identification: a guardid log, turned into arrays in SI units."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from guardid.errors import LogFormatError
from guardid.log import read_log


@dataclass
class Run:
    """One run: ticks (N,), t [s] (N,), q [rad], current [A], voltage [V] (N, n) or None."""

    path: str
    robot: str | None
    ticks: np.ndarray | None
    t: np.ndarray
    q: np.ndarray
    current: np.ndarray
    voltage: np.ndarray | None


def load_run(path, sample_period_s: float | None = None) -> Run:
    """Load a guardid capture log. Time comes from the tick column and the sample period."""
    data = read_log(path)
    for col in ("tick",):
        if col not in data.columns:
            raise LogFormatError(f"{path}: column {col!r} missing")
    ticks = data.columns["tick"].astype(np.int64)
    if len(ticks) < 10:
        raise LogFormatError(f"{path}: only {len(ticks)} rows")
    period = sample_period_s or float(data.header.get("sample_period_s", 0.015))
    q = data.joint_array("q")
    current = data.joint_array("i")
    voltage = data.joint_array("v")
    if q.shape[1] == 0 or current.shape != q.shape:
        raise LogFormatError(f"{path}: expected q_* and i_* columns for every joint")
    return Run(
        path=str(path),
        robot=data.header.get("robot_source") or data.header.get("robot"),
        ticks=ticks,
        t=(ticks - ticks[0]) * period,
        q=q,
        current=current,
        voltage=voltage if voltage.shape == q.shape else None,
    )
