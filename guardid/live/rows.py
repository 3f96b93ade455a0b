"""One log row as one JSON object, the same for the UDP stream and the MCAP file.

The row's time is ``timestamp`` [s] (the log's ``time_s``; PlotJuggler's JSON parser takes
a top-level numeric field of that name as the sample's time, in seconds); per-joint
columns become one object per joint, so that PlotJuggler's and Foxglove's trees show one
branch per joint::

    {"tick": 1234, "timestamp": 0.015,
     "pan":  {"counts": 12, "q_rad": 0.0188, "v_V": 1.2, "i_A": 0.05, "setpoint_rad": 0.02},
     "tilt": {...}, "status": 0}

Other columns (``tick``, ``status``, any a foreign log has) stay at the top level under
their column names.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from dataclasses import dataclass

from guardid.log.csvlog import PER_JOINT, per_joint_column

TIME_FIELD = "timestamp"
"""The field holding the row's time [s] (PlotJuggler's 'use field as timestamp')."""

JOINT_FIELDS = {"counts": "counts", "q": "q_rad", "v": "v_V", "i": "i_A", "sp": "setpoint_rad"}
"""A per-joint column group's field name inside the joint's object, units in the name."""

_DESCRIPTIONS = dict(PER_JOINT)
_INTEGER_KINDS = ("tick", "counts", "status")


@dataclass(frozen=True)
class RowLayout:
    """Where each log column goes in a row's JSON object.

    ``columns``: the log's column names in file order; ``paths``: for each, ``(name,)`` at
    the top level or ``(joint, field)`` inside the joint's object; ``integer``: whether
    the column's values are written as JSON integers (else as numbers)."""

    columns: tuple[str, ...]
    paths: tuple[tuple[str, ...], ...]
    integer: tuple[bool, ...]

    @classmethod
    def for_columns(
        cls,
        columns: Sequence[str],
        joint_names: Iterable[str],
        integer: Iterable[str] | None = None,
    ) -> RowLayout:
        """The layout of a log with ``columns`` and joints ``joint_names``; the columns in
        ``integer`` (default: tick, counts_* and status) are written as integers."""
        joints = list(joint_names)
        where = {per_joint_column(k, j): (j, JOINT_FIELDS[k]) for k in JOINT_FIELDS for j in joints}
        paths = []
        for c in columns:
            if c == "time_s":
                paths.append((TIME_FIELD,))
            else:
                paths.append(where.get(c, (c,)))
        if integer is None:
            integer = integer_kind(columns)
        integer = set(integer)
        return cls(tuple(columns), tuple(paths), tuple(c in integer for c in columns))

    def message(self, values: Sequence) -> dict:
        """The JSON object of one row, ``values`` in :attr:`columns` order."""
        out: dict = {}
        for path, is_int, v in zip(self.paths, self.integer, values, strict=True):
            x = int(v) if is_int else float(v)
            if len(path) == 1:
                out[path[0]] = x
            else:
                out.setdefault(path[0], {})[path[1]] = x
        return out

    def json_schema(self, title: str = "guardid log row") -> dict:
        """A JSON Schema (draft 2020-12) of :meth:`message`'s objects, units in the
        descriptions."""
        props: dict = {}
        for column, path, is_int in zip(self.columns, self.paths, self.integer, strict=True):
            leaf = {"type": "integer" if is_int else "number", "description": _describe(column)}
            if len(path) == 1:
                props[path[0]] = leaf
            else:
                joint = props.setdefault(
                    path[0], {"type": "object", "description": f"joint {path[0]}",
                              "properties": {}}
                )  # fmt: skip
                joint["properties"][path[1]] = leaf
        return {
            "$schema": "https://json-schema.org/draft/2020-12/schema",
            "title": title,
            "type": "object",
            "properties": props,
        }


def integer_kind(columns: Iterable[str]) -> list[str]:
    """The columns guardid writes as integers: tick, counts_* and status."""
    return [c for c in columns if c.split("_")[0] in _INTEGER_KINDS]


def _describe(column: str) -> str:
    if column == "time_s":
        return "time since the first row [s] (log column time_s)"
    kind = column.split("_")[0]
    if kind in _DESCRIPTIONS and kind != column:
        return f"{_DESCRIPTIONS[kind]} (log column {column})"
    return f"log column {column}"
