"""``guardid simulate`` writes its rows as it makes them: its memory does not grow with the
run's length (it held every row's text until the end before 2026-11-28, so that a long
``--duration`` filled the memory), and the file holds every tick."""

from __future__ import annotations

import tracemalloc

from badinput_tools import invoke


def _peak_bytes(path, seconds: float) -> int:
    tracemalloc.start()
    try:
        res = invoke("simulate", "--duration", seconds, "--no-noise", "-o", path)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert res.exit_code == 0, res.output
    return peak


def test_memory_does_not_grow_with_the_run(tmp_path):
    assert invoke("simulate", "--duration", 1, "-o", tmp_path / "warm.csv").exit_code == 0
    short = _peak_bytes(tmp_path / "short.csv", 15.0)
    long = _peak_bytes(tmp_path / "long.csv", 60.0)
    # four times the rows: a run that kept its rows (about 200 bytes of text each, 4000
    # rows more) would peak at least 0.8 MB higher; written as it goes, within 0.3 MB
    assert long - short < 300_000, (short, long)
    rows = [x for x in (tmp_path / "long.csv").read_text().splitlines() if x[:1].isdigit()]
    assert len(rows) == 4000 and rows[-1].startswith("4000,")
