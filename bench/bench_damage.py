"""Randomly damaged copies of a capture: no traceback, no silent confident wrong answer.

Issue 26's acceptance check. One lock-step capture of ``sim://guard`` (``--seed``) is
identified intact (``--method wls``); then ``--copies`` damaged copies, each with one kind of
damage drawn at random (seeded), are identified the same way through the command line:

    cut        a stretch of 2 to 1500 consecutive rows removed (a gap in the ticks)
    splice     the same with the ticks and times renumbered and the footer dropped: rows
               lost without a trace (split only where the step is a jump)
    swap       two joint columns swapped, header and data together (same data by name)
    swapdata   the two joints' angle values swapped under unchanged names
    flip       1 to 6 bytes of the data rows replaced by random bytes
    nan        1 to 20 cells of the data made NaN
    truncate   the file cut at a random byte
    repeat     a block of 1 to 50 rows written twice (repeated ticks)
    reorder    two rows exchanged
    dropcol    one column removed (header and data)

Each copy ends in one of: ``error`` (non-zero exit, exactly one ``guardid: error:`` line after
any one-line ``guardid: warning:`` notes of the reader, as tests/badinput_tools.py allows),
``same`` (exit 0, every parameter within 3 intact std of the intact estimate), ``warned``
(exit 0, further off, with a warning line on the output that is not one a clean log
can give too, such as a parameter's large relative std) or ``BAD`` (a traceback, an error of
more than one line, or exit 0 more than 3 std off without a warning). The distance is
computed here with numpy from the params files, not by guardid.

    python bench/bench_damage.py [--copies 100] [--seed 7] [--duration 60] [--jobs 2]
                                 [--keep DIR] [--kinds cut,splice,...]
"""

from __future__ import annotations

import argparse
import subprocess
import sys
import tempfile
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import numpy as np
import yaml

GENERIC = ("relative standard deviation",)
"""Warnings that do not name any damage (they come with a clean log too)."""
KINDS = ("cut", "swap", "swapdata", "flip", "nan", "truncate", "repeat", "reorder", "dropcol",
         "splice")  # fmt: skip


def _run(*args) -> subprocess.CompletedProcess:
    return subprocess.run(
        [sys.executable, "-m", "guardid", *map(str, args)], capture_output=True, text=True
    )


def _split(text: str) -> tuple[list[str], list[str], list[str]]:
    """([], [column line + the header's comment lines], data rows and footer lines)."""
    lines = text.splitlines(keepends=True)
    k = next(i for i, ln in enumerate(lines) if ln.startswith("tick,"))
    h = next(i for i in range(k + 1, len(lines)) if not lines[i].startswith("#"))
    return lines[:k], lines[k:h], lines[h:]


def _rows_and_footer(body: list[str]) -> tuple[list[str], list[str]]:
    n = next((i for i, ln in enumerate(body) if ln.startswith("#")), len(body))
    return body[:n], body[n:]


def _swap_fields(line: str, a: int, b: int) -> str:
    cells = line.rstrip("\n").split(",")
    cells[a], cells[b] = cells[b], cells[a]
    return ",".join(cells) + "\n"


def damage(text: str, kind: str, rng: np.random.Generator) -> tuple[str, str]:
    """The damaged text and a short description of the damage."""
    head, cols, body = _split(text)
    rows, foot = _rows_and_footer(body)
    names = cols[0].rstrip("\n").split(",")
    n = len(rows)
    if kind == "cut":
        k = int(rng.integers(2, 1501))
        at = int(rng.integers(50, n - k - 50))
        return "".join(head + cols + rows[:at] + rows[at + k :] + foot), f"{k} rows cut at {at}"
    if kind == "splice":
        k = int(rng.integers(2, 1501))
        at = int(rng.integers(50, n - k - 50))
        kept = rows[:at] + rows[at + k :]
        first = kept[0].split(",")
        tick0, t0 = int(first[0]), float(first[1])
        dt = float(kept[1].split(",")[1]) - t0
        renumbered = []
        for m, row in enumerate(kept):
            cells = row.split(",")
            cells[0], cells[1] = str(tick0 + m), f"{t0 + m * dt:.6f}"
            renumbered.append(",".join(cells))
        return "".join(head + cols + renumbered), f"{k} rows spliced out at {at}"
    if kind in ("swap", "swapdata"):
        group = str(rng.choice(["q", "counts", "i", "v"]))
        idx = [i for i, c in enumerate(names) if c.split("_")[0] == group]
        a, b = idx[0], idx[1]
        new_rows = [_swap_fields(r, a, b) for r in rows]
        new_cols = [_swap_fields(cols[0], a, b), *cols[1:]] if kind == "swap" else cols
        return "".join(head + new_cols + new_rows + foot), f"{kind} {names[a]}<->{names[b]}"
    if kind == "flip":
        data = bytearray("".join(rows).encode())
        k = int(rng.integers(1, 7))
        for _ in range(k):
            data[int(rng.integers(0, len(data)))] = int(rng.integers(0, 256))
        text2 = "".join(head + cols) + data.decode("utf-8", errors="replace") + "".join(foot)
        return text2, f"{k} bytes flipped"
    if kind == "nan":
        k = int(rng.integers(1, 21))
        new_rows = list(rows)
        for _ in range(k):
            r = int(rng.integers(0, n))
            cells = new_rows[r].rstrip("\n").split(",")
            cells[int(rng.integers(0, len(cells)))] = "nan"
            new_rows[r] = ",".join(cells) + "\n"
        return "".join(head + cols + new_rows + foot), f"{k} cells NaN"
    if kind == "truncate":
        at = int(rng.integers(len(text) // 20, len(text)))
        return text[:at], f"truncated at byte {at}"
    if kind == "repeat":
        k = int(rng.integers(1, 51))
        at = int(rng.integers(50, n - k - 50))
        return "".join(head + cols + rows[: at + k] + rows[at : at + k] + rows[at + k :] + foot), (
            f"{k} rows repeated at {at}"
        )
    if kind == "reorder":
        a = int(rng.integers(10, n - 10))
        b = a + int(rng.integers(1, 10))
        new_rows = list(rows)
        new_rows[a], new_rows[b] = new_rows[b], new_rows[a]
        return "".join(head + cols + new_rows + foot), f"rows {a} and {b} exchanged"
    if kind == "dropcol":
        j = int(rng.integers(0, len(names)))

        def drop(line: str) -> str:
            cells = line.rstrip("\n").split(",")
            return ",".join(cells[:j] + cells[j + 1 :]) + "\n"

        return "".join(head + [drop(cols[0]), *cols[1:]] + [drop(r) for r in rows] + foot), (
            f"column {names[j]} dropped"
        )
    raise ValueError(kind)


def _estimate(params: Path) -> tuple[np.ndarray, np.ndarray]:
    data = yaml.safe_load(params.read_text())
    entry = data["methods"]["wls"]
    return np.asarray(entry["values"], float), np.asarray(entry["std"], float)


def judge(res, params: Path, theta0, std0) -> tuple[str, str]:
    """(verdict, detail) of one damaged copy's identify run."""
    err = res.stderr.strip().splitlines()
    if "Traceback" in res.stderr:
        return "BAD", "traceback: " + (err[-1] if err else "")
    if res.returncode != 0:  # the reader's one-line warnings may come first (the contract
        # of tests/badinput_tools.assert_ok_or_one_line): the error itself is one line
        lines = [ln for ln in err if ln.strip() and not ln.startswith("guardid: warning: ")]
        if len(lines) == 1 and lines[0].startswith("guardid: error:"):
            return "error", lines[0]
        return "BAD", f"exit {res.returncode}, {len(lines)} lines: " + " | ".join(lines[:3])
    theta, _ = _estimate(params)
    off = float(np.max(np.abs(theta - theta0) / std0))
    warned = [
        ln
        for ln in (res.stdout + res.stderr).splitlines()
        if "warning" in ln.lower() and not any(g in ln for g in GENERIC)
    ]
    if off <= 3.0:
        return "same", f"{off:.2f} std"
    if warned:
        return "warned", f"{off:.2f} std; {warned[0][:120]}"
    return "BAD", f"exit 0, {off:.2f} std off, no warning"


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--copies", type=int, default=100)
    ap.add_argument("--seed", type=int, default=7, help="capture and damage seed")
    ap.add_argument("--duration", type=float, default=60.0, help="capture length [s]")
    ap.add_argument("--jobs", type=int, default=2)
    ap.add_argument("--keep", type=Path, default=None, help="keep the files in this folder")
    ap.add_argument("--kinds", default=",".join(KINDS), help="damage kinds, in turn")
    args = ap.parse_args(argv)
    work = args.keep or Path(tempfile.mkdtemp(prefix="damage_"))
    work.mkdir(parents=True, exist_ok=True)
    traj, log, params = work / "traj.yaml", work / "intact.csv", work / "intact.yaml"
    for path, cmd in (
        (traj, ("excite", "-o", traj)),
        (
            log,
            (
                "capture",
                "--trajectory",
                traj,
                "--duration",
                f"{args.duration:g}",
                "--port",
                f"sim://guard?seed={args.seed}&phase=1",
                "--quiet",
                "-o",
                log,
            ),
        ),  # fmt: skip
        (params, ("identify", log, "--method", "wls", "-o", params)),
    ):
        if not path.exists():
            res = _run(*cmd)
            if res.returncode != 0:
                raise SystemExit(f"guardid {cmd[0]} failed: {res.stderr.strip()[-400:]}")
    theta0, std0 = _estimate(params)
    kinds = [k for k in args.kinds.split(",") if k]
    if not set(kinds) <= set(KINDS):
        raise SystemExit(f"--kinds: unknown {sorted(set(kinds) - set(KINDS))}; known {KINDS}")
    text = log.read_text()
    rng = np.random.default_rng(args.seed)
    jobs = []
    for k in range(args.copies):
        kind = kinds[k % len(kinds)]
        damaged, what = damage(text, kind, rng)
        path = work / f"damaged_{k:03d}.csv"
        path.write_text(damaged)
        jobs.append((k, kind, what, path, work / f"damaged_{k:03d}.yaml"))

    def one(job):
        k, kind, what, path, out = job
        out.unlink(missing_ok=True)
        res = _run("identify", path, "--method", "wls", "-o", out)
        return (k, kind, what, *judge(res, out, theta0, std0))

    with ThreadPoolExecutor(args.jobs) as pool:
        results = list(pool.map(one, jobs))
    counts: dict[str, int] = {}
    for k, kind, what, verdict, detail in results:
        counts[verdict] = counts.get(verdict, 0) + 1
        print(f"{k:3d} {kind:9s} {verdict:6s} {what:32s} {detail}")
    verdicts = ("error", "same", "warned", "BAD")
    print("summary: " + ", ".join(f"{v} {counts.get(v, 0)}" for v in verdicts))
    print(f"files in {work}")


if __name__ == "__main__":
    main()
