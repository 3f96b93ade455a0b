"""``read_log`` against pandas' ``read_csv`` on the same capture log, in one process (issue 30).

The logs are bench_identify.py's cached captures (``--cache``): one hour of the optimised
excitation captured from ``sim://guard`` in lock-step, and that hour's rows repeated for the
longer logs. Each round reads the log with ``guardid.read_log`` and with
``pandas.read_csv(path, comment="#")`` (its C engine, default options), in turn,
``--runs`` rounds; the figures are the CPU time (``time.process_time``) of each read, median
and worst, and the ratio of the medians. The import of pandas is not counted (it is done
before the first round).

Then, once each: the paths that read the log (``compiled``, ``fixed``, ``plain``,
``checked``: the DEBUG line of the ``guardid.log`` logger), the peak of memory traced during
one ``read_log`` (``tracemalloc``; numpy's arrays are traced) against the file's size and
the float64 arrays kept, and an independent check of the values: every cell equal, bit for
bit, to what Python's ``float()`` makes of its text (and whether pandas' values are the
same).

    python bench/bench_read_log.py [--hours 1 4] [--runs 7] [--cache DIR]
"""

from __future__ import annotations

import argparse
import logging
import statistics
import sys
import tempfile
import time
import tracemalloc
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_identify import hour_log, repeated_log  # noqa: E402


class _Paths(logging.Handler):
    def __init__(self) -> None:
        super().__init__(logging.DEBUG)
        self.lines: list[str] = []

    def emit(self, record) -> None:
        self.lines.append(record.getMessage())


def cpu(fn) -> float:
    start = time.process_time()
    fn()
    return time.process_time() - start


def compare(path: Path, runs: int) -> None:
    import pandas as pd

    from guardid.log import read_log

    times: dict[str, list[float]] = {"read_log": [], "pandas": []}
    for _ in range(runs):
        times["read_log"].append(cpu(lambda: read_log(path)))
        times["pandas"].append(cpu(lambda: pd.read_csv(path, comment="#")))
    med = {k: statistics.median(v) for k, v in times.items()}
    size = path.stat().st_size
    print(f"{path.name}: {size / 1e6:.1f} MB, {runs} rounds, CPU s median (worst):")
    for k, v in times.items():
        print(f"  {k:9s} {med[k]:.3f} ({max(v):.3f})")
    ratios = [a / b for a, b in zip(times["read_log"], times["pandas"], strict=True)]
    print(
        f"  read_log / pandas: {med['read_log'] / med['pandas']:.2f} (ratio of the medians); "
        f"round by round median {statistics.median(ratios):.2f}, worst {max(ratios):.2f}"
    )

    handler = _Paths()
    log = logging.getLogger("guardid.log")
    log.addHandler(handler)
    log.setLevel(logging.DEBUG)
    tracemalloc.start()
    data = read_log(path)
    peak = tracemalloc.get_traced_memory()[1]
    tracemalloc.stop()
    log.removeHandler(handler)
    kept = sum(c.nbytes for c in data.columns.values())
    said = handler.lines[-1].split(": ", 1)[1] if handler.lines else "(not logged by this tree)"
    print(f"  path: {said}")
    print(
        f"  read_log peak traced {peak / 1e6:.1f} MB = {peak / kept:.2f}x the arrays kept "
        f"({kept / 1e6:.1f} MB), {peak / size:.2f}x the file"
    )

    print(f"  every cell bit for bit float(text): {_as_float_reads(path, data.columns)}")
    frame = pd.read_csv(path, comment="#")
    same = all(_bits(frame[c]) == _bits(v) for c, v in data.columns.items())
    print(f"  pandas' values bit for bit the same: {same}")


def _bits(column) -> bytes:
    return np.asarray(column, dtype=np.float64).tobytes()


def _as_float_reads(path: Path, columns: dict) -> bool:
    """Every data cell of ``path`` through Python's ``float()`` against ``columns``."""
    with open(path, encoding="utf-8") as f:
        names = f.readline().strip().split(",")
        rows = [[float(x) for x in ln.split(",")] for ln in f if ln[0] != "#" and ln.strip()]
    want = np.array(rows)
    return all(_bits(want[:, k]) == _bits(columns[n]) for k, n in enumerate(names))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--hours", type=int, nargs="+", default=[1, 4], help="Log lengths [h].")
    ap.add_argument("--runs", type=int, default=7, help="Rounds (read_log, pandas) per log.")
    cache = Path(tempfile.gettempdir()) / "guardid-bench-cache"
    ap.add_argument("--cache", type=Path, default=cache, help="bench_identify.py's cache.")
    args = ap.parse_args()
    import pandas  # noqa: F401  -- imported before the first round, not timed

    hour = hour_log(args.cache)
    for hours in args.hours:
        compare(repeated_log(hour, hours), args.runs)


if __name__ == "__main__":
    main()
