"""identify and validate on a real capture damaged at random: exit 0 or one error line.

The log is a 10 s lock-step capture of sim://guard (made once per module); hypothesis flips
bytes, cuts rows or the file's end, drops columns and writes NaN / inf into cells. Whatever
the damage, ``guardid identify`` and ``guardid validate`` must end with exit code 0 or with
exactly one ``guardid: error:`` line on stderr and a non-zero exit code, never with an
exception (a traceback). Seeded (derandomised), no deadline: 300 + 220 examples.
"""

from __future__ import annotations

import pytest
from badinput_tools import assert_ok_or_one_line, invoke, short_capture
from hypothesis import HealthCheck, event, given, settings
from hypothesis import strategies as st

SETTINGS = dict(
    deadline=None,
    derandomize=True,
    database=None,
    suppress_health_check=[HealthCheck.too_slow, HealthCheck.function_scoped_fixture],
)


class Base(tuple):
    """(log bytes, params.yaml path); a short repr for hypothesis's failure reports."""

    def __repr__(self):
        return f"Base({len(self[0])} bytes, {self[1].name})"


@pytest.fixture(scope="module")
def base(tmp_path_factory):
    """(log bytes, params.yaml path) of an undamaged run that identifies cleanly."""
    d = tmp_path_factory.mktemp("damage")
    log = short_capture(d)
    params = d / "params.yaml"
    res = invoke("identify", log, "--method", "ls", "-o", params)
    assert res.exit_code == 0, res.output  # the undamaged log is fine: damage makes the errors
    return Base((log.read_bytes(), params))


def _flip(data: bytes, draw) -> bytes:
    if not data:
        return data
    out = bytearray(data)
    for _ in range(draw(st.integers(1, 6))):
        out[draw(st.integers(0, len(out) - 1))] = draw(st.integers(0, 255))
    return bytes(out)


class NoRows(Exception):
    """The (already damaged) text has no data row left."""


def _split(data: bytes):
    lines = data.decode("utf-8").splitlines(keepends=True)
    rows = [k for k, line in enumerate(lines) if line[:1].isdigit()]
    if not rows:
        raise NoRows
    return lines, rows


def _cut_rows(data: bytes, draw) -> bytes:
    lines, rows = _split(data)
    a = draw(st.sampled_from(rows))
    b = draw(st.integers(a, min(a + draw(st.sampled_from([1, 5, 300, 700])), rows[-1] + 1)))
    return "".join(lines[:a] + lines[b:]).encode()


def _truncate(data: bytes, draw) -> bytes:
    return data[: draw(st.integers(0, len(data)))]


def _drop_column(data: bytes, draw) -> bytes:
    lines, rows = _split(data)
    ncol = lines[0].count(",") + 1
    k = draw(st.integers(0, ncol - 1))
    everywhere = draw(st.booleans())  # else only from the data rows
    targets = ([0] if everywhere else []) + rows

    def drop(line: str) -> str:
        parts = line.rstrip("\n").split(",")
        return ",".join(parts[:k] + parts[k + 1 :]) + "\n"

    for i in targets:
        lines[i] = drop(lines[i])
    return "".join(lines).encode()


def _bad_values(data: bytes, draw) -> bytes:
    lines, rows = _split(data)
    ncol = lines[0].count(",") + 1
    for _ in range(draw(st.integers(1, 4))):
        i = draw(st.sampled_from(rows))
        parts = lines[i].rstrip("\n").split(",")
        parts[draw(st.integers(0, ncol - 1))] = draw(st.sampled_from(["nan", "inf", "-inf"]))
        lines[i] = ",".join(parts) + "\n"
    return "".join(lines).encode()


DAMAGE = {
    "flip": _flip,
    "cut_rows": _cut_rows,
    "truncate": _truncate,
    "drop_column": _drop_column,
    "nan": _bad_values,
}


def damage(data: bytes, draw) -> tuple[list[str], bytes]:
    """One or two damages drawn with ``draw`` (hypothesis's data.draw) applied in turn."""
    kinds = draw(st.lists(st.sampled_from(sorted(DAMAGE)), min_size=1, max_size=2))
    for kind in kinds:
        try:
            data = DAMAGE[kind](data, draw)
        except (UnicodeDecodeError, IndexError, NoRows):
            data = _flip(data, draw)  # no text or no row left to damage that way: flip bytes
    return kinds, data


def _write(tmp_path, data: bytes):
    path = tmp_path / "damaged.csv"
    path.write_bytes(data)
    return path


@settings(max_examples=300, **SETTINGS)
@given(st.data())
def test_identify_on_a_damaged_log_exits_0_or_one_line(base, tmp_path, data):
    kinds, blob = damage(base[0], data.draw)
    path = _write(tmp_path, blob)
    result = invoke("identify", path, "--method", "ls")
    event(f"exit {result.exit_code}")  # --hypothesis-show-statistics: how many ran through
    assert_ok_or_one_line(result, f"identify {kinds}")


@settings(max_examples=220, **SETTINGS)
@given(st.data())
def test_validate_on_a_damaged_log_exits_0_or_one_line(base, tmp_path, data):
    kinds, blob = damage(base[0], data.draw)
    path = _write(tmp_path, blob)
    result = invoke("validate", path, "--params", base[1])
    event(f"exit {result.exit_code}")
    assert_ok_or_one_line(result, f"validate {kinds}")
