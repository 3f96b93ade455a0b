"""Live parameter uncertainty: how well the rows so far identify each base parameter.

:class:`DecimatedLS` is a growing-window least squares fed by the online tracker
(:class:`guardid.online.OnlineIdentifier` with method ``"ls"``): its square-root information
grows row by row (a QR update per row it takes, never a refit), and it takes every k-th used
row only, k the offline pipeline's decimation (about the cut-off's Nyquist rate), because
rows closer than that share their filtered noise and would make the standard deviations
look smaller than they are.

:func:`assess` is the rule ``capture --until-std`` stops on and the HTML report's verdict
uses: a parameter is *resolved* when its standard deviation is within the target share of
its magnitude, or of :data:`SMALL_FRACTION` of its kind's scale when it is smaller than that
(:func:`guardid.online.tracker.prior_half_widths`: the largest described value of the
parameters with the same unit). A relative standard deviation says little of a parameter
that is tiny beside the others of its kind (a product of inertia that the design makes
nearly zero): it may be known to a fraction of a per cent of its kind's scale and still
carry a relative std of 100 %. A parameter the run does not excite has a large standard
deviation on both readings, and stays unresolved.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from guardid.estimators import LeastSquares

ZERO_SIGMAS = 3.0  #: an estimate within this many std of zero is "consistent with zero"
SMALL_FRACTION = 0.1
"""A parameter smaller than this share of its kind's scale is judged against that share [-]
(the same floor as the batch Hopfield box, :func:`guardid.identify.methods.run_hopfield`)."""


class DecimatedLS:
    """Least squares on every ``every``-th :meth:`update` (a row of 1..n joint equations).

    After the first row it takes: ``theta_`` (b,), ``std_`` (b,) and ``rel_std_`` (b,) [%]
    of :class:`guardid.estimators.LeastSquares`, ``cond_``; ``rows_`` the rows taken.
    """

    def __init__(self, every: int = 1) -> None:
        self.every = max(1, int(every))
        self.ls = LeastSquares()
        self._seen = 0
        self.rows_ = 0

    @staticmethod
    def every_for(cutoff_hz: float, dt_s: float) -> int:
        """The offline pipeline's spaced rows (``identify --spaced-rows``): one row per half
        cut-off period [-], whose errors are about independent (the white std holds)."""
        return max(1, int(1.0 / (dt_s * 2.0 * cutoff_hz)))

    def update(self, A_k, y_k) -> DecimatedLS:
        self._seen += 1
        if (self._seen - 1) % self.every == 0:
            self.ls.update(A_k, y_k)
            self.rows_ += 1
        return self

    def __getattr__(self, name):
        if name.endswith("_") and not name.startswith("_"):
            return getattr(self.__dict__["ls"], name)
        raise AttributeError(name)


@dataclass(frozen=True)
class Assessment:
    """Per base parameter: ``resolved`` (b,) bool; ``zero_like`` (b,) bool (within
    :data:`ZERO_SIGMAS` std of zero); ``score`` (b,) [%]: 100 std / max(|theta|,
    :data:`SMALL_FRACTION` x its kind's scale), the relative std for all but the tiny.
    ``slowest``: index of the largest score among the unresolved (else of all)."""

    names: tuple[str, ...]
    resolved: np.ndarray
    zero_like: np.ndarray
    score: np.ndarray
    target_pct: float

    @property
    def all_resolved(self) -> bool:
        return bool(self.resolved.all())

    @property
    def slowest(self) -> int:
        if self.all_resolved:
            return int(np.argmax(self.score))
        return int(np.argmax(np.where(self.resolved, -np.inf, self.score)))

    @property
    def unresolved(self) -> tuple[str, ...]:
        return tuple(n for n, r in zip(self.names, self.resolved, strict=True) if not r)

    @property
    def worst_pct(self) -> float:
        """The largest score [%]."""
        return float(self.score.max()) if self.score.size else float("nan")


def assess(theta, std, names, nominal, target_pct: float) -> Assessment:
    """Which base parameters the estimate ``theta`` (b,) with ``std`` (b,) resolves to
    ``target_pct`` [%] (module docstring); ``nominal`` (b,) the described values."""
    from guardid.online.tracker import prior_half_widths

    theta = np.asarray(theta, dtype=float)
    std = np.asarray(std, dtype=float)
    floor = SMALL_FRACTION * prior_half_widths(np.asarray(nominal, dtype=float), names)
    finite = np.isfinite(theta) & np.isfinite(std)
    zero_like = finite & (np.abs(theta) < ZERO_SIGMAS * std)
    with np.errstate(divide="ignore", invalid="ignore"):
        score = 100.0 * std / np.maximum(np.abs(theta), floor)
    score = np.where(finite, score, np.inf)
    return Assessment(tuple(names), score <= target_pct, zero_like, score, float(target_pct))


def describe(a: Assessment) -> str:
    """One line: the verdict of :func:`assess` and, when not resolved, what would help."""
    zero = [n for n, z in zip(a.names, a.zero_like, strict=True) if z]
    tail = f"; consistent with zero: {', '.join(zero)}" if zero else ""
    if a.all_resolved:
        return f"identified to {a.worst_pct:.2g} % (target {a.target_pct:g} %){tail}"
    k = a.slowest
    return (
        f"not identified to {a.target_pct:g} %: {', '.join(a.unresolved)} "
        f"(slowest {a.names[k]} at {a.score[k]:.3g} %); a longer run, or an excitation that "
        f"moves {a.names[k]}'s column more, would help{tail}"
    )


CHECK_EVERY_S = 0.5
"""``capture --until-std`` re-assesses the live estimate every this much telemetry [s]."""


class UntilStd:
    """The live estimate ``capture --until-std`` stops on (module docstring).

    Fed every telemetry row (:meth:`update`); :meth:`done` is True once the run has covered
    at least one period of ``trajectory``, the least squares has more than 3 rows per
    parameter, and :func:`assess` resolves every base parameter to ``target_pct`` [%]. The
    rows are those of the offline pipeline as closely as a causal filter allows: the current
    sensor's effort and whole rows dropped near stiction, so that the live standard
    deviations are not smaller than ``guardid identify``'s on the same log.
    """

    def __init__(self, description, trajectory, target_pct: float) -> None:
        from guardid.identify.acceleration_run import STICTION_GUARD_PERIODS
        from guardid.online.tracker import LIVE_LS, OnlineIdentifier

        self.target_pct = float(target_pct)
        self.tracker = OnlineIdentifier.for_trajectory(
            description, (LIVE_LS,), trajectory, effort="current", per_joint=False,
            detector=False, lam=1.0, rho=None, keep_history=False,
            guard_periods=STICTION_GUARD_PERIODS,
        )  # fmt: skip
        self.ls = self.tracker.estimators[LIVE_LS]
        self.period_s = float(getattr(trajectory, "period", 0.0) or 0.0)
        self._every = max(1, int(round(CHECK_EVERY_S / self.tracker.dt)))
        self.t_s = 0.0
        self._rows = 0
        self._assessment: Assessment | None = None

    def update(self, time_s: float, q_rad, current_a, voltage_v=None) -> None:
        self.tracker.update(time_s, q_rad, current_a, voltage_v)
        self.t_s = float(time_s)
        self._rows += 1
        if self._rows % self._every == 0:
            self._assessment = None  # re-assessed on the next ask

    @property
    def names(self) -> tuple[str, ...]:
        return self.tracker.names

    def assessment(self) -> Assessment | None:
        """:func:`assess` of the estimate so far (None before enough rows)."""
        if self.ls.rows_ <= 3 * len(self.names):
            return None
        if self._assessment is None:
            self._assessment = assess(
                self.ls.theta_, self.ls.std_, self.names, self.tracker.nominal, self.target_pct
            )
        return self._assessment

    def done(self) -> bool:
        a = self.assessment()
        return a is not None and self.t_s >= self.period_s and a.all_resolved

    def verdict(self) -> str:
        a = self.assessment()
        if a is None:
            return f"not identified: too few usable rows in {self.t_s:.1f} s"
        return f"{describe(a)}, after {self.t_s:.1f} s"


class LiveDisplay:
    """``capture --until-std``'s progress: on a terminal a block, one line per parameter
    (estimate, relative std, a bar) under the link counters, rewritten in place; elsewhere
    one line (rows, link counters, cond, how many are resolved, the slowest)."""

    BAR = 20  #: characters of a full bar (4 x the target)

    def __init__(self, live: UntilStd, stream, tracker=None) -> None:
        self.live = live
        self.stream = stream
        self.tracker = tracker
        self.tty = bool(getattr(stream, "isatty", lambda: False)())
        self._drawn = 0

    def summary(self, c: dict) -> str:
        head = f"rows {c['rows']:6d}  lost {c['lost']:4d}  CRC {c['crc_errors']:3d}"
        a = self.live.assessment()
        if a is None:
            return f"{head}  | collecting rows"
        k = a.slowest
        return (
            f"{head}  | cond {self.live.ls.cond_:.4g}  resolved {int(a.resolved.sum())}/"
            f"{len(a.names)}  slowest {a.names[k]} {a.score[k]:.3g} % "
            f"(target {self.live.target_pct:g} %)"
        )

    def lines(self, c: dict) -> list[str]:
        out = [self.summary(c)]
        a = self.live.assessment()
        if a is None:
            return out
        theta, target = self.live.ls.theta_, self.live.target_pct
        for k, name in enumerate(a.names):
            n = min(self.BAR, int(round(self.BAR * a.score[k] / (4 * target))))
            mark = "ok" if a.resolved[k] else ".."
            kind = "of scale" if a.zero_like[k] else "        "
            out.append(
                f"  {name:6s} {theta[k]:+11.4g}  {a.score[k]:8.3g} % {kind} {mark} " + "#" * n
            )
        return out

    def show(self, c: dict) -> None:
        if not self.tty:
            self.stream.write("\r" + self.summary(c) + "   ")
            self.stream.flush()
            return
        lines = self.lines(c)
        up = f"\x1b[{self._drawn}F" if self._drawn else "\r"
        self.stream.write(up + "".join(f"\x1b[2K{x}\n" for x in lines))
        self.stream.flush()
        self._drawn = len(lines)
