"""Edits of a guardid log's text for tests, with str.split only (independent of guardid.log):
rows removed (with or without a trace in the ticks), columns swapped (with or without their
names) or scaled, a header line changed."""

from __future__ import annotations


def data_rows(text: str) -> tuple[list[str], list[int]]:
    """(lines with their ends, indices of the data lines)."""
    lines = text.splitlines(keepends=True)
    return lines, [k for k, line in enumerate(lines) if line[:1].isdigit()]


def without_rows(text: str, start: int, count: int) -> str:
    """The log without data rows start .. start + count - 1 (0 = the first data row)."""
    lines, rows = data_rows(text)
    drop = set(rows[start : start + count])
    return "".join(line for k, line in enumerate(lines) if k not in drop)


def column(text: str, name: str) -> list[float]:
    """The values of column ``name`` over the data rows."""
    lines, rows = data_rows(text)
    c = lines[0].rstrip("\n").split(",").index(name)
    return [float(lines[k].split(",")[c]) for k in rows]


def swapped(text: str, a: str, b: str, names_too: bool) -> str:
    """Columns ``a`` and ``b`` swapped in every data row, and in line 1 if ``names_too``
    (then the file holds the same data by name)."""
    lines, rows = data_rows(text)
    head = lines[0].rstrip("\n").split(",")
    i, j = head.index(a), head.index(b)
    for k in [0, *rows] if names_too else rows:
        parts = lines[k].rstrip("\n").split(",")
        parts[i], parts[j] = parts[j], parts[i]
        lines[k] = ",".join(parts) + "\n"
    return "".join(lines)


def scaled(text: str, name: str, factor: float) -> str:
    """Column ``name``'s values times ``factor`` in every data row (printed with repr)."""
    lines, rows = data_rows(text)
    c = lines[0].rstrip("\n").split(",").index(name)
    for k in rows:
        parts = lines[k].rstrip("\n").split(",")
        parts[c] = repr(float(parts[c]) * factor)
        lines[k] = ",".join(parts) + "\n"
    return "".join(lines)


def with_header_line(text: str, key: str, value: str) -> str:
    """The log with its header line ``# key: ...`` replaced by ``# key: value``."""
    lines = text.splitlines(keepends=True)
    out = [f"# {key}: {value}\n" if line.startswith(f"# {key}: ") else line for line in lines]
    assert out != lines, key
    return "".join(out)


def without_footer(text: str) -> str:
    """The log without its footer (the comment lines after the last data row)."""
    lines, rows = data_rows(text)
    return "".join(lines[: rows[-1] + 1])


def spliced(text: str, start: int, count: int) -> str:
    """The log without data rows start .. start + count - 1, its tick and time columns
    renumbered to run on without a gap (the first row's tick and time, one period per row)
    and its footer dropped: rows lost with nothing in the log to show it."""
    lines, rows = data_rows(text)
    head = lines[0].rstrip("\n").split(",")
    tick, time = head.index("tick"), head.index("time_s")
    first = lines[rows[0]].split(",")
    tick0, t0 = int(first[tick]), float(first[time])
    dt = float(lines[rows[1]].split(",")[time]) - t0
    drop, data = set(rows[start : start + count]), set(rows)
    out, n = [], 0
    for k, line in enumerate(lines[: rows[-1] + 1]):
        if k in drop:
            continue
        if k in data:
            parts = line.rstrip("\n").split(",")
            parts[tick], parts[time] = str(tick0 + n), f"{t0 + n * dt:.6f}"
            line, n = ",".join(parts) + "\n", n + 1
        out.append(line)
    return "".join(out)
