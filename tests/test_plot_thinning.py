"""Long series are drawn thinned: ``identify --plot`` on a long log drew every row (a 1 h
guard log: 531 MB peak and 6.1-6.3 s of plotting; thinned: 311 MB, 2.6-2.9 s;
bench/results/plot_thinning_2026-11-28.txt)."""

from __future__ import annotations

import re

import matplotlib
import numpy as np
import pytest
from badinput_tools import invoke

from guardid.report import series

matplotlib.use("Agg")


@pytest.mark.parametrize(("n", "most", "stride"), [(10, 3, 4), (10, 5, 2), (10, 10, 1), (7, 20, 1)])
def test_thin_keeps_every_kth_point_within_the_limit(n, most, stride):
    x = np.arange(n)
    (kept,) = series.thin(x, max_points=most)
    np.testing.assert_array_equal(kept, np.arange(0, n, stride))  # strides worked out by hand
    assert len(kept) <= most


def test_identify_plot_draws_every_line_thinned_over_the_whole_log(
    gap_guard_captures, tmp_path, monkeypatch
):
    from matplotlib.axes import Axes

    drawn = []
    real = Axes.plot

    def recorded(self, *args, **kwargs):
        drawn.append(np.asarray(args[0], dtype=float))
        return real(self, *args, **kwargs)

    monkeypatch.setattr(Axes, "plot", recorded)
    monkeypatch.setattr(series, "MAX_PLOT_POINTS", 500)
    res = invoke("identify", gap_guard_captures[1], "--method", "wls,rls", "--plot",
                 tmp_path / "p.png")  # fmt: skip
    assert res.exit_code == 0, res.stderr
    rows = int(re.search(r"^rows (\d+),", res.stdout, re.M).group(1))
    assert rows > 2000  # the case: longer than the limit
    torque, track = drawn[:4], drawn[4:]  # measured and model, two joints; then the tracker's
    stride = -(-rows // 500)
    for x in torque:
        np.testing.assert_array_equal(x, np.arange(0, rows, stride))  # to the last row's stride
    assert track and all(len(t) <= 500 for t in track)
    assert all(t[-1] > 59.0 - 60.0 / 500 * 2 for t in track)  # to the log's end (60 s)
