"""Capture log files: one CSV row per telemetry frame, written and flushed as it arrives.

Layout (read by :func:`guardid.log.read_log`, and by ``numpy.genfromtxt(path,
delimiter=",", names=True, invalid_raise=False)``, which also skips a cut last row)::

    tick,time_s,counts_pan,...,status          <- line 1: column names
    # guardid-log: 1                           <- commented YAML header
    # robot: {...}  port: ...  info: {...}  trajectory: {...}  start_time: ...
    1234,0.0,0,...,0                           <- data rows, flushed one by one
    ...
    # footer:                                   <- commented YAML footer (link statistics)
    #   rows: 4000 ...

Lost ticks show as gaps in the tick column; no row is ever invented. A killed writer
leaves every completed row readable; the footer is then missing, which the reader reports.
"""

from __future__ import annotations

import io
import os
from pathlib import Path

import yaml

from guardid.errors import LogFormatError

LOG_VERSION = 1
PER_JOINT = (
    ("counts", "raw encoder counts at the tick"),
    ("q", "joint angle at the tick [rad]"),
    ("v", "motor voltage, mean over the period ending at the tick [V]"),
    ("i", "motor current, mean over the period ending at the tick [A]"),
    ("sp", "setpoint in force at the tick [rad]"),
)


def column_names(joint_names) -> list[str]:
    """Column names for the given joints, in file order."""
    cols = ["tick", "time_s"]
    for key, _ in PER_JOINT:
        unit = {"q": "_rad", "v": "_V", "i": "_A", "sp": "_rad"}.get(key, "")
        cols += [f"{key}_{name}{unit}" for name in joint_names]
    return cols + ["status"]


def _comment(text: str) -> str:
    return "".join(f"# {line}\n" for line in text.rstrip("\n").splitlines())


class LogWriter:
    """Write a log incrementally. Every row is flushed (and fsync'ed every ``sync_every``)."""

    def __init__(self, path, joint_names, header: dict, sync_every: int = 50) -> None:
        self.path = Path(path)
        self.joint_names = list(joint_names)
        self.columns = column_names(self.joint_names)
        self.rows = 0
        self.sync_every = sync_every
        try:
            self._f = open(self.path, "w", encoding="utf-8", newline="\n")  # noqa: SIM115
        except OSError as exc:
            raise LogFormatError(f"{self.path}: cannot write: {exc.strerror}") from None
        head = {"guardid-log": LOG_VERSION, **header, "columns": self.columns}
        self._f.write(",".join(self.columns) + "\n")
        self._f.write(_comment(yaml.safe_dump(head, sort_keys=False, width=1000)))
        self._flush(sync=True)

    def write_row(self, tick: int, time_s: float, counts, q, v, i, sp, status: int) -> None:
        """Append one row: per-joint sequences in joint order, SI units."""
        buf = io.StringIO()
        buf.write(f"{tick},{time_s:.6f}")
        buf.write("".join(f",{int(c)}" for c in counts))
        for seq, fmt in ((q, ".9f"), (v, ".3f"), (i, ".3f"), (sp, ".9f")):
            buf.write("".join(f",{x:{fmt}}" for x in seq))
        buf.write(f",{int(status)}\n")
        self._f.write(buf.getvalue())
        self.rows += 1
        self._flush(sync=self.rows % self.sync_every == 0)

    def close(self, footer: dict) -> None:
        """Write the footer and close (safe to call twice)."""
        if self._f.closed:
            return
        self._f.write(
            _comment(
                yaml.safe_dump(
                    {"footer": {"rows": self.rows, **footer}}, sort_keys=False, width=1000
                )
            )
        )
        self._flush(sync=True)
        self._f.close()

    def _flush(self, sync: bool) -> None:
        self._f.flush()
        if sync:
            os.fsync(self._f.fileno())
