"""Live parameter uncertainty: how well the rows so far identify each base parameter.

:class:`DecimatedLS` is a growing-window least squares fed by the online tracker
(:class:`guardid.online.OnlineIdentifier` with method ``"ls"``): its square-root information
grows row by row (a QR update per row it takes, never a refit), and it takes every k-th used
row only, k the offline pipeline's decimation (about the cut-off's Nyquist rate), because
rows closer than that share their filtered noise and would make the standard deviations
look smaller than they are.

:func:`assess` is the rule ``capture --until-std`` stops on and the HTML report's verdict
uses: a parameter is *resolved* when its relative standard deviation is within the target,
or, when its estimate is within 3 std of zero (a relative std then says nothing: the
parameter may be zero), when its standard deviation is within the target share of its
kind's scale (:func:`guardid.online.tracker.prior_half_widths`: the largest described value
of the parameters with the same unit). A parameter the run does not excite has a large
standard deviation in both readings, and stays unresolved.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from guardid.estimators import LeastSquares

ZERO_SIGMAS = 3.0  #: an estimate within this many std of zero is "consistent with zero"


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
        """The offline pipeline's decimation: one row per half cut-off period [-]."""
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
    """Per base parameter: ``resolved`` (b,) bool, ``zero_like`` (b,) bool, ``score`` (b,)
    [%]: the relative std, or for a zero-like estimate the std relative to its kind's scale.
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
        pool = (
            np.where(~self.resolved, self.score, -np.inf) if not self.all_resolved else self.score
        )
        return int(np.argmax(pool))

    @property
    def unresolved(self) -> tuple[str, ...]:
        return tuple(n for n, r in zip(self.names, self.resolved, strict=True) if not r)

    @property
    def worst_resolved_pct(self) -> float:
        """The largest relative std [%] among the parameters distinguishable from zero."""
        rel = self.score[~self.zero_like]
        return float(rel.max()) if rel.size else float("nan")


def assess(theta, std, names, nominal, target_pct: float) -> Assessment:
    """Which base parameters the estimate ``theta`` (b,) with ``std`` (b,) resolves to
    ``target_pct`` [%] (module docstring); ``nominal`` (b,) the described values."""
    from guardid.online.tracker import prior_half_widths

    theta = np.asarray(theta, dtype=float)
    std = np.asarray(std, dtype=float)
    scale = prior_half_widths(np.asarray(nominal, dtype=float), names)
    finite = np.isfinite(theta) & np.isfinite(std)
    zero_like = finite & (np.abs(theta) < ZERO_SIGMAS * std)
    with np.errstate(divide="ignore", invalid="ignore"):
        rel = np.where(zero_like, 100.0 * std / scale, 100.0 * std / np.abs(theta))
    rel = np.where(finite, rel, np.inf)
    return Assessment(tuple(names), rel <= target_pct, zero_like, rel, float(target_pct))


def describe(a: Assessment) -> str:
    """One line: the verdict of :func:`assess` and, when not resolved, what would help."""
    zero = [n for n, z in zip(a.names, a.zero_like, strict=True) if z]
    tail = f"; consistent with zero: {', '.join(zero)}" if zero else ""
    if a.all_resolved:
        worst = a.worst_resolved_pct
        head = f"identified to {worst:.2g} % relative std" if np.isfinite(worst) else "identified"
        return f"{head} (target {a.target_pct:g} %){tail}"
    k = a.slowest
    return (
        f"not identified to {a.target_pct:g} %: {', '.join(a.unresolved)} "
        f"(slowest {a.names[k]} at {a.score[k]:.3g} %); a longer run, or an excitation that "
        f"moves {a.names[k]}'s column more, would help{tail}"
    )
