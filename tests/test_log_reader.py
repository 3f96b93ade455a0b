"""The log reader (guardid.log.read_log): one pass, the numbers float() reads, one-line errors.

Truth is an independent reading of the same text with Python's str.split and float(); the
logs are a real 20 s capture from sim://guard and texts built here line by line.
"""

from __future__ import annotations

import gzip
import re
import subprocess
import sys
import tracemalloc
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from guardid.errors import LogFormatError, LogWarning
from guardid.log import csvrows, read_log
from guardid.log import reader as reader_module
from guardid.log.numeric import parse_plain

README = Path(__file__).resolve().parents[1] / "README.md"


def _cli(*args, check=True):
    return subprocess.run(
        [sys.executable, "-m", "guardid", *args], check=check, capture_output=True, text=True
    )


@pytest.fixture(scope="module")
def sim_log(tmp_path_factory) -> Path:
    d = tmp_path_factory.mktemp("logread")
    traj = d / "traj.yaml"
    _cli("excite", "--no-optimise", "-o", str(traj))
    log = d / "run.csv"
    _cli("capture", "--trajectory", str(traj), "--duration", "20", "--quiet", "-o", str(log))
    return log


@pytest.fixture(params=["compiled", "numpy"])
def body_reader(request, monkeypatch) -> str:
    """Which reader reads the data rows: the compiled one (csvrows.c, handing what it does
    not recognise to numpy's path; skipped without a compiler) or numpy's path alone (as on
    a machine without a compiler)."""
    if request.param == "numpy":
        monkeypatch.setattr(csvrows, "library", lambda: None)
    elif csvrows.library() is None:
        pytest.skip("needs a C compiler")
    return request.param


def reference(text: str):
    """(names, rows as a float array, comment lines) of a complete log, by str.split/float."""
    lines = text.splitlines()
    names = lines[0].split(",")
    rows = [[float(x) for x in ln.split(",")] for ln in lines[1:] if ln and ln[0] != "#"]
    return names, np.array(rows), [ln for ln in lines[1:] if ln.startswith("#")]


def parts(text: str):
    """(head lines incl. column names and header, data lines, footer lines) of a log."""
    lines = text.splitlines(keepends=True)
    first = next(k for k, ln in enumerate(lines) if k and not ln.startswith("#"))
    last = max(k for k, ln in enumerate(lines) if not ln.startswith("#")) + 1
    return lines[:first], lines[first:last], lines[last:]


def write(tmp_path, name, text) -> Path:
    path = tmp_path / name
    path.write_bytes(text.encode() if isinstance(text, str) else text)
    return path


def test_a_captured_log_reads_as_float_reads_it(sim_log, body_reader):
    text = sim_log.read_text()
    names, rows, comments = reference(text)
    data = read_log(sim_log)
    assert list(data.columns) == names and len(rows) > 1300
    for c, name in enumerate(names):
        assert np.array_equal(data.columns[name], rows[:, c]), name
    assert data.columns["tick"].dtype == np.int64
    assert data.header["robot"] == "guard" and data.footer["rows"] == len(rows)
    assert data.warnings == [] and len(comments) > 10


@pytest.mark.parametrize("block", [97, 1000, 65536])
def test_any_block_size_gives_the_same_rows_and_line_numbers(
    sim_log, tmp_path, block, monkeypatch, body_reader
):
    monkeypatch.setattr(reader_module, "BLOCK_BYTES", block)
    whole = read_log(sim_log)
    head, data, foot = parts(sim_log.read_text())
    for name in whole.columns:
        assert np.array_equal(whole.columns[name], reference(sim_log.read_text())[1][
            :, list(whole.columns).index(name)])  # fmt: skip
    k = 1000  # a bad number deep in the file: its line is named
    bad = data[:k] + [data[k].replace(",", ",x", 1)] + data[k + 1 :]
    path = write(tmp_path, "bad.csv", "".join(head + bad + foot))
    with pytest.raises(LogFormatError, match=rf"bad.csv: line {len(head) + k + 1}: not a number"):
        read_log(path)


# --- the fast path against float(), on decimals of every shape -----------------------------

PLAIN = st.builds(  # a plain decimal of up to 15 digits: exact as an integer in float64
    lambda neg, whole, frac: (
        ("-" if neg else "") + whole + ("." + frac if frac is not None else "")
    ),
    st.booleans(),
    st.text(alphabet="0123456789", max_size=7),
    st.none() | st.text(alphabet="0123456789", max_size=8),
).filter(lambda s: any(ch.isdigit() for ch in s))
ANY = st.one_of(PLAIN, st.text(alphabet="0123456789-.e+ na", max_size=6))


@settings(max_examples=200, deadline=None)
@given(st.lists(st.lists(ANY, min_size=3, max_size=3), min_size=1, max_size=20))
def test_fast_path_is_float_or_declines(cells):
    text = "".join(",".join(row) + "\n" for row in cells)
    rows = parse_plain(text.encode(), 3)
    plain = all(re.fullmatch(r"-?[0-9]*\.?[0-9]*", c) and re.search("[0-9]", c) for r in cells
                for c in r)  # fmt: skip
    if plain:
        assert rows is not None  # every plain decimal takes the fast path
    if rows is not None:
        want = np.array([[float(c) for c in r] for r in cells])
        assert np.array_equal(rows, want) and np.array_equal(np.signbit(rows), np.signbit(want))


def test_other_number_syntax_reads_through_the_general_path(tmp_path, body_reader):
    text = "tick,a,b\n# h: 1\n1,1e-3,+2.5\n2, 7 ,-.25\n3,1E2,0x\n"
    with pytest.raises(LogFormatError, match=r"line 5: not a number in column 'b'"):
        read_log(write(tmp_path, "x.csv", text))
    data = read_log(write(tmp_path, "y.csv", text.replace("0x", "4")))
    assert np.array_equal(data.columns["a"], [1e-3, 7.0, 100.0])
    assert np.array_equal(data.columns["b"], [2.5, -0.25, 4.0])


# --- damage: one line naming the file and the line ----------------------------------------


def _damaged(sim_log, kind):
    """(text or bytes, expected message pattern, data rows before the damage) of the log
    damaged as ``kind`` (rows before: what a reader of rows can take before it stops)."""
    text = sim_log.read_text()
    head, data, foot = parts(text)
    n0 = len(head)
    if kind in ("nan", "inf", "-inf"):
        cells = data[300].split(",")
        cells[4] = kind
        bad = data[:300] + [",".join(cells)] + data[301:]
        return "".join(head + bad + foot), rf"line {n0 + 301}: column 'q_pan_rad'.*not finite", 300
    if kind == "gzip":
        return gzip.compress(text.encode()), r"gzip-compressed", 0
    if kind == "binary":
        return np.random.default_rng(5).bytes(5000), r"binary data", 0
    if kind == "ticks restart":  # two logs' rows one after the other
        return (
            "".join(head + data + data + foot),
            (rf"line {n0 + len(data) + 1}: tick \d+ after \d+: the ticks restart"),
            2 * len(data),
        )  # every row is well formed: the ticks are checked once read
    if kind == "second log appended":  # a killed log, then a whole one
        pattern = rf"line {n0 + len(data) + 1}: a second log's column"
        return "".join(head + data) + text, pattern, len(data)
    if kind == "data after footer":
        return (
            text + data[0],
            rf"line {len(text.splitlines()) + 1}: data after the footer",
            len(data),
        )
    if kind == "field missing":
        cells = data[50].split(",")
        bad = data[:50] + [",".join(cells[:-2] + cells[-1:])] + data[51:]
        return "".join(head + bad + foot), rf"line {n0 + 51}: 12 fields, expected 13", 50
    raise AssertionError(kind)


KINDS = ["nan", "inf", "-inf", "gzip", "binary", "ticks restart", "second log appended",
         "data after footer", "field missing"]  # fmt: skip


@pytest.mark.parametrize("kind", KINDS)
def test_damaged_log_is_one_line_error_naming_file_and_line(
    sim_log, tmp_path, kind, body_reader, monkeypatch
):
    """The same one-line error on both readers; the compiled one reads the rows before the
    damage and hands the rest of its block to numpy's path, which names the line."""
    content, pattern, before = _damaged(sim_log, kind)
    path = write(tmp_path, "damaged.csv", content)
    compiled = []
    real = csvrows.parse_rows
    monkeypatch.setattr(csvrows, "parse_rows", lambda *a: compiled.append(real(*a)) or compiled[-1])
    with pytest.raises(LogFormatError) as info:
        read_log(path)
    msg = str(info.value)
    assert "\n" not in msg and msg.startswith(f"{path}: ") and re.search(pattern, msg), msg
    assert sum(rows for rows, _ in compiled) == (before if body_reader == "compiled" else 0)


@pytest.mark.parametrize("kind", ["nan", "gzip", "ticks restart"])
def test_identify_prints_the_error_as_one_line(sim_log, tmp_path, kind):
    content, pattern, _ = _damaged(sim_log, kind)
    path = write(tmp_path, "damaged.csv", content)
    out = _cli("identify", str(path), "--method", "ls", check=False)
    assert out.returncode == 2 and "Traceback" not in out.stderr
    assert re.fullmatch(rf"guardid: error: {re.escape(str(path))}: .*{pattern}.*\n", out.stderr)


# --- a log cut mid-row: the complete rows, with a warning ---------------------------------


@pytest.mark.parametrize("cut_at", [1, 7, 40, -2])
def test_cut_last_row_is_dropped_with_a_warning(sim_log, tmp_path, cut_at, body_reader):
    head, data, _ = parts(sim_log.read_text())
    keep = data[:-1]
    cut = data[-1][: cut_at % len(data[-1])]  # 1 byte, mid-number, ..., all but the '\n'
    path = write(tmp_path, "cut.csv", "".join(head + keep) + cut)
    with pytest.warns(LogWarning, match=rf"line {len(head) + len(keep) + 1}: last row incomplete"):
        got = read_log(path)
    want = reference("".join(head + keep))[1]
    assert got.footer is None and len(got.columns["tick"]) == len(keep)
    assert np.array_equal(np.column_stack(list(got.columns.values())), want)


def test_log_ending_on_a_complete_row_has_no_warning(sim_log, tmp_path, recwarn, body_reader):
    head, data, _ = parts(sim_log.read_text())
    got = read_log(write(tmp_path, "killed.csv", "".join(head + data)))
    assert len(got.columns["tick"]) == len(data) and got.footer is None
    assert not [w for w in recwarn if issubclass(w.category, LogWarning)]


def test_readme_recipe_reads_a_cut_log(sim_log, tmp_path):
    recipe = re.search(r"`(numpy\.genfromtxt\(\"run\.csv\"[^`]*)`", README.read_text()).group(1)
    head, data, _ = parts(sim_log.read_text())
    path = write(tmp_path, "run.csv", "".join(head + data) + data[0][:25])
    import warnings

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # numpy's note about the skipped line
        arr = eval(recipe.replace('"run.csv"', repr(str(path))), {"numpy": np})  # noqa: S307
    want = reference("".join(head + data))[1]
    assert arr.shape == (len(data),) and np.array_equal(arr["tick"], want[:, 0])
    assert np.array_equal(arr["q_tilt_rad"], want[:, 5])


def test_readme_pandas_recipe_reads_a_cut_log(sim_log, tmp_path):
    """The README's pandas recipe (the pandas extra; the test extra installs pandas)."""
    pytest.importorskip("pandas")
    recipe = re.search(r"`(pandas\.read_csv\(\"run\.csv\"[^`]*)`", README.read_text()).group(1)
    head, data, _ = parts(sim_log.read_text())
    path = write(tmp_path, "run.csv", "".join(head + data) + data[0][:25])
    import pandas

    df = eval(recipe.replace('"run.csv"', repr(str(path))), {"pandas": pandas})  # noqa: S307
    want = reference("".join(head + data))[1]
    assert len(df) == len(data) and np.array_equal(df["tick"].to_numpy(), want[:, 0])
    assert np.array_equal(df["q_tilt_rad"].to_numpy(), want[:, 5])


def test_identify_warns_once_about_a_cut_row(sim_log, tmp_path):
    head, data, _ = parts(sim_log.read_text())
    path = write(tmp_path, "cut.csv", "".join(head + data) + data[0][:30])
    out = _cli("identify", str(path), "--method", "ls")
    warned = [ln for ln in out.stderr.splitlines() if "last row incomplete" in ln]
    assert warned == [f"guardid: warning: {path}: line {len(head) + len(data) + 1}: last row "
                      "incomplete, ignored (the writer was stopped)"]  # fmt: skip


# --- one read per log, memory for the rows kept --------------------------------------------


def test_identify_reads_each_log_once(sim_log, monkeypatch):
    from click.testing import CliRunner

    from guardid.cli import main

    reads = []
    real = reader_module._Reader.read
    monkeypatch.setattr(reader_module._Reader, "read", lambda self: reads.append(1) or real(self))
    result = CliRunner().invoke(main, ["identify", str(sim_log), "--method", "ls,rls"])
    assert result.exit_code == 0, result.output
    assert "tracking" in result.output and len(reads) == 1


def test_memory_follows_the_rows_kept_not_the_text(sim_log, tmp_path, monkeypatch, body_reader):
    monkeypatch.setattr(reader_module, "BLOCK_BYTES", 1 << 16)
    head, data, foot = parts(sim_log.read_text())
    span = len(data)
    rows = []
    for rep in range(24):  # 32 000 rows: a 3.4 MB text, 3.3 MB of float64
        for line in data:
            tick, rest = line.split(",", 1)
            rows.append(f"{int(tick) + rep * span},{rest}")
    foot = [re.sub(r"rows: \d+", f"rows: {len(rows)}", line) for line in foot]
    path = write(tmp_path, "long.csv", "".join(head + rows + foot))
    kept = len(rows) * 13 * 8
    tracemalloc.start()
    try:
        read_log(path)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert peak < 1.25 * kept + 1_000_000, (peak, kept, path.stat().st_size)


def test_foreign_csv_reads_the_same_on_both_paths(tmp_path):
    from guardid.identify.foreign import parse_mapping, read_foreign

    rng = np.random.default_rng(2)
    vals = np.round(rng.normal(size=(40, 5)), 6)
    vals[:, 0] = np.arange(40) * 0.002
    plain = "time,pos1,pos2,tau1,tau2\n" + "".join(
        ",".join(f"{v:.6f}" for v in row) + "\n" for row in vals
    )
    labelled = "time,pos1,pos2,tau1,tau2,note\n" + "".join(
        ",".join(f"{v:.6f}" for v in row) + ",ok\n" for row in vals
    )  # a text column: not plain decimals, so the per-cell path reads it
    mapping = parse_mapping(["time=time,q1=pos1,q2=pos2,tau1=tau1,tau2=tau2"])
    a = read_foreign(write(tmp_path, "a.csv", plain), mapping, 2, "planar2")
    b = read_foreign(write(tmp_path, "b.csv", labelled), mapping, 2, "planar2")
    want = np.array([[float(f"{v:.6f}") for v in row] for row in vals])
    for got in (a, b):
        assert np.array_equal(got.q, want[:, 1:3]) and np.array_equal(got.effort, want[:, 3:5])
        assert np.array_equal(got.t, want[:, 0] - want[0, 0])


_NOT_PLAIN = [b"1, 2\n", b"1,+2\n", b"1,2\r\n", b"1,\t2\n", b"1,0x2\n", b"1,2e3\n", b"1,\xff\n",
              b"1,2\x00\n", b"1,1.2.3\n", b"1+2\n", b"1 2\n"]  # fmt: skip


@pytest.mark.parametrize("block", _NOT_PLAIN)
def test_fast_parser_leaves_anything_but_plain_decimals_to_the_checked_path(block):
    """The compiled fast path reads only digits, one '-', one '.', ',' and '\\n': a space,
    a '+', a CR, a tab (which an integer parser would skip or accept) and other bytes go to
    the checked path, which reads or names them."""
    from guardid.log.numeric import parse_plain

    assert parse_plain(block, 2) is None
    assert parse_plain(b"1,-2.50\n", 2).tolist() == [[1.0, -2.5]]


# --- the fixed-point path: guardid's writer format, read without finding every point -------

_ROWS = st.lists(  # values across every magnitude a row's columns may hold, -0.0 and ties
    st.tuples(
        st.integers(0, 2**52),  # tick
        st.floats(0, 1e9) | st.sampled_from([0.0, 0.0000005, 0.0000015, 2.5e-7]),  # time_s
        st.lists(st.integers(-(2**31), 2**31), min_size=2, max_size=2),  # counts
        st.lists(
            st.floats(-9e6, 9e6) | st.sampled_from([-0.0, -1e-10, 5e-10, -4.9999999999e-10]),
            min_size=4,
            max_size=4,
        ),  # q, sp
        st.lists(
            st.floats(-9e12, 9e12) | st.sampled_from([-0.0, -0.0004, 0.0005, -0.0015]),
            min_size=4,
            max_size=4,
        ),  # v, i
        st.integers(0, 255),  # status
    ),
    min_size=1,
    max_size=12,
)


@settings(max_examples=50, deadline=None)
@given(_ROWS)
def test_writer_rows_read_on_the_fixed_path_as_float_reads_them(rows):
    """Random values through the writer's own row format, read back on the fixed-point path:
    every cell bit for bit what ``float(text)`` makes of it (the sign of -0.0 too)."""
    from guardid.log.csvlog import format_row
    from guardid.log.numeric import decimals_of, parse_block

    lines = [format_row(t, s, c, qs[:2], vi[:2], vi[2:], qs[2:], st_) for t, s, c, qs, vi, st_
             in rows]  # fmt: skip
    block = "".join(lines).encode()
    got, how = parse_block(block, 13, decimals_of(lines[0].encode(), 13))
    want = np.array([[float(x) for x in line.split(",")] for line in lines])
    assert how == "fixed"
    assert np.array_equal(got, want) and np.array_equal(np.signbit(got), np.signbit(want))


@pytest.mark.parametrize(
    ("block", "decimals", "why"),
    [
        (b"0.5,1.2500\n0.5,1250\n", [1, 4], "a point missing"),
        (b"0.5,1.2500\n0.5,12.500\n", [1, 4], "the point one digit off"),
        (b"0.5,1.2500\n0.5,1.25000\n", [1, 4], "one decimal more"),
        (b"0.5,1.2500\n0.50,1.2500\n", [1, 4], "a decimal more in column 1"),
        (b"0.5,12\n0.5,1.2.34\n", [1, 4], "a point borrowed from the field before"),
        (b"0.5,1.2500\n0.5,1.2.500\n", [1, 4], "two points in a field"),
        (b"0.250,1.5\n5,1.2.5\n", [3, 1], "a point borrowed from the line before"),
        (b"5,1.2500\n5.0,1.2500\n", [0, 4], "a point in an integer column"),
        (b"0.5\n1.2500,0.5,1.2500\n", [1, 4], "lines of 1 and 3 fields"),
        (b"0.5,1.2500,\n", [1, 4], "a trailing comma"),
        (b"5\n1.2500\n", [0, 4], "a row split over two lines"),
        (b"5,1.2500\n-,1.2500\n", [0, 4], "a lone '-'"),
    ],
)
def test_fixed_path_declines_rows_out_of_its_format(block, decimals, why):
    """Each check of the fixed path: a row out of the first row's format is not read there
    (it goes to the plain path, which reads a plain decimal exactly or declines)."""
    from guardid.log.numeric import _fixed_point, _integers, parse_block

    decimals = np.array(decimals)
    ints = _integers(block)
    if ints is not None and ints.size % 2 == 0:
        assert _fixed_point(np.frombuffer(block, np.uint8), ints, decimals) is None, why
    got, how = parse_block(block, 2, decimals)
    assert how != "fixed", why
    if got is not None:
        assert got.tolist() == [[float(x) for x in ln.split(b",")] for ln in block.splitlines()]


_DEC = np.array([1, 4])


def test_fixed_path_reads_signs_and_bare_points():
    from guardid.log.numeric import parse_block

    got, how = parse_block(b"-0.0,-0.0000\n-.5,.2500\n7.0,-1.0001\n", 2, _DEC)
    assert how == "fixed"
    assert got.tolist() == [[0.0, 0.0], [-0.5, 0.25], [7.0, -1.0001]]
    assert np.signbit(got[0]).all() and not np.signbit(got[1:, 1][0])


def test_numbers_beyond_int64_are_not_clipped():
    """numpy's integer parser clips at the int64 range: numbers that large (and any from
    2^53, not exact in float64) leave the fast paths; the checked path reads them."""
    for block in (b"-99999999999999999999,1\n", b"99999999999999999999,1\n",
                  b"9007199254740993,1\n"):  # fmt: skip
        assert parse_plain(block, 2) is None
    assert parse_plain(b"9007199254740991,-1\n", 2).tolist() == [[2.0**53 - 1, -1.0]]


def test_the_path_that_read_a_log_is_logged(sim_log, tmp_path, caplog, monkeypatch):
    """A guardid log reads on the compiled path (with a compiler), else on the fixed path;
    a log whose decimals vary row by row on the compiled or the plain path, to the same
    values; stdout and stderr stay clean (DEBUG log only)."""
    caplog.set_level("DEBUG", logger="guardid.log")
    head, data, foot = parts(sim_log.read_text())
    varied = [re.sub(r"\.(\d{3}),", r".\g<1>0,", ln, count=1) if k % 2 else ln
              for k, ln in enumerate(data)]  # fmt: skip
    path = write(tmp_path, "varied.csv", "".join(head + varied + foot))
    n = len(data)
    if csvrows.library() is not None:
        for log in (sim_log, path):
            caplog.clear()
            read_log(log)
            assert f"{{'compiled': {n}, 'fixed': 0, 'plain': 0, 'checked': 0}}" in caplog.text
    monkeypatch.setattr(csvrows, "library", lambda: None)  # no compiler: numpy's paths
    caplog.clear()
    assert len(read_log(sim_log).columns["tick"]) == n
    assert f"{{'compiled': 0, 'fixed': {n}, 'plain': 0, 'checked': 0}}" in caplog.text
    caplog.clear()
    got = read_log(path)
    assert f"{{'compiled': 0, 'fixed': 0, 'plain': {n}, 'checked': 0}}" in caplog.text
    names, rows, _ = reference(path.read_text())
    for c, name in enumerate(names):
        assert np.array_equal(got.columns[name], rows[:, c]), name


def test_joint_groups_are_the_columns_without_a_copy(sim_log):
    """Issue 30 (memory): a per-joint group in the log's joint order is handed out as it is
    stored (the columns are views of it: no (N, n) copy beside the store); in another
    order it is a fresh array of those columns. Values against a str.split/float parse."""
    data = read_log(sim_log)
    names, rows, _ = reference(sim_log.read_text())
    joints = data.joint_names
    q = data.joint_array("q", joints)
    assert np.array_equal(q, rows[:, [names.index(f"q_{j}_rad") for j in joints]])
    assert all(np.shares_memory(q, data.columns[f"q_{j}_rad"]) for j in joints)
    assert q.flags.c_contiguous
    swapped = data.joint_array("q", joints[::-1])
    assert np.array_equal(swapped, q[:, ::-1]) and not np.shares_memory(swapped, q)
