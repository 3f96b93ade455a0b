"""``seed000-fast``: seed 000's Fig. 8, l1 varying ten times faster.

As ``seed000-slow`` but l1(t) = 1.2 + 0.05 sin(t) m: the parameter moves at 1 rad/s, in the
band of the system's own motion (eq. 26 has 2 and 5 rad/s), and the estimate lags. The
paper says a smaller beta alleviates this (Theorem 2: the radius of the region the error
converges to shrinks with beta). Printed for three betas: gamma's rms and largest error
after 2 pi s, and the amplitude ratio and phase lag of the estimate's 1 rad/s component
against the truth's.
"""

from __future__ import annotations

import math

from guardid.reproduce import flexsim as fs
from guardid.reproduce.common import DEFAULT_SEEDS, Report
from guardid.reproduce.seed000_slow import track_report

NAME = "seed000-fast"
OMEGA = 1.0
"""Angular frequency of the l1 variation [rad/s]."""
BETA_SMALL = 0.0001
"""The reduced gain (ten times below ours) [N^2 m^2 s]."""


def l1(t: float) -> float:
    """l1(t) [m]."""
    return 1.2 + 0.05 * math.sin(OMEGA * t)


def run(seed: int = 0, seeds: int = DEFAULT_SEEDS) -> Report:
    """Simulate, estimate over ``seeds`` noise draws from ``seed``, and build the report."""
    rep = Report(NAME, "seed 000 flexible link, Fig. 8: l1 = 1.2 + 0.05 sin(t) m (10x faster)")
    rep = track_report(rep, l1, OMEGA, (fs.BETA_DESIGN, fs.BETA, BETA_SMALL), seed, True, seeds)
    return rep


def plot(rep: Report, out_dir) -> list[str]:
    """Seed 000 Fig. 8 (gamma with fast variation) at each beta."""
    from guardid.reproduce.plots import seed000_track

    return seed000_track(rep, out_dir, figs=("fig8",))
