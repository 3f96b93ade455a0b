"""The compiled reader of the log body (guardid/log/csvrows.c): float(text) bit for bit on
the rows it recognises, a stop at the first row it does not, and numpy's path without it.

Truth is Python's ``float()`` on each field and offsets counted by hand; the reader's use
inside ``read_log`` (captured logs, damaged logs on both readers) is in test_log_reader.py.
"""

from __future__ import annotations

import logging

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from guardid.log import csvrows, read_log
from guardid.log import reader as reader_module
from guardid.native import cached_library, find_compiler

needs_cc = pytest.mark.skipif(find_compiler() is None, reason="needs a C compiler")


def c_read(block: bytes, ncols: int, start: int = 0, max_rows: int | None = None):
    """(rows parsed as a (rows, ncols) array, offset after them) by the C function, into
    one column-major array (each column's stride 1: not the row layout the C could assume)."""
    fn = csvrows.library()
    assert fn is not None
    room = block.count(b"\n") + 1 if max_rows is None else max_rows
    out = np.full((ncols, room), np.nan)  # column c at out[c], rows contiguous
    addresses = out.ctypes.data + 8 * room * np.arange(ncols)
    rows, end = csvrows.parse_rows(fn, block, start, addresses, np.ones(ncols, int), room)
    return out[:, :rows].T, end


def as_float(block: bytes) -> np.ndarray:
    return np.array([[float(x) for x in line.split(b",")] for line in block.splitlines()])


def same_bits(a: np.ndarray, b: np.ndarray) -> bool:
    """Equal bit for bit (the sign of -0.0 too)."""
    return a.shape == b.shape and np.array_equal(a.view(np.uint64), b.view(np.uint64))


@needs_cc
def test_the_source_builds_with_the_projects_flags(tmp_path, monkeypatch):
    """C99, -Wall -Wextra -Werror -pedantic (guardid.native's flags): a warning is an error
    here, where :func:`csvrows.library` would only log it and fall back."""
    monkeypatch.setenv("GUARDID_CACHE_DIR", str(tmp_path))
    assert cached_library("csvrows", [csvrows.SOURCE]) is not None
    assert csvrows.library() is not None


HAND = (  # negative numbers, zeros and -0, the largest counts, 0 to 22 decimals
    b"0,-0,0.0,-0.000,0.000000000\n"
    b"-1,-0.5,9007199254740991,-9007199254740991,0.0000000000000000000001\n"
    b"2147483647,-2147483648,4294967295,-9007199254.740991,123456.789012345\n"
    b"1,0.1,0.2,0.3,-0.7\n"
    b"00012,-00.50,000000000000000000000000012,1.00000000000000,-99999.9999999999\n"
    b"240001,3599.970000,-67,-0.017540559,1.523\n"
    b"5,0.015,1e0,2,3\n"  # stops here: an exponent
)


@needs_cc
def test_hand_written_rows_read_as_float_reads_them():
    got, end = c_read(HAND, 5)
    good = HAND[: HAND.index(b"5,0.015,1e0")]
    assert end == len(good)  # the offset of the row with the exponent
    assert same_bits(got, as_float(good))
    assert np.signbit(got[0, 1]) and np.signbit(got[0, 3]) and not np.signbit(got[0, 2])


@needs_cc
def test_rows_are_read_from_the_start_offset_up_to_max_rows():
    block = b"1,2\n3,4\n5,6\n7,8\n"
    got, end = c_read(block, 2, start=4, max_rows=2)
    assert got.tolist() == [[3.0, 4.0], [5.0, 6.0]] and end == 12


GOOD = b"1,-2.5,3\n"
BAD_ROWS = [
    b"1,nan,3\n", b"1,inf,3\n", b"1,,3\n", b"1,2\n", b"1,2,3,4\n", b"1,2,3,\n", b"1,2,3\r\n",
    b"1, 2,3\n", b"1,+2,3\n", b"1,2e3,3\n", b"1,5.,3\n", b"1,.5,3\n", b"1,-,3\n", b"1,--2,3\n",
    b"1,2.3.4,3\n", b"1,0x1,3\n", b"1,9007199254740992,3\n", b"1,-9007199254740992,3\n",
    b"1,900719925474099.2,3\n", b"1,0.00000000000000000000001,3\n",
    b"1,18446744073709551621,3\n", b"1,-1844674407370955.1621,3\n", b"# footer:\n", b"\n",
    b"tick,a,b\n", b"1,2,3", b"1,2\xff,3\n", b"1,2\x00,3\n",
]  # fmt: skip


@needs_cc
@pytest.mark.parametrize("bad", BAD_ROWS)
def test_stops_at_the_first_row_it_does_not_recognise(bad):
    """A NaN, an empty or signed-plus field, another field count, a CR, an exponent, a bare
    point, 2^53 (not exact), 23 decimals, 2^64 + 5 (which a uint64 wraps to 5), a comment,
    a blank line, the column names, a line without its '\\n', binary bytes: the rows before
    are read, the parse stops at the start of that row (where numpy's path takes over)."""
    block = GOOD * 3 + bad + GOOD
    got, end = c_read(block, 3)
    assert end == 3 * len(GOOD) and same_bits(got, as_float(GOOD * 3))


FIELD = st.builds(  # a plain decimal the writer could print: up to 15 digits, 0-9 decimals
    lambda neg, whole, frac: ("-" if neg else "") + whole + ("." + frac if frac else ""),
    st.booleans(),
    st.text(alphabet="0123456789", min_size=1, max_size=6),
    st.text(alphabet="0123456789", max_size=9),
)
JUNK = st.text(alphabet="0123456789-.e+ nax", max_size=5)


def recognised(field: str) -> bool:
    """The C reader's syntax, said independently: -?digits(.digits)?, at most 19 digits
    from the first non-zero one, 22 decimals, the digits below 2^53."""
    sign, body = (1, field[1:]) if field.startswith("-") else (0, field)
    whole, point, frac = body.partition(".")
    digits = whole + frac
    return (
        whole.isdigit() and whole.isascii() and (not point or (frac.isdigit() and frac.isascii()))
        and len(digits.lstrip("0")) <= 19 and len(frac) <= 22 and int(digits) < 2**53
    ) or False  # fmt: skip


@needs_cc
@settings(max_examples=150, deadline=None, derandomize=True, database=None)
@given(st.lists(st.lists(FIELD | JUNK, min_size=4, max_size=4), min_size=1, max_size=15))
def test_random_fields_read_as_float_or_stop_at_their_row(cells):
    """Random fields: the rows before the first one with a field out of the syntax are read,
    each value ``float(text)`` bit for bit; the parse stops at that row's start."""
    lines = [(",".join(row) + "\n").encode() for row in cells]
    first_bad = next((k for k, row in enumerate(cells) if not all(map(recognised, row))), None)
    k = len(lines) if first_bad is None else first_bad
    got, end = c_read(b"".join(lines), 4)
    assert end == sum(map(len, lines[:k]))
    assert same_bits(got, as_float(b"".join(lines[:k])).reshape(k, 4))


def _log(tmp_path, rows: list[str], name="x.csv"):
    path = tmp_path / name
    path.write_text("tick,a_V,q_pan_rad,q_tilt_rad\n# guardid-log: 1\n" + "".join(rows))
    return path


def _same_logs(a, b) -> bool:
    return list(a.columns) == list(b.columns) and all(
        a.columns[k].dtype == b.columns[k].dtype and same_bits(
            a.columns[k].astype(np.float64), b.columns[k].astype(np.float64))
        for k in a.columns
    )  # fmt: skip


@needs_cc
def test_a_store_filled_mid_block_grows_and_the_rows_go_on(tmp_path, monkeypatch, caplog):
    """Long rows first, short ones after: the store sized from the first block fills up in
    the middle of a block; it grows and the compiled reader reads on (every row by it)."""
    monkeypatch.setattr(reader_module, "BLOCK_BYTES", 4096)
    long_rows = [f"{k},{k}.123456789012,-{k}.000000000001,{k}0000.5\n" for k in range(1, 200)]
    short_rows = [f"{k},{k % 7},-{k % 3},0\n" for k in range(200, 5000)]
    path = _log(tmp_path, long_rows + short_rows)
    caplog.set_level(logging.DEBUG, logger="guardid.log")
    got = read_log(path)
    assert "'compiled': 4999, 'fixed': 0, 'plain': 0, 'checked': 0" in caplog.text
    want = as_float("".join(long_rows + short_rows).encode())
    assert same_bits(np.column_stack([c.astype(float) for c in got.columns.values()]), want)


def test_without_a_compiler_numpy_reads_the_same(tmp_path, monkeypatch, caplog):
    """$CC naming no compiler: no library, numpy's path, the same arrays as the compiled
    reader's (when there is a compiler) and as float()."""
    rows = [f"{k},{(-1) ** k * k / 8:.3f},-0.{k:09d},{k * 1e-3:.9f}\n" for k in range(1, 400)]
    path = _log(tmp_path, rows)
    with_cc = read_log(path) if csvrows.library() is not None else None
    monkeypatch.setenv("CC", "/nonexistent/cc")
    csvrows.library.cache_clear()
    try:
        assert csvrows.library() is None
        caplog.set_level(logging.DEBUG, logger="guardid.log")
        without = read_log(path)
    finally:
        csvrows.library.cache_clear()
    assert "'compiled': 0, 'fixed': 399" in caplog.text
    assert same_bits(
        np.column_stack([c.astype(float) for c in without.columns.values()]),
        as_float("".join(rows).encode()),
    )
    if with_cc is not None:
        assert _same_logs(with_cc, without)


@needs_cc
def test_a_source_that_does_not_build_falls_back_with_a_warning(tmp_path, monkeypatch, caplog):
    """A compiler error (a broken source, a compiler refusing the flags): numpy's path reads
    the log, and the reason is logged as a warning, not raised at the user."""
    bad = tmp_path / "csvrows.c"
    bad.write_text("long guardid_csv_rows(void) { int unused; return 0; }\n")
    monkeypatch.setenv("GUARDID_CACHE_DIR", str(tmp_path / "cache"))
    monkeypatch.setattr(csvrows, "SOURCE", bad)
    csvrows.library.cache_clear()
    try:
        assert csvrows.library() is None
        assert "building csvrows failed" in caplog.text
        assert read_log(_log(tmp_path, ["1,2,3,4\n", "2,-0.5,0,1\n"])).columns["a_V"].tolist() == [
            2.0, -0.5]  # fmt: skip
    finally:
        csvrows.library.cache_clear()


@needs_cc
def test_a_cache_it_cannot_write_falls_back_with_a_warning(tmp_path, monkeypatch, caplog):
    """The cache directory under a file (as a read-only home would): no library, numpy's
    path, a warning, and not read_log's "cannot read" (an OSError inside the read)."""
    (tmp_path / "file").write_text("")
    monkeypatch.setenv("GUARDID_CACHE_DIR", str(tmp_path / "file" / "cache"))
    csvrows.library.cache_clear()
    try:
        got = read_log(_log(tmp_path, ["1,2,3,4\n", "2,-0.5,0,1\n"]))
        assert got.columns["a_V"].tolist() == [2.0, -0.5]
        assert "compiled log reader unavailable" in caplog.text
    finally:
        csvrows.library.cache_clear()
