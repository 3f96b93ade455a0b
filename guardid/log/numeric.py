"""Numeric CSV text to float64 arrays in compiled loops, a block of complete lines at a time.

:func:`parse_plain` is the fast path for what guardid's log writer produces: plain decimals
(``-12.345``, ``17``) separated by ``,``, lines ending in ``\\n``. It removes the decimal
points, reads the digits as integers with numpy's integer text parser (about 5x faster than
its float parser) and divides each field by 10^(digits after the point). Both numbers are
exact in float64 (fewer than 2^53, at most 10^22), so the quotient is the correctly rounded
value of the decimal: bit-identical to ``float(text)``. It returns None for anything else
(exponents, ``nan``, spaces, CRLF, empty fields: one ``bytes.translate`` pass turns the
newlines into commas, drops the points and any other byte into an ``x`` that no integer
parses), which :func:`parse_lines` reads with
``numpy.loadtxt`` and, on failure, diagnoses line by line.
"""

from __future__ import annotations

import warnings

import numpy as np

_PLAIN_BYTES = b"0123456789,.-\n"
_POW10 = 10.0 ** np.arange(23)  # every power exact in float64
_EXACT_INT = 2**53
_PLAIN_TABLE = bytes(  # '\n' -> ',' and any byte not in _PLAIN_BYTES -> 'x' (no number)
    44 if c == 10 else c if c in _PLAIN_BYTES else 120 for c in range(256)
)


def parse_plain(block: bytes, ncols: int) -> np.ndarray | None:
    """(rows, ncols) float64 of ``block`` (complete ``\\n``-terminated lines of ``ncols``
    comma-separated plain decimals), or None when the block holds anything else."""
    if not block:
        return np.empty((0, ncols))
    if not block.endswith(b"\n"):
        return None
    b = np.frombuffer(block, dtype=np.uint8)
    at = np.flatnonzero(b < 48)  # every ',' '\n' '-' '.' (the other bytes are digits)
    kind = b[at]
    is_sep = kind <= 44  # ',' or '\n'
    seps_upto = np.cumsum(is_sep, dtype=np.int32)  # separators up to each mark, inclusive
    nsep = int(seps_upto[-1])  # the block ends in '\n': the last mark is a separator
    newline = np.flatnonzero(kind == 10)
    if nsep % ncols or newline.size != nsep // ncols:
        return None
    if not np.array_equal(seps_upto[newline], np.arange(ncols, nsep + 1, ncols)):
        return None  # a line with another field count
    dash = np.flatnonzero(kind == 45)
    if dash.size:
        pos = at[dash]
        after = b[pos + 1]  # a dash is never last: the block ends in '\n'
        at_start = (pos == 0) | (b[pos - 1] == 44) | (b[pos - 1] == 10)
        digit_next = (after - 48 < 10) | (
            (after == 46) & (b[np.minimum(pos + 2, b.size - 1)] - 48 < 10)
        )
        if not (at_start.all() and digit_next.all()):
            return None  # '-' inside a number, or a field that is only '-' / '-.'
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        try:  # text mode (sep) of fromstring is not deprecated
            ints = np.fromstring(block.translate(_PLAIN_TABLE, b"."), dtype=np.int64, sep=",")
        except (ValueError, DeprecationWarning):
            return None  # an empty field
    if ints.size != nsep or np.abs(ints).max(initial=0) >= _EXACT_INT:
        return None
    values = ints.astype(np.float64)
    dot = np.flatnonzero(kind == 46)
    if dot.size:
        if not is_sep[dot + 1].all():  # the mark after a point must end its field
            return None  # two points in a field, or a '-' after the point
        frac = at[dot + 1] - at[dot] - 1
        if frac.max() >= _POW10.size:
            return None  # too many decimals to be exact
        values[seps_upto[dot]] /= _POW10[frac]  # a point's field: the separators before it
    if dash.size:
        neg = seps_upto[dash]
        values[neg[ints[neg] == 0]] = -0.0  # '-0.000' keeps its sign, as float() does
    return values.reshape(-1, ncols)


class RowError(ValueError):
    """A line that is not ``ncols`` numbers: ``line`` (1-based) and what is wrong."""

    def __init__(self, line: int, what: str) -> None:
        super().__init__(f"line {line}: {what}")
        self.line = line
        self.what = what


def parse_lines(lines: list[bytes], first_line: int, names: list[str]) -> np.ndarray:
    """(rows, len(names)) float64 of data ``lines`` (``first_line`` is the first's 1-based
    number; blank lines skipped, any float syntax). Raises :class:`RowError` for the first
    line with another field count or a field that is not a number, and for NaN or inf."""
    ncols = len(names)
    numbered = [(first_line + k, line) for k, line in enumerate(lines) if line.strip()]
    text = [line.decode("latin-1") for _, line in numbered]
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            rows = np.loadtxt(text, delimiter=",", ndmin=2, comments=None)
        if rows.shape[1] != ncols and rows.size:
            raise ValueError
    except ValueError:
        _diagnose(numbered, names)
        raise RowError(numbered[0][0], "not a number") from None  # not reached
    rows = rows.reshape(-1, ncols)
    bad = np.argwhere(~np.isfinite(rows))
    if bad.size:
        r, c = (int(x) for x in bad[0])
        raise RowError(numbered[r][0], f"column {names[c]!r}: {rows[r, c]} (not finite)")
    return rows


def _diagnose(numbered, names) -> None:
    """Raise :class:`RowError` for the first bad line of ``numbered`` [(line, bytes)]."""
    for no, line in numbered:
        try:
            parts = line.decode("utf-8").rstrip("\r\n").split(",")
        except UnicodeDecodeError:
            raise RowError(no, "binary data (not a text log)") from None
        if "\x00" in line.decode("latin-1"):
            raise RowError(no, "binary data (not a text log)")
        if len(parts) != len(names):
            raise RowError(no, f"{len(parts)} fields, expected {len(names)}")
        for name, part in zip(names, parts, strict=True):
            try:
                float(part)
            except ValueError:
                raise RowError(no, f"not a number in column {name!r} ({part.strip()!r})") from None
