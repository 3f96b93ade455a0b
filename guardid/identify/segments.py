"""Runs split at long gaps: rows are conditioned only across (nearly) contiguous ticks.

A guardid log has one row per firmware tick; a lost frame leaves a gap in the tick column.
Conditioning bridges a gap: the positions are resampled by a cubic spline onto the uniform
grid (:func:`guardid.conditioning.filters.resample`) and the period-mean currents through
a spline of their running integral (:mod:`guardid.conditioning.alignment`). That is
harmless for a lost tick or a few, and wrong for a long stretch: the filter, the
derivatives and the regressor then see a made-up motion (a 95-tick gap moved Fc1 by 5 std).

**The limit** (:func:`bridge_limit_ticks`). A bridge over h = (m + 1) T seconds (m lost
ticks of period T) reproduces a component of frequency f with a relative error of about
(5 / 384) (2 pi f h)^4 (the cubic spline's interpolation error, h^4 / 384 x 5 max|x''''|
for x = sin(2 pi f t)). The motion the filter must pass lies below
f_m = f_c / :data:`~guardid.conditioning.bandwidth.HARMONIC_FACTOR`: the cut-off f_c is
sized at that factor times the excitation's highest harmonic (above f_m and up to f_c the
filter passes stick/slip transients and noise, which no bridge reproduces and no
conditioning keeps away from the rows). The bridge is accepted while its error at f_m is
:data:`BRIDGE_ERROR` (0.1 %, -60 dB: far below the pass band's unit gain, and below the
accelerations' noise): h_max = (384 eps / 5)^(1/4) / (2 pi f_m) = 0.67 / f_c at order 8,
i.e. m_max = floor(h_max / T) - 1 lost ticks, and never fewer than one (a single lost tick,
as on a noisy link, is bridged as before). The same ratio holds for the accelerations the
regressor uses (qdd of a sine is the sine times (2 pi f)^2). On the guard robot (T = 15
ms, highest harmonic 0.5 Hz, highest cut-off candidate 8 Hz) that is 4 lost ticks; on
60 s captures gaps of up to 20 ticks moved no parameter by more than 0.07 std, 40 ticks by
1.7 std and 95 by 35 std (``identify --method wls`` on a capture with rows removed).

**Which cut-off.** The cut-off is chosen by cross-validation after the runs are split (every
candidate must see the same runs), so the limit uses the *highest* candidate
(:func:`highest_cutoff_hz`: the strictest limit, any candidate's bridges are then within
the error above), or the cut-off given with ``--cutoff`` / stored in a params file. This is
the acceleration form's rule: the momentum form (the default for guardid logs) bridges no
gap at all (its filter's stretch ends at every lost tick, :mod:`guardid.conditioning.momentum`),
so there the split changes little but the gap's line, whose limit and cut-off are still this
rule's, not the momentum form's own cut-off.

A step between two rows beyond what the drives can make (a **jump**: rows lost without a
gap in the ticks, :mod:`guardid.identify.jumps`) splits the run as such a gap does, whatever
the ticks say.

A gap longer than the limit splits the run into segments ``run.csv[1]``, ``run.csv[2]``, ...
treated as separate runs are (each filtered, differentiated and its ends cut on its own;
the closed-loop methods simulate each from its first state; ``--cv`` holds out whole
files). A segment too short to be conditioned (fewer than :func:`min_segment_rows` rows)
is dropped. Each gap costs its lost ticks and the rows its two new segment ends drop
(one cut-off period each: the conditioning's ``edge_s``); :meth:`Split.lines` says so.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace

import numpy as np

from guardid.conditioning.bandwidth import HARMONIC_FACTOR, MAX_NYQUIST_FRACTION, MIN_CUTOFF_HZ
from guardid.identify.cutoff import SPAN, motion_bandwidth
from guardid.identify.jumps import drive_reach, find_jumps

BRIDGE_ERROR = 1e-3
"""Largest relative error [-] of a bridged gap at the motion's highest frequency (module)."""
MIN_SEGMENT_PERIODS = 2.0
"""A segment shorter than this many periods of the (highest) cut-off, plus the nine samples
of the derivative stencils, has no row left after its ends are cut: it is dropped [-]."""

_PER_RUN = ("t", "q", "current", "voltage", "ticks", "qd", "setpoint", "counts")


def bridge_limit_ticks(cutoff_hz: float, sample_period_s: float) -> int:
    """The most lost ticks [-] a bridge may span at cut-off ``cutoff_hz`` [Hz] and sample
    period ``sample_period_s`` [s] (module docstring); at least 1."""
    f_motion = float(cutoff_hz) / HARMONIC_FACTOR
    h_max = (384.0 * BRIDGE_ERROR / 5.0) ** 0.25 / (2.0 * math.pi * f_motion)  # [s]
    return max(1, math.floor(h_max / float(sample_period_s) + 1e-9) - 1)


def min_segment_rows(cutoff_hz: float, sample_period_s: float) -> int:
    """Fewest rows [-] of a segment worth conditioning at ``cutoff_hz`` [Hz]."""
    return math.ceil(MIN_SEGMENT_PERIODS / (float(cutoff_hz) * float(sample_period_s))) + 9


def highest_cutoff_hz(runs, highest_harmonic_hz: float | None = None) -> float:
    """The highest cut-off [Hz] the cross-validation may choose for ``runs`` (Run objects):
    min(0.4 x Nyquist, SPAN x the motion's bandwidth), as :mod:`guardid.identify.cutoff`."""
    period = min(_period(r) for r in runs)
    top = MAX_NYQUIST_FRACTION * 0.5 / period
    band = motion_bandwidth([(r.t, r.q) for r in runs], highest_harmonic_hz)
    return float(min(top, SPAN * max(band, MIN_CUTOFF_HZ)))


def _period(run) -> float:
    """The run's tick period [s] (its median time step when unknown)."""
    period = getattr(run, "sample_period_s", None)
    return float(period) if period else float(np.median(np.diff(np.asarray(run.t, float))))


@dataclass(frozen=True)
class Gap:
    """Ticks lost in ``path`` after the row at ``at_s`` [s] (run time): ``lost`` ticks of
    ``period_s`` [s]; it split the run (``split``) or was bridged."""

    path: str
    at_s: float
    lost: int
    period_s: float
    split: bool = True

    @property
    def length_s(self) -> float:
        """The time without rows [s]: the lost ticks."""
        return self.lost * self.period_s


@dataclass
class Split:
    """Runs after splitting: ``runs`` (segments and whole runs, in order), the ``gaps``
    and the ``jumps`` (:class:`~guardid.identify.jumps.Jump`) that split them, the segments
    ``dropped`` as too short ((name, rows)), the gaps' limit [lost ticks] and the cut-off
    [Hz] it was derived from."""

    runs: list
    gaps: list[Gap] = field(default_factory=list)
    dropped: list[tuple[str, int]] = field(default_factory=list)
    limit_ticks: int = 0
    cutoff_hz: float = math.nan
    jumps: list = field(default_factory=list)

    @property
    def split(self) -> bool:
        """Whether any run was split (at a gap or a jump) or lost a segment."""
        return bool(self.gaps or self.jumps or self.dropped)

    def lines(self, cutoff_hz: float | None = None) -> list[str]:
        """One line per splitting gap or jump and per dropped segment: where, how long, what it
        cost. ``cutoff_hz`` [Hz]: the cut-off used (the rows cut at the new ends); default
        the one the limit was derived from."""
        fc = float(cutoff_hz or self.cutoff_hz)
        out = []
        for g in self.gaps:
            edge = _new_end_rows(fc, g.period_s)
            out.append(
                f"{g.path}: gap at {g.at_s:.3f} s: {g.lost} ticks ({g.length_s:.3g} s) lost, "
                f"more than the {self.limit_ticks} a bridge may span at a {self.cutoff_hz:.3g} "
                f"Hz cut-off: run split there, conditioned as two; cost {g.lost + edge} rows "
                f"({g.lost} lost, {edge} at the new ends)"
            )
        out += [
            f"{j.path}: jump after {j.at_s:.3f} s: {j.joint} moved {j.step:.3g} between two "
            f"rows, {j.step / j.limit:.3g} x the {j.limit:.3g} its motor can drive it (rows "
            "lost without a gap in the ticks: a log cut or joined by hand?): run split there, "
            f"conditioned as two; cost {_new_end_rows(fc, j.period_s)} rows at the new ends"
            for j in self.jumps
        ]
        out += [
            f"{name}: {rows} rows between gaps, too short to condition: not used"
            for name, rows in self.dropped
        ]
        return out


def _new_end_rows(cutoff_hz: float, period_s: float) -> int:
    """Rows [-] a split costs at its two new ends: a cut-off period at each."""
    return 2 * math.ceil(1.0 / (cutoff_hz * period_s))


def split_run(run, limit_ticks: int, min_rows: int = 10, reach=None):
    """(segments, gaps, dropped, jumps) of one Run: split after every gap of more than
    ``limit_ticks`` lost ticks and at every jump against ``reach`` (a
    :class:`~guardid.identify.jumps.Reach`, or None: no jump is looked for); segments of
    fewer than ``min_rows`` rows are dropped. A run without ticks (a foreign log off the
    tick grid) is returned whole."""
    if run.ticks is None or len(run.ticks) < 2:
        return [run], [], [], []
    period = _period(run)
    jumps = find_jumps(run, reach, period)
    lost = np.diff(np.asarray(run.ticks, dtype=np.int64)) - 1
    at = np.flatnonzero(lost > limit_ticks) + 1
    t = np.asarray(run.t, dtype=float)
    gaps = [Gap(run.path, float(t[k - 1]), int(lost[k - 1]), period) for k in at]
    cuts = np.union1d([j.index for j in jumps], at).astype(np.int64)
    if not cuts.size:
        return [run], [], [], []
    bounds = np.concatenate([[0], cuts, [len(run.t)]])
    segments, dropped = [], []
    for number, (a, b) in enumerate(zip(bounds[:-1], bounds[1:], strict=True), start=1):
        name = f"{run.path}[{number}]"
        if b - a < min_rows:
            dropped.append((name, int(b - a)))
            continue
        segments.append(run_rows(run, a, b, path=name, source=run.source or run.path))
    return segments, gaps, dropped, jumps


def run_rows(run, a: int, b: int, **changes):
    """``run``'s rows a .. b - 1 (every per-row array), with ``changes`` to its other
    fields."""
    parts = {k: None if getattr(run, k, None) is None else getattr(run, k)[a:b] for k in _PER_RUN}
    return replace(run, **parts, **changes)


def split_runs(
    runs, cutoff_hz: float | None = None, highest_harmonic_hz=None, description=None
) -> Split:
    """Every run split at its long gaps and its jumps (:func:`split_run`), the gaps' limit
    from ``cutoff_hz`` [Hz] (given, or stored in a params file) or else the highest cut-off
    candidate (:func:`highest_cutoff_hz`, informed by ``highest_harmonic_hz`` [Hz]: the
    excitation's, from a guardid log's header); the jumps against ``description``'s drives
    (:mod:`guardid.identify.jumps`; None: no jump is looked for)."""
    runs = list(runs)
    reach = drive_reach(description) if description is not None else None
    timed = [r for r in runs if r.ticks is not None and len(r.t) > 1]
    if not timed:
        return Split(runs)
    harmonic = highest_harmonic_hz or getattr(runs[0], "highest_harmonic_hz", None)
    fc = float(cutoff_hz) if cutoff_hz else highest_cutoff_hz(timed, harmonic)
    period = min(_period(r) for r in timed)
    limit = bridge_limit_ticks(fc, period)
    least = min_segment_rows(fc, period)
    out = Split([], limit_ticks=limit, cutoff_hz=fc)
    for run in runs:
        segments, gaps, dropped, jumps = split_run(run, limit, least, reach)
        out.runs += segments
        out.gaps += gaps
        out.dropped += dropped
        out.jumps += jumps
    return out
