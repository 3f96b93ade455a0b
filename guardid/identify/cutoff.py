"""The default low-pass cut-off, chosen from the data by cross-validation.

Candidates are the preferred numbers (Renard R10: 1, 1.25, 1.6, 2, 2.5, 3.15, 4, 5, 6.3, 8
x 10^k Hz) between the positions' 99.5 % energy bandwidth (below it the filter would cut
the motion itself) and min(0.4 x Nyquist, :data:`SPAN` x that bandwidth). When a guardid
log names its excitation, the bandwidth is its highest harmonic, and the cut-off measured
best on guardid captures, :data:`~guardid.conditioning.bandwidth.HARMONIC_FACTOR` x that
harmonic, is a candidate too and is preferred when its score is within :data:`TOLERANCE` of
the best (the stick/slip of PID-tracked joints leaves the score flat over a wide range).

For each candidate the runs are conditioned with it, the rows are split into contiguous
time blocks (each run into ceil(4 / runs) blocks), and least squares fitted on all blocks
but one predicts the held-out block's *measured* effort (before the low-pass). The score is
the stacked relative rms error over every held-out row, rms(tau_meas - A theta) /
rms(tau_meas). The measured effort's noise does not depend on the candidate, so the score
trades the two ways a cut-off fails: too low, the model's prediction lacks the torque the
filter removed from the motion; too high, the differentiated noise enters the regressor
(biasing least squares toward zero) and its predictions. The candidate with the lowest
score is used (each candidate fitted twice when the model has Coulomb columns: as they
are, and low-passed like the effort, the better one kept), or the lowest candidate scoring
within :data:`TOLERANCE` of it (the smoother conditioning when the data cannot tell them
apart, as in the one-standard-error rule of cross-validation). Every candidate is scored on
the same instants (one decimation for all) and
the same rows (those usable under the middle candidate's conditioning).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from guardid.conditioning.bandwidth import (
    HARMONIC_FACTOR,
    MAX_NYQUIST_FRACTION,
    MIN_CUTOFF_HZ,
    clip_cutoff,
    energy_bandwidth,
)

R10 = (1.0, 1.25, 1.6, 2.0, 2.5, 3.15, 4.0, 5.0, 6.3, 8.0)
SPAN = 16.0
"""Highest candidate = this x the motion's bandwidth (or 0.4 x Nyquist if lower) [-]."""
MIN_BLOCKS = 4
MIN_VARIANCE_GAIN = 2.0
"""A parallel filter is used only when it divides the geometric mean of the parameters'
variances by at least this [-] (a factor 2 in variance, sqrt 2 in standard deviation)."""
TOLERANCE = 0.02
"""A lower candidate whose score is within this fraction of the best one is preferred [-]."""


@dataclass
class CutoffChoice:
    """The chosen cut-off [Hz], why, and every candidate's held-out score [-]."""

    cutoff_hz: float
    reason: str
    candidates: list[float] = field(default_factory=list)
    scores: list[float] = field(default_factory=list)
    thetas: list[np.ndarray] = field(default_factory=list)
    bandwidth_hz: float = math.nan
    friction_filters: list[bool] = field(default_factory=list)

    @property
    def friction_filter(self) -> bool:
        """Whether the chosen candidate low-passes the Coulomb columns."""
        if not self.friction_filters:
            return False
        return self.friction_filters[self.candidates.index(self.cutoff_hz)]

    def table(self) -> str:
        """One line: candidate [Hz] = held-out score, the chosen one starred."""
        cells = [
            f"{c:g}{'*' if c == self.cutoff_hz else ''} {s:.3f}"
            for c, s in zip(self.candidates, self.scores, strict=True)
        ]
        return "held-out error per cut-off [Hz]: " + ", ".join(cells)


def candidate_cutoffs(low_hz: float, high_hz: float) -> list[float]:
    """Preferred numbers (R10) in [low_hz, high_hz] [Hz] (at least one: the clipped low)."""
    out = []
    for decade in range(-2, 5):
        for r in R10:
            f = round(r * 10.0**decade, 6)
            if low_hz <= f <= high_hz:
                out.append(f)
    return out or [float(np.clip(low_hz, MIN_CUTOFF_HZ, high_hz))]


def motion_bandwidth(runs, highest_harmonic_hz: float | None) -> float:
    """The excitation's highest harmonic [Hz] if known, else the largest 99.5 % energy
    bandwidth of the positions over the runs and joints."""
    if highest_harmonic_hz:
        return float(highest_harmonic_hz)
    return max(float(energy_bandwidth(r[0], r[1]).max()) for r in runs)


def choose_cutoff_cv(runs, score_fn, fs_hz: float, highest_harmonic_hz=None) -> CutoffChoice:
    """Cross-validated cut-off (module docstring).

    ``runs``: (t [s], q, effort) per run. ``score_fn(candidates, blocks_per_run)`` returns,
    per candidate, (held-out relative rms error, full-data estimate, friction columns filtered)
    (see
    :func:`guardid.identify.cutoff_scores.cutoff_scores`). ``fs_hz``: the logs' sample rate [Hz].
    """
    bandwidth = motion_bandwidth(runs, highest_harmonic_hz)
    top = MAX_NYQUIST_FRACTION * 0.5 * fs_hz
    low = max(MIN_CUTOFF_HZ, bandwidth)
    cands = candidate_cutoffs(min(low, top), min(top, SPAN * max(bandwidth, MIN_CUTOFF_HZ)))
    preferred = None
    if highest_harmonic_hz:  # the rule measured on guardid captures, if the data agree
        preferred = clip_cutoff(HARMONIC_FACTOR * float(highest_harmonic_hz), fs_hz)
        cands = sorted(set(cands) | {preferred})
    blocks = max(1, math.ceil(MIN_BLOCKS / len(runs)))
    scores, thetas, filters = score_fn(cands, blocks)
    s = np.asarray(scores, dtype=float)
    folds = blocks * len(runs)
    src = "excitation's highest harmonic" if highest_harmonic_hz else "positions' 99.5 % band"
    how = (
        f"{len(cands)} candidates from {cands[0]:g} to {cands[-1]:g} Hz ({src} {bandwidth:.3g} "
        f"Hz; {folds}-fold cross-validation over time blocks, predicting the measured effort)"
    )
    if not np.any(np.isfinite(s)):
        fc = preferred or cands[len(cands) // 2]
        return CutoffChoice(fc, f"no candidate could be scored ({how}); middle one taken",
                            cands, list(scores), list(thetas), bandwidth, filters)  # fmt: skip
    near_best = s <= (1.0 + TOLERANCE) * np.nanmin(s)
    if preferred is not None and near_best[cands.index(preferred)]:
        best = cands.index(preferred)
        why = f"{HARMONIC_FACTOR:g} x the excitation's highest harmonic, within "
        why += f"{100 * TOLERANCE:g} % of the lowest held-out error of {how}"
    else:
        best = int(np.flatnonzero(near_best)[0])
        why = f"lowest held-out error of {how}"
    if filters[best]:
        why += "; the Coulomb columns low-passed like the effort predicted it better"
    return CutoffChoice(cands[best], why, cands, list(scores), list(thetas), bandwidth, filters)


@dataclass
class ParallelChoice:
    """The parallel filter's cut-off [Hz] (None: off), why, and every candidate's
    log-determinant of the estimate's covariance (None stands for "off")."""

    hz: float | None
    reason: str
    candidates: list = field(default_factory=list)
    scores: list[float] = field(default_factory=list)
    decimate: int | None = None


def parallel_candidates(cutoff_hz: float) -> list[float]:
    """Preferred numbers (R10) from cutoff_hz / :data:`SPAN` (at least the 0.5 Hz floor) to
    cutoff_hz [Hz]: the parallel filter's candidates below the positions' cut-off."""
    low = max(MIN_CUTOFF_HZ, cutoff_hz / SPAN)
    return [c for c in candidate_cutoffs(low, cutoff_hz) if c <= cutoff_hz]


def choose_parallel_filter(cutoff_hz: float, score_fn) -> ParallelChoice:
    """The parallel filter (Gautier) that makes the estimate most precise.

    Parallel filtering low-passes the regressor's columns and the effort with one filter
    after the regressor was computed, so the model's equation holds on the filtered rows
    whatever that filter's cut-off, even one inside the excitation's band (it only drops
    information). What it removes is the differentiated encoder noise in the
    accelerations, whose power grows as f^4 up to the positions' cut-off: in a band where
    every harmonic carries the same acceleration, the low harmonics carry the most precise
    rows. No cut-off is then biased, so the one whose least-squares covariance is smallest
    (lowest log-determinant: D-optimality, independent of the parameters' units) is taken;
    "off" (the rows at the positions' cut-off as they are) is a candidate too.

    Real joints are not the model, though, and a parallel filter shifts weight between
    frequencies: a candidate whose estimate predicts the measured effort of held-out time
    blocks more than :data:`TOLERANCE` worse than "off" does (the cross-validation of the
    cut-off, same blocks) is not taken.

    And a parallel filter only pays where the differentiated noise dominates the rows'
    residual: it is taken only when it shrinks the geometric mean of the parameters'
    variances by at least :data:`MIN_VARIANCE_GAIN` (where the residual is mostly model
    error in the excitation's band, as on measured joints, the gain is small and the
    rows stay as they are).

    ``score_fn(hz)`` returns (log-determinant per parameter [-] of the covariance,
    held-out relative rms error [-]) for the parallel filter at ``hz`` [Hz] (None: off),
    NaN when not fitted.
    """
    cands = [None, *parallel_candidates(cutoff_hz)]
    pairs = [score_fn(hz) for hz in cands]
    scores = [float(p[0]) for p in pairs]
    held = np.array([float(p[1]) for p in pairs])
    s = np.asarray(scores, dtype=float)
    ok = np.isfinite(s) & np.isfinite(held)
    if np.isfinite(held[0]):
        ok &= held <= (1.0 + TOLERANCE) * held[0]
    span = f"{len(cands) - 1} candidates from {cands[1]:g} to {cands[-1]:g} Hz and off"
    if not np.any(ok):
        return ParallelChoice(None, f"parallel filter off (none of {span} could be fitted)",
                              cands, scores)  # fmt: skip
    best = int(np.flatnonzero(ok)[np.argmin(s[ok])])
    hz = cands[best]
    gain = float(np.exp(s[0] - s[best])) if np.isfinite(s[0]) else math.inf
    if hz is None or gain < MIN_VARIANCE_GAIN:
        return ParallelChoice(None, f"parallel filter off: the best of {span} shrinks the "
                              f"variances by {gain:.2f} x only (< {MIN_VARIANCE_GAIN:g} x)",
                              cands, scores)  # fmt: skip
    why = (f"parallel filter {hz:g} Hz on the regressor and the effort: the smallest "
           f"covariance of {span} (variances {gain:.3g} x smaller than off, geometric "
           f"mean), held-out error within {100 * TOLERANCE:g} % of off's")  # fmt: skip
    return ParallelChoice(hz, why, cands, scores)
