"""``guardid convert LOG --mcap OUT``: a log as an MCAP file that Foxglove and PlotJuggler
open.

One channel, :data:`TOPIC`, JSON-encoded with a JSON Schema: one message per log row, the
row's object of :mod:`guardid.live.rows` (the same as ``capture --stream`` sends). A
message's log time is the capture's ``start_time`` (header; 0 when the log has none) plus
the row's ``time_s``, in nanoseconds. The log's header and footer are MCAP metadata
records :data:`HEADER_METADATA` and :data:`FOOTER_METADATA`, each top-level key's value as
JSON text (MCAP metadata values are strings).

Needs the ``mcap`` package (``pip install 'guardid[mcap]'``): :func:`require_mcap`.
"""

from __future__ import annotations

import datetime as _dt
import json

import numpy as np

from guardid.errors import ConfigError
from guardid.live.rows import RowLayout, integer_kind
from guardid.log import LogData

TOPIC = "/guardid/joints"
"""The channel of the log's rows."""
SCHEMA_NAME = "guardid.LogRow"
HEADER_METADATA = "guardid.header"
FOOTER_METADATA = "guardid.footer"
EXTRA = "pip install 'guardid[mcap]'"


def require_mcap(option: str = "--mcap") -> None:
    """ConfigError naming ``option`` and the extra when the ``mcap`` package is missing."""
    try:
        import mcap.writer  # noqa: F401
    except ImportError:
        raise ConfigError(f"{option}: needs the mcap package, not installed: {EXTRA}") from None


def start_time_ns(header: dict) -> int:
    """The header's ``start_time`` (ISO 8601; UTC when it names no zone) since the Unix
    epoch [ns]; 0 when the header has none or it is not a time."""
    value = header.get("start_time")
    if isinstance(value, str):
        try:
            value = _dt.datetime.fromisoformat(value)
        except ValueError:
            return 0
    if not isinstance(value, _dt.datetime):
        return 0
    if value.tzinfo is None:
        value = value.replace(tzinfo=_dt.timezone.utc)
    since = value - _dt.datetime(1970, 1, 1, tzinfo=_dt.timezone.utc)
    return since // _dt.timedelta(microseconds=1) * 1000


def metadata(record: dict) -> dict[str, str]:
    """An MCAP metadata map of ``record``: each key's value as JSON text."""
    return {str(k): json.dumps(v, default=str) for k, v in record.items()}


def write_mcap(log: LogData, path) -> int:
    """Write ``log`` to the MCAP file ``path``; return the number of messages (rows).
    A log without a ``time_s`` column is a :class:`ConfigError` (its rows have no time)."""
    from mcap.writer import Writer

    if "time_s" not in log.columns:
        raise ConfigError(
            f"{log.path}: no time_s column (a guardid log's time [s]): convert writes guardid "
            "logs; a foreign log's rows have no time for MCAP"
        )

    columns = list(log.columns)
    integer = [c for c in integer_kind(columns) if _integral(log.columns[c])]
    layout = RowLayout.for_columns(columns, log.joint_names, integer)
    schema = json.dumps(layout.json_schema()).encode()
    times = _log_times_ns(log)
    rows = zip(*(log.columns[c].tolist() for c in columns), strict=True)
    with open(path, "wb") as fh:
        writer = Writer(fh)
        writer.start(profile="", library="guardid")
        schema_id = writer.register_schema(SCHEMA_NAME, "jsonschema", schema)
        channel = writer.register_channel(TOPIC, "json", schema_id)
        writer.add_metadata(HEADER_METADATA, metadata(log.header))
        if log.footer is not None:
            writer.add_metadata(FOOTER_METADATA, metadata(log.footer))
        for k, (row, t_ns) in enumerate(zip(rows, times, strict=True)):
            data = json.dumps(layout.message(row), separators=(",", ":")).encode()
            writer.add_message(channel, log_time=t_ns, data=data, publish_time=t_ns, sequence=k)
        writer.finish()
    return len(times)


def _log_times_ns(log: LogData) -> list[int]:
    """Each row's log time: the header's start_time plus the row's time_s [ns]."""
    t_s = log.columns["time_s"]
    return (start_time_ns(log.header) + np.rint(t_s * 1e9).astype(np.int64)).tolist()


def _integral(x: np.ndarray) -> bool:
    return bool(np.all(np.isfinite(x) & (x == np.rint(x))))
