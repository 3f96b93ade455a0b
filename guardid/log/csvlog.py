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

import errno
import io
import os
import time
from pathlib import Path

import yaml

from guardid.errors import GuardidError

LOG_VERSION = 1
LOG_VERSION_KEY = "guardid-log"  #: the header key holding the format version
KNOWN_LOG_VERSIONS = (1,)  #: format versions :func:`guardid.log.read_log` reads
PER_JOINT = (
    ("counts", "raw encoder counts at the tick"),
    ("q", "joint angle at the tick [rad]"),
    ("v", "motor voltage, mean over the period ending at the tick [V]"),
    ("i", "motor current, mean over the period ending at the tick [A]"),
    ("sp", "setpoint in force at the tick [rad]"),
)


_UNIT_SUFFIX = {"q": "_rad", "v": "_V", "i": "_A", "sp": "_rad"}


def per_joint_column(key: str, joint: str) -> str:
    """The column of ``joint`` in group ``key`` (counts, q, v, i or sp), e.g. q_pan_rad."""
    return f"{key}_{joint}{_UNIT_SUFFIX.get(key, '')}"


def column_names(joint_names) -> list[str]:
    """Column names for the given joints, in file order."""
    cols = ["tick", "time_s"]
    for key, _ in PER_JOINT:
        cols += [per_joint_column(key, name) for name in joint_names]
    return cols + ["status"]


def format_row(tick: int, time_s: float, counts, q, v, i, sp, status: int) -> str:
    """One data line, ``\\n`` included: per-joint sequences in joint order, SI units, each
    column with fixed decimals (time 6, angles 9, volts and amperes 3, integers none), the
    fixed-point format :mod:`guardid.log.numeric` reads fastest."""
    buf = io.StringIO()
    buf.write(f"{tick},{time_s:.6f}")
    buf.write("".join(f",{int(c)}" for c in counts))
    for seq, fmt in ((q, ".9f"), (v, ".3f"), (i, ".3f"), (sp, ".9f")):
        buf.write("".join(f",{x:{fmt}}" for x in seq))
    buf.write(f",{int(status)}\n")
    return buf.getvalue()


def _comment(text: str) -> str:
    return "".join(f"# {line}\n" for line in text.rstrip("\n").splitlines())


class LogWriteError(GuardidError):
    """A log cannot be written (exists, no permission, disk full); the rows already
    written are kept."""


SYNC_INTERVAL_S = 1.0
"""Longest wall-clock time [s] between two fsyncs of a log (power loss loses at most this)."""

_NO_SYNC = (errno.EINVAL, errno.EROFS, errno.ENOTSUP)  # fsync on a pipe or a device


class LogWriter:
    """Write a log incrementally, one ``os.write`` per row.

    Each row reaches the kernel as soon as it is written, so a killed process (even
    SIGKILL) leaves every completed row in the file; ``fsync`` runs at most every
    ``sync_interval_s`` [s] (power loss), and for the header and footer. ``overwrite``
    False refuses an existing ``path`` (exclusive create). A failed write raises
    :class:`LogWriteError`; the file is then cut back to its last complete line, so a
    footer can still follow the rows kept.
    """

    def __init__(
        self,
        path,
        joint_names,
        header: dict,
        overwrite: bool = False,
        sync_interval_s: float = SYNC_INTERVAL_S,
    ) -> None:
        self.path = Path(path)
        self.joint_names = list(joint_names)
        self.columns = column_names(self.joint_names)
        self.rows = 0
        self.sync_interval_s = sync_interval_s
        self._good = 0  # bytes of complete lines in the file
        self._synced_at = time.monotonic()
        flags = os.O_WRONLY | os.O_CREAT | (os.O_TRUNC if overwrite else os.O_EXCL)
        try:
            self._fd: int | None = os.open(self.path, flags, 0o666)
        except FileExistsError:
            raise LogWriteError(
                f"{self.path}: already exists; a recorded log is never replaced "
                "(choose another name, or --force)"
            ) from None
        except OSError as exc:
            raise LogWriteError(f"{self.path}: cannot write: {exc.strerror}") from None
        head = {LOG_VERSION_KEY: LOG_VERSION, **header, "columns": self.columns}
        text = ",".join(self.columns) + "\n"
        text += _comment(yaml.safe_dump(head, sort_keys=False, width=1000))
        try:
            self._append(text, "the header")
            self._sync(force=True)
        except LogWriteError:
            self._close_fd()
            raise

    @property
    def closed(self) -> bool:
        """True once :meth:`close` ran or a write failed beyond repair."""
        return self._fd is None

    def write_row(self, tick: int, time_s: float, counts, q, v, i, sp, status: int) -> None:
        """Append one row: per-joint sequences in joint order, SI units."""
        self._append(format_row(tick, time_s, counts, q, v, i, sp, status), f"row {self.rows + 1}")
        self.rows += 1
        self._sync(force=False)

    def close(self, footer: dict) -> None:
        """Write the footer, fsync and close (safe to call twice; closes even on error)."""
        if self._fd is None:
            return
        body = {"footer": {"rows": self.rows, **footer}}
        text = yaml.safe_dump(body, sort_keys=False, width=1000)
        try:
            self._append(_comment(text), "the footer")
            self._sync(force=True)
        finally:
            self._close_fd()

    # ------------------------------------------------------------------ bytes
    def _append(self, text: str, what: str) -> None:
        raw = text.encode("utf-8")
        data = memoryview(raw)
        if self._fd is None:
            raise LogWriteError(f"{self.path}: cannot write {what}: the log is closed")
        try:
            while data:
                data = data[self._write(self._fd, data) :]
        except OSError as exc:
            self._cut_to_last_line()
            raise LogWriteError(
                f"{self.path}: cannot write {what}: {exc.strerror or exc}; {self.rows} rows kept"
            ) from None
        self._good += len(raw)

    @staticmethod
    def _write(fd: int, data) -> int:
        """The one place bytes leave the writer (tests inject disk faults here)."""
        return os.write(fd, data)

    def _cut_to_last_line(self) -> None:
        """Drop a partly written line so the file ends with complete lines."""
        try:
            os.ftruncate(self._fd, self._good)
            os.lseek(self._fd, self._good, os.SEEK_SET)
        except OSError:
            pass  # a device (e.g. /dev/full) or a pipe: nothing to cut

    def _sync(self, force: bool) -> None:
        now = time.monotonic()
        if not force and now - self._synced_at < self.sync_interval_s:
            return
        self._synced_at = now
        try:
            os.fsync(self._fd)
        except OSError as exc:
            if exc.errno not in _NO_SYNC:
                raise LogWriteError(
                    f"{self.path}: cannot sync to disk: {exc.strerror}; {self.rows} rows written"
                ) from None

    def _close_fd(self) -> None:
        fd, self._fd = self._fd, None
        if fd is not None:
            try:
                os.close(fd)
            except OSError:
                pass
