"""Read a capture log in one pass: column names, YAML header, data rows, YAML footer.

The file is read once, in blocks of :data:`BLOCK_BYTES`; each block of complete data lines
is parsed by :mod:`guardid.log.numeric` (compiled loops) into one preallocated float64
array, so memory follows the rows kept, not the text. Every problem is a one-line
:class:`~guardid.errors.LogFormatError` naming the file and the line (and column): binary
or gzip-compressed data, a field that is not a number, NaN or inf, a line with another field
count, data after the footer, ticks that do not increase (two logs appended). A last row
cut mid-line (a killed writer) is dropped with a :class:`~guardid.errors.LogWarning`.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import yaml

from guardid.errors import LogFormatError, LogWarning
from guardid.log.numeric import RowError, parse_lines, parse_plain

BLOCK_BYTES = 1 << 18  #: bytes read and parsed at a time (256 kB: the work arrays stay in cache)
_GZIP_MAGIC = b"\x1f\x8b"
_YAML_LOADER = getattr(yaml, "CSafeLoader", yaml.SafeLoader)  # libyaml when built with it


@dataclass
class LogData:
    """A log read back: header and footer dicts, columns by name (numpy arrays).

    ``tick`` is int64; every other column float64. ``footer`` is None when the writer was
    killed; ``warnings`` lists what was tolerated (a cut last row).
    """

    path: Path
    header: dict
    footer: dict | None
    columns: dict[str, np.ndarray] = field(default_factory=dict)
    warnings: list[str] = field(default_factory=list)

    @property
    def joint_names(self) -> list[str]:
        return [c[len("counts_") :] for c in self.columns if c.startswith("counts_")]

    def joint_array(self, key: str) -> np.ndarray:
        """(N, n) array of a per-joint column group: counts, q, v, i or sp."""
        names = [c for c in self.columns if c.startswith(key + "_")]
        return np.column_stack([self.columns[c] for c in names])


def read_log(path) -> LogData:
    """Read a guardid log; raise :class:`LogFormatError` naming the file and line."""
    path = Path(path)
    try:
        f = open(path, "rb")  # noqa: SIM115 -- closed below
    except OSError as exc:
        raise LogFormatError(f"{path}: cannot read: {exc.strerror}") from None
    try:
        with f:
            return _Reader(path, f).read()
    except RowError as exc:
        raise LogFormatError(f"{path}: {exc}") from None
    except OSError as exc:
        raise LogFormatError(f"{path}: cannot read: {exc.strerror}") from None


class _Rows:
    """A growing (ncols, capacity) float64 store, sized from the first block's bytes per row
    and the file's size; ``line_of(row)`` gives a row's line number."""

    def __init__(self, ncols: int, file_bytes: int) -> None:
        self.data = np.empty((ncols, 0))
        self.n = 0
        self.file_bytes = file_bytes
        self._segments: list[tuple[int, int | np.ndarray]] = []  # (first row, line(s))

    def add(self, rows: np.ndarray, lines: int | np.ndarray, nbytes: int) -> None:
        """Append ``rows`` (m, ncols) parsed from ``nbytes`` of text; ``lines``: the first
        row's line number when the rows are consecutive lines, else each row's."""
        m = len(rows)
        if self.n + m > self.data.shape[1]:
            if self.n == 0:  # rows in the file, from this block's bytes per row, +2 %
                want = int(m * self.file_bytes / max(nbytes, 1) * 1.02) + 16
            else:
                want = self.data.shape[1] * 5 // 4
            grown = np.empty((self.data.shape[0], max(self.n + m, want)))
            grown[:, : self.n] = self.data[:, : self.n]
            self.data = grown
        self.data[:, self.n : self.n + m] = rows.T
        self._segments.append((self.n, lines))
        self.n += m

    def line_of(self, row: int) -> int:
        for first, lines in reversed(self._segments):
            if row >= first:
                return lines + row - first if isinstance(lines, int) else int(lines[row - first])
        return 0


class _Reader:
    def __init__(self, path: Path, f) -> None:
        self.path, self.f = path, f
        self.line = 0  # number of the last line consumed
        self.warnings: list[str] = []

    def _text(self, raw: bytes, no: int) -> str:
        if b"\x00" in raw:
            raise RowError(no, "binary data (not a text log)")
        try:
            return raw.decode("utf-8")
        except UnicodeDecodeError:
            raise RowError(no, "binary data (not a text log)") from None

    def read(self) -> LogData:
        path, f = self.path, self.f
        first = f.readline()
        self.line = 1
        if first.startswith(_GZIP_MAGIC):
            raise LogFormatError(f"{path}: gzip-compressed: decompress it first (gunzip)")
        names_text = self._text(first, 1).strip()
        if not names_text or names_text.startswith("#"):
            raise LogFormatError(f"{path}: line 1: expected the column names")
        names = [n.strip() for n in names_text.split(",")]
        head, pending = [], b""
        for raw in iter(f.readline, b""):
            self.line += 1
            if raw.startswith(b"#"):
                head.append(self._text(raw, self.line).rstrip("\r\n")[2:])
            elif raw.strip():
                pending = raw
                self.line -= 1  # re-read as the first data line
                break
        header = _yaml(path, head, "header")
        store = _Rows(len(names), path.stat().st_size)
        foot = self._body(names, pending, store)
        footer = _yaml(path, foot, "footer").get("footer") if foot is not None else None
        columns = {name: store.data[c, : store.n] for c, name in enumerate(names)}
        if "tick" in columns:
            columns["tick"] = self._ticks(columns["tick"], store)
        return LogData(path, header, footer, columns, self.warnings)

    def _body(self, names: list[str], buf: bytes, store: _Rows) -> list[str] | None:
        """Parse data lines into ``store``; return the footer's lines (None: no footer)."""
        ncols = len(names)
        while True:
            more = self.f.read(BLOCK_BYTES)
            buf += more
            cut = buf.rfind(b"\n") + 1
            if more and self._parse_plain(buf[:cut], ncols, store):
                buf = buf[cut:]
                continue
            start = _comment_start(buf)
            if start is not None:
                self._parse(buf[:start], names, store)
                return self._footer(buf[start:])
            if more:
                self._parse(buf[:cut], names, store)
                buf = buf[cut:]
                continue
            tail = buf[cut:]
            last_start = buf.rfind(b"\n", 0, max(cut - 1, 0)) + 1
            last = buf[last_start:cut]
            if tail.strip():  # the writer never leaves a line without its '\n'
                self._parse(buf[:cut], names, store)
                self._cut(self.line + 1)
            elif last.strip() and last.count(b",") != ncols - 1:
                self._parse(buf[:last_start], names, store)  # partial last line
                self._cut(self.line + 1)
            else:
                self._parse(buf, names, store)
            return None

    def _parse_plain(self, block: bytes, ncols: int, store: _Rows) -> bool:
        """Parse ``block`` on the fast path; False (nothing consumed) when it cannot."""
        rows = parse_plain(block, ncols)
        if rows is None:
            return False
        store.add(rows, self.line + 1, len(block))
        self.line += len(rows)
        return True

    def _cut(self, no: int) -> None:
        msg = f"{self.path}: line {no}: last row incomplete, ignored (the writer was stopped)"
        self.warnings.append(msg)
        warnings.warn(msg, LogWarning, stacklevel=4)

    def _parse(self, block: bytes, names: list[str], store: _Rows) -> None:
        """Parse complete data lines ``block`` following line ``self.line``."""
        if not block:
            return
        first = self.line + 1
        if self._parse_plain(block, len(names), store):
            return
        lines = block.split(b"\n")
        if not lines[-1]:
            lines.pop()  # the text after the block's last '\n'
        names_line = ",".join(names)
        for k, line in enumerate(lines):
            if line.decode("latin-1").strip() == names_line:
                raise RowError(
                    first + k, "a second log's column names (two logs appended? split them)"
                )
        rows = parse_lines(lines, first, names)
        numbers = [first + k for k, line in enumerate(lines) if line.strip()]
        store.add(rows, np.asarray(numbers), len(block))
        self.line += len(lines)

    def _footer(self, rest: bytes) -> list[str]:
        """The footer's comment lines; data after them is an error."""
        rest += self.f.read()
        out = []
        for raw in rest.splitlines():
            self.line += 1
            if raw.startswith(b"#"):
                out.append(self._text(raw, self.line)[2:])
            elif raw.strip():
                raise RowError(self.line, "data after the footer")
        return out

    def _ticks(self, tick: np.ndarray, store: _Rows) -> np.ndarray:
        """The tick column as int64; it must increase row by row."""
        ticks = tick.astype(np.int64)
        off = np.flatnonzero(ticks != tick)
        if off.size:
            r = int(off[0])
            raise RowError(store.line_of(r), f"tick {tick[r]!r} is not an integer")
        back = np.flatnonzero(np.diff(ticks) <= 0)
        if back.size:
            r = int(back[0]) + 1
            raise RowError(
                store.line_of(r),
                f"tick {ticks[r]} after {ticks[r - 1]}: the ticks restart (two logs "
                "appended? split them and give each to the command)",
            )
        return ticks


def _comment_start(buf: bytes) -> int | None:
    """Offset of the first line starting with '#' in ``buf``, or None."""
    if buf.startswith(b"#"):
        return 0
    k = buf.find(b"\n#")
    return None if k < 0 else k + 1


def _yaml(path: Path, lines: list[str], what: str) -> dict:
    try:
        value = yaml.load("\n".join(lines), Loader=_YAML_LOADER) if lines else {}
    except yaml.YAMLError as exc:
        raise LogFormatError(f"{path}: {what}: invalid YAML: {str(exc).splitlines()[0]}") from None
    if not isinstance(value, dict):
        raise LogFormatError(f"{path}: {what}: expected a mapping")
    return value
