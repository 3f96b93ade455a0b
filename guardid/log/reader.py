"""Read a capture log in one pass: column names, YAML header, data rows, YAML footer.

The file is read once, in blocks of :data:`BLOCK_BYTES`. The compiled reader
(:mod:`guardid.log.csvrows`, C built once on first use) parses each block's leading rows of
plain decimals straight into preallocated float64 arrays; the rows from the first one it
does not recognise (and every row on a machine without a C compiler) are parsed by
:mod:`guardid.log.numeric` (numpy's compiled loops) to the same values, bit for bit, or
named in an error. The arrays are one (rows, joints) array per per-joint column group
(``q_*``, ``i_*``, ...: what :meth:`LogData.joint_array` returns without a copy) and one per
other column, so memory follows the rows kept, not the text, and a group no one keeps is
freed on its own. Every problem is a one-line :class:`~guardid.errors.LogFormatError` naming
the file and the line (and column): binary or gzip-compressed data, a field that is not a
number, NaN or inf, a line with another field count, data after the footer, ticks that do
not increase (two logs appended or a repeated tick), a column name given twice, a header
naming a format version this reader does not know, fields separated by tabs or semicolons
(guardid logs are comma-separated). A last row cut mid-line (a killed writer) is dropped
with a :class:`~guardid.errors.LogWarning`, and so is a footer whose row count disagrees
with the rows read. A UTF-8 byte-order mark before the column names (an editor's) is
skipped.
"""

from __future__ import annotations

import logging
import warnings
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import yaml

from guardid.errors import LogFormatError, LogWarning
from guardid.log import csvrows
from guardid.log.csvlog import KNOWN_LOG_VERSIONS, LOG_VERSION_KEY, per_joint_column
from guardid.log.numeric import RowError, decimals_of, parse_block, parse_lines
from guardid.yaml_load import safe_load

BLOCK_BYTES = 1 << 18  #: bytes read and parsed at a time (256 kB: the work arrays stay in cache)
_GZIP_MAGIC = b"\x1f\x8b"
_BOM = b"\xef\xbb\xbf"  #: UTF-8 byte-order mark (some editors write it)
_OTHER_DELIMITERS = {"\t": "tabs", ";": "semicolons"}
_LOG = logging.getLogger("guardid.log")


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
    groups: dict[tuple[str, ...], np.ndarray] = field(default_factory=dict, repr=False)
    """(N, k) arrays of the per-joint column groups by their column names (file order): the
    columns are views of them."""

    @property
    def joint_names(self) -> list[str]:
        """The log's joints, in the order of its ``counts_<joint>`` columns."""
        return [c[len("counts_") :] for c in self.columns if c.startswith("counts_")]

    def has_group(self, key: str) -> bool:
        """Whether any per-joint column of group ``key`` (counts, q, v, i or sp) is present."""
        return any(c.startswith(key + "_") for c in self.columns)

    def joint_array(self, key: str, joints=None) -> np.ndarray:
        """(N, n) array of a per-joint column group (counts, q, v, i or sp), found by name
        (``q_<joint>_rad``, ...: :func:`~guardid.log.csvlog.per_joint_column`) in the order
        of ``joints`` (default :attr:`joint_names`); a missing column is a
        :class:`LogFormatError` naming it."""
        joints = self.joint_names if joints is None else list(joints)
        names = [per_joint_column(key, j) for j in joints]
        missing = [c for c in names if c not in self.columns]
        if missing:
            raise LogFormatError(
                f"{self.path}: column {missing[0]} missing (expected counts_*, q_*, i_* and, "
                f"if any, v_*, sp_* columns for every joint: {', '.join(joints)})"
            )
        if not names:
            return np.empty((len(self.columns.get("tick", ())), 0))
        whole = self.groups.get(tuple(names))
        if whole is not None:  # the group as stored, in this order: no copy
            return whole
        return np.column_stack([self.columns[c] for c in names])

    def check_joint_columns(self) -> None:
        """Every per-joint column must name one of the joints of the ``counts_*`` columns
        (a :class:`LogFormatError` naming the first that does not)."""
        known = {per_joint_column(k, j) for k in ("counts", "q", "v", "i", "sp")
                 for j in self.joint_names}  # fmt: skip
        for c in self.columns:
            if c.split("_")[0] in ("counts", "q", "v", "i", "sp") and c not in known:
                raise LogFormatError(
                    f"{self.path}: column {c}: no such joint among the log's counts_* "
                    f"columns ({', '.join(self.joint_names) or 'none'})"
                )


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


_JOINT_GROUPS = ("counts", "q", "v", "i", "sp")


class _Rows:
    """Growing float64 stores, one (capacity, k) array per column group (the columns of a
    per-joint group together, every other column alone), sized from the first block's
    bytes per row and the file's size; ``line_of(row)`` gives a row's line number."""

    def __init__(self, names: list[str], file_bytes: int) -> None:
        members: dict[tuple[str, str], list[int]] = {}
        for c, name in enumerate(names):
            key = name.split("_", 1)[0]
            group = ("group", key) if "_" in name and key in _JOINT_GROUPS else ("one", name)
            members.setdefault(group, []).append(c)
        self.names = names
        self.cols = [
            slice(c[0], c[-1] + 1) if c == list(range(c[0], c[-1] + 1)) else np.array(c)
            for c in members.values()
        ]
        self.members = list(members.values())
        self.blocks = [np.empty((0, len(c))) for c in self.members]
        self.n = 0
        self.file_bytes = file_bytes
        self._segments: list[tuple[int, int | np.ndarray]] = []  # (first row, line(s))
        self._bases: np.ndarray | None = None  # see targets()
        self._strides = np.zeros(0, dtype=np.int64)

    def add(self, rows: np.ndarray, lines: int | np.ndarray, nbytes: int) -> None:
        """Append ``rows`` (m, ncols) parsed from ``nbytes`` of text; ``lines``: the first
        row's line number when the rows are consecutive lines, else each row's."""
        m = len(rows)
        self.reserve(m, nbytes)
        for cols, block in zip(self.cols, self.blocks, strict=True):
            block[self.n : self.n + m] = rows[:, cols]
        self.commit(m, lines)

    def reserve(self, m: int, nbytes: int) -> None:
        """Room for ``m`` more rows (parsed from ``nbytes`` of text) in every store."""
        if self.n + m > self.blocks[0].shape[0]:
            if self.n == 0:  # rows in the file, from this block's bytes per row, +2 %
                want = int(m * self.file_bytes / max(nbytes, 1) * 1.02) + 16
            else:
                want = self.blocks[0].shape[0] * 5 // 4
            for g, old in enumerate(self.blocks):
                grown = np.empty((max(self.n + m, want), old.shape[1]))
                grown[: self.n] = old[: self.n]
                self.blocks[g] = grown
            self._bases = None

    def commit(self, m: int, lines: int | np.ndarray) -> None:
        """Count ``m`` rows written in place after the last (see :meth:`add`'s ``lines``)."""
        self._segments.append((self.n, lines))
        self.n += m

    def room(self) -> int:
        """Rows that fit in the stores after the :attr:`n` kept."""
        return self.blocks[0].shape[0] - self.n

    def targets(self) -> tuple[np.ndarray, np.ndarray]:
        """(address of row :attr:`n` of each column in file order, its row stride in
        float64s): where the compiled reader writes the next rows (after :meth:`reserve`)."""
        if self._bases is None:  # each column's row 0 (until a store grows)
            self._bases = np.zeros(len(self.names), dtype=np.uintp)
            self._strides = np.zeros(len(self.names), dtype=np.int64)
            for members, block in zip(self.members, self.blocks, strict=True):
                address, k = block.__array_interface__["data"][0], block.shape[1]
                for j, c in enumerate(members):
                    self._bases[c], self._strides[c] = address + 8 * j, k
        return self._bases + (8 * self.n) * self._strides.astype(np.uintp), self._strides

    def space(self, m: int, nbytes: int) -> np.ndarray:  # noqa: ARG002 (the parsers' signature)
        """A writable (m, ncols) buffer for the next ``m`` rows, which :meth:`add` then
        copies into the column groups' stores."""
        return np.empty((m, len(self.names)))

    def columns(self) -> dict[str, np.ndarray]:
        """Every column (a view of its group's store), in file order."""
        out = {}
        for members, block in zip(self.members, self.blocks, strict=True):
            for j, c in enumerate(members):
                out[c] = block[: self.n, j]
        return {self.names[c]: out[c] for c in sorted(out)}

    def groups(self) -> dict[tuple[str, ...], np.ndarray]:
        """The per-joint groups' (N, k) stores by their column names."""
        return {
            tuple(self.names[c] for c in members): block[: self.n]
            for members, block in zip(self.members, self.blocks, strict=True)
            if len(members) > 1 or self.names[members[0]].split("_", 1)[0] in _JOINT_GROUPS
        }

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
        self.decimals = None  # each column's decimals, from the first data row (fixed path)
        self.path_rows = {"compiled": 0, "fixed": 0, "plain": 0, "checked": 0}  # rows by path

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
        names = _column_names(path, self._text(first.removeprefix(_BOM), 1).strip())
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
        _check_version(path, header)
        store = _Rows(names, path.stat().st_size)
        self.decimals = decimals_of(pending, len(names))
        foot = self._body(names, pending, store)
        _LOG.debug("%s: %d rows; read by path: %s", path, store.n, self.path_rows)
        footer = _yaml(path, foot, "footer").get("footer") if foot is not None else None
        columns = store.columns()
        if "tick" in columns:
            columns["tick"] = self._ticks(columns["tick"], store)
        self._check_footer(footer, store.n)
        return LogData(path, header, footer, columns, self.warnings, store.groups())

    def _check_footer(self, footer, rows: int) -> None:
        """Warn when the footer's row count is not the number of data rows read."""
        claimed = footer.get("rows") if isinstance(footer, dict) else None
        if claimed is None or claimed == rows:
            return
        msg = (
            f"{self.path}: footer: rows: {claimed!r}, but the file holds {rows} data rows "
            "(rows removed or added after the capture?)"
        )
        self.warnings.append(msg)
        warnings.warn(msg, LogWarning, stacklevel=4)

    def _body(self, names: list[str], buf: bytes, store: _Rows) -> list[str] | None:
        """Parse data lines into ``store``; return the footer's lines (None: no footer)."""
        ncols = len(names)
        compiled = csvrows.library()
        while True:
            more = self.f.read(BLOCK_BYTES)
            buf += more
            if compiled is not None:
                buf = self._parse_compiled(compiled, buf, store)
            cut = buf.rfind(b"\n") + 1
            if more and (not cut or self._parse_plain(buf[:cut], ncols, store)):
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

    def _parse_compiled(self, fn, buf: bytes, store: _Rows) -> bytes:
        """Read the leading rows of ``buf`` that the compiled reader recognises into
        ``store``; return the rest (from the first row it stopped at, or the cut line)."""
        done = 0
        while True:
            if store.room() == 0 or store.n == 0:  # the first rows size the store
                need = buf.count(b"\n", done)
                if not need:
                    break
                store.reserve(need, len(buf) - done)
            room = store.room()
            rows, end = csvrows.parse_rows(fn, buf, done, *store.targets(), room)
            if rows:
                store.commit(rows, self.line + 1)
                self.line += rows
                self.path_rows["compiled"] += rows
            done = end
            if rows < room:  # stopped at a row it does not read, or at the cut line
                break
        return buf[done:] if done else buf

    def _parse_plain(self, block: bytes, ncols: int, store: _Rows) -> bool:
        """Parse ``block`` on the fast path; False (nothing consumed) when it cannot."""
        rows, how = parse_block(block, ncols, self.decimals, lambda m: store.space(m, len(block)))
        if rows is None:
            return False
        if how == "plain":
            self.decimals = None  # not fixed-point: the next blocks go straight to plain
        self.path_rows[how] += len(rows)
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
        self.path_rows["checked"] += len(rows)
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
            if ticks[r] == ticks[r - 1]:
                why = "a repeated tick (a row written twice?)"
            else:
                why = "the ticks restart (two logs appended? split them and give each to the "
                why += "command)"
            raise RowError(store.line_of(r), f"tick {ticks[r]} after {ticks[r - 1]}: {why}")
        return ticks


def _column_names(path: Path, text: str) -> list[str]:
    """The names of line 1; refuse a blank or commented line, another delimiter than the
    comma, and a name given twice."""
    if not text or text.startswith("#"):
        raise LogFormatError(f"{path}: line 1: expected the column names")
    if "," not in text:
        for delimiter, what in _OTHER_DELIMITERS.items():
            if delimiter in text:
                raise LogFormatError(
                    f"{path}: line 1: fields separated by {what}; guardid logs are "
                    "comma-separated (re-export it as CSV with commas)"
                )
    names = [n.strip() for n in text.split(",")]
    seen = set()
    for name in names:
        if name in seen:
            raise LogFormatError(f"{path}: line 1: column {name!r} given twice")
        seen.add(name)
    return names


def _check_version(path: Path, header: dict) -> None:
    """Refuse a header naming a log format version this reader does not know."""
    if LOG_VERSION_KEY not in header:
        return
    version = header[LOG_VERSION_KEY]
    if isinstance(version, bool) or version not in KNOWN_LOG_VERSIONS:
        known = ", ".join(str(v) for v in KNOWN_LOG_VERSIONS)
        raise LogFormatError(
            f"{path}: header: {LOG_VERSION_KEY}: format version {version!r} unknown to this "
            f"guardid (it reads version {known}; a newer guardid wrote it?)"
        )


def _comment_start(buf: bytes) -> int | None:
    """Offset of the first line starting with '#' in ``buf``, or None."""
    if buf.startswith(b"#"):
        return 0
    k = buf.find(b"\n#")
    return None if k < 0 else k + 1


def _yaml(path: Path, lines: list[str], what: str) -> dict:
    try:
        value = safe_load("\n".join(lines)) if lines else {}
    except yaml.YAMLError as exc:
        raise LogFormatError(f"{path}: {what}: invalid YAML: {str(exc).splitlines()[0]}") from None
    if not isinstance(value, dict):
        raise LogFormatError(f"{path}: {what}: expected a mapping")
    return value
