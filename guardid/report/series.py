"""Long series made short enough to draw: the pages' SVG and ``identify --plot``'s PNG."""

from __future__ import annotations

import math

MAX_PLOT_POINTS = 3000
"""Points per drawn line at most [-]: a figure is about 1000 pixels wide, and a 1 h guard log
has 240 000 ticks (``identify --plot`` drawing every row: 531 MB peak and 6.1-6.3 s of
plotting; thinned: 311 MB, 2.6-2.9 s; bench/results/plot_thinning_2026-11-28.txt)."""


def thin(*arrays, max_points: int | None = None):
    """Every k-th element of each array (same first length), k the smallest stride that
    leaves at most ``max_points`` (default :data:`MAX_PLOT_POINTS`); the arrays as they are
    when already that short."""
    n = len(arrays[0])
    k = max(1, math.ceil(n / (max_points or MAX_PLOT_POINTS)))
    return [a[::k] for a in arrays]
