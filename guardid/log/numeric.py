"""Numeric CSV text to float64 arrays in compiled loops, a block of complete lines at a time.

:func:`parse_plain` is the fast path for what guardid's log writer produces: plain decimals
(``-12.345``, ``17``) separated by ``,``, lines ending in ``\\n``. It removes the decimal
points, reads the digits as integers with numpy's integer text parser (about 10x faster than
its float parser) and divides each field by 10^(digits after the point). Both numbers are
exact in float64 (fewer than 2^53, at most 10^22), so the quotient is the correctly rounded
value of the decimal: bit-identical to ``float(text)``. It returns None for anything else
(exponents, ``nan``, spaces, CRLF, empty fields: one ``bytes.translate`` pass turns the
newlines into commas, drops the points and any other byte into an ``x`` that no integer
parses), which :func:`parse_lines` reads with
``numpy.loadtxt`` and, on failure, diagnoses line by line.

Where the points are is found one of two ways. A fixed-point log (every row printed with the
same decimals per column, as guardid's writer does: :func:`decimals_of` reads them off the
first row) needs only the separators' places and one byte per field, the point
``decimals[c]`` bytes before the field's end (the ``fixed`` path). Any other plain
decimals take the ``plain`` path, which finds every point and sign. Both give the same
values; which one read a log is logged at DEBUG level (logger ``guardid.log``).
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


def decimals_of(line: bytes, ncols: int) -> np.ndarray | None:
    """Digits after the point in each of the ``ncols`` fields of one data ``line`` (0 for a
    field without a point): the fixed-point format a writer like guardid's keeps for every
    row (``%.9f`` for angles, ``%.3f`` for volts, ...). None when the line has another
    field count or a field has more decimals than a float64 power of ten holds exactly."""
    fields = line.rstrip(b"\r\n").split(b",")
    if len(fields) != ncols:
        return None
    decimals = np.array([len(f) - f.index(b".") - 1 if b"." in f else 0 for f in fields])
    return decimals if decimals.max(initial=0) < _POW10.size else None


def parse_plain(block: bytes, ncols: int, decimals: np.ndarray | None = None) -> np.ndarray | None:
    """(rows, ncols) float64 of ``block`` (complete ``\\n``-terminated lines of ``ncols``
    comma-separated plain decimals), or None when the block holds anything else.
    ``decimals`` (from :func:`decimals_of`): try the fixed-point check first."""
    return parse_block(block, ncols, decimals)[0]


def parse_block(
    block: bytes, ncols: int, decimals: np.ndarray | None = None, out=None
) -> tuple[np.ndarray | None, str]:
    """:func:`parse_plain` and the path that read the block: ``fixed`` (every field has the
    point where ``decimals`` puts it), ``plain`` (the point found field by field) or
    ``declined`` (None: not plain decimals). ``out(rows)``, if given, returns the (rows,
    ncols) float64 array to fill (the caller's store; written to even when declined)."""
    if not block:
        return np.empty((0, ncols)), "plain"
    if not block.endswith(b"\n"):
        return None, "declined"
    ints = _integers(block)
    if ints is None or ints.size % ncols:
        return None, "declined"
    b = np.frombuffer(block, dtype=np.uint8)
    if decimals is not None and decimals.size == ncols:
        values = _fixed_point(b, ints, decimals, out)
        if values is not None:
            return values, "fixed"
    values = _plain(b, ints, ncols)
    if values is None:
        return None, "declined"
    if out is not None:
        dest = out(len(values))
        dest[...] = values
        values = dest
    return values, "plain"


def _integers(block: bytes) -> np.ndarray | None:
    """Every field of ``block`` with its point dropped, as int64 (numpy's compiled integer
    parser); None for an empty field, a byte that is not plain (see the module's note), or
    a number of 2^53 or more (not exact in float64; the parser clips at the int64 range)."""
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        try:  # text mode (sep) of fromstring is not deprecated
            ints = np.fromstring(block.translate(_PLAIN_TABLE, b"."), dtype=np.int64, sep=",")
        except (ValueError, DeprecationWarning):
            return None  # an empty field
    if ints.size and (ints.max() >= _EXACT_INT or ints.min() <= -_EXACT_INT):
        return None
    return ints


def _fixed_point(b: np.ndarray, ints: np.ndarray, decimals: np.ndarray, out=None):
    """The values of ``ints`` (parsed from the bytes ``b``) when every line has
    ``decimals.size`` fields and every field of column c has its point exactly
    ``decimals[c]`` digits before its end (no point where ``decimals[c]`` is 0); else None.
    Checks the separators' and the points' places, not each byte: cheaper than
    :func:`_plain`, the same values (in ``out(rows)`` if given, as :func:`parse_block`)."""
    ncols = decimals.size
    seps = np.flatnonzero(b <= 44)  # ',' and '\n' (no other byte below 45 got parsed)
    if seps.size != ints.size:
        return None
    ends = seps.reshape(-1, ncols)  # each field's separator, by row and column
    nrows = len(ends)
    if not (b[ends[:, -1]] == 10).all() or np.count_nonzero(b == 10) != nrows:
        return None  # a line with another field count
    dotted = np.flatnonzero(decimals)
    if np.count_nonzero(b == 46) != nrows * dotted.size:
        return None  # a point where none belongs, or one missing
    if dotted.size:
        points = ends[:, dotted] - (decimals[dotted] + 1)
        before = ends[:, dotted - 1]  # the separator before each field (column 0: below)
        if dotted[0] == 0:
            before[:, 0] = np.concatenate(([-1], ends[:-1, -1]))
        if not ((b[points] == 46).all() and (points > before).all()):
            return None  # the point elsewhere in the field (or in the field before)
    zero = np.flatnonzero(ints == 0)
    start = np.where(zero > 0, seps[zero - 1] + 1, 0)
    neg = b[start] == 45  # '-0.000' keeps its sign, as float() does; a lone '-' is no number
    negzero, start = zero[neg], start[neg]
    if ((decimals[negzero % ncols] == 0) & (b[start + 1] - 48 >= 10)).any():
        return None
    dest = None if out is None else out(nrows)  # exact / exact: correctly rounded
    values = np.divide(ints.reshape(nrows, ncols), _POW10[decimals], out=dest)
    values[np.divmod(negzero, ncols)] = -0.0
    return values


def _plain(b: np.ndarray, ints: np.ndarray, ncols: int) -> np.ndarray | None:
    """The values of ``ints`` (parsed from the bytes ``b``), each field's point and sign
    found mark by mark; None when the lines or the numbers are not plain decimals."""
    at = np.flatnonzero(b < 48)  # every ',' '\n' '-' '.' (the other bytes are digits)
    kind = b[at]
    is_sep = kind <= 44  # ',' or '\n'
    seps_upto = np.cumsum(is_sep, dtype=np.int32)  # separators up to each mark, inclusive
    nsep = int(seps_upto[-1])  # the block ends in '\n': the last mark is a separator
    newline = np.flatnonzero(kind == 10)
    if nsep % ncols or newline.size != nsep // ncols or ints.size != nsep:
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
