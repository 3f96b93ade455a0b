"""Shared pieces of the reproductions: fixed-step integration, noise, metrics, the printer.

Everything is SI (s, rad, kg, m, N m). Integration is the classical fourth-order Runge-Kutta
method with a fixed step on the models' fast single-sample evaluators ``mass_matrix_1`` /
``bias_1`` (the same equations as ``forward_dynamics``, without its per-call overhead).
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np


def accel(model, q, qd, tau, params) -> tuple[float, float]:
    """q'' = M^-1 (tau - bias) for a 2-DOF model, one sample [rad/s^2] (2x2 Cramer solve)."""
    (a, c), (_, d) = np.asarray(model.mass_matrix_1(q, params)).tolist()  # Python floats:
    b0, b1 = np.asarray(model.bias_1(q, qd, params)).tolist()  # the same values, faster
    r0, r1 = tau[0] - b0, tau[1] - b1
    det = a * d - c * c
    return (d * r0 - c * r1) / det, (a * r1 - c * r0) / det


def rk4_step(model, t: float, x: list, h: float, tau_fn: Callable, params_fn: Callable) -> list:
    """One RK4 step of length h [s] of x = (q1, q2, q1', q2') for a 2-DOF model.

    ``tau_fn(t)`` -> generalised forces (2,) [N m]; ``params_fn(t)`` -> model parameters
    (each called once per distinct time: t, t + h/2, t + h).
    """

    def f(tt, s):
        a0, a1 = accel(model, s[:2], s[2:], *tt)
        return (s[2], s[3], a0, a1)

    tm = t + 0.5 * h
    mid = (tau_fn(tm), params_fn(tm))
    k1 = f((tau_fn(t), params_fn(t)), x)
    x2 = [x[i] + 0.5 * h * k1[i] for i in range(4)]
    k2 = f(mid, x2)
    x3 = [x[i] + 0.5 * h * k2[i] for i in range(4)]
    k3 = f(mid, x3)
    x4 = [x[i] + h * k3[i] for i in range(4)]
    k4 = f((tau_fn(t + h), params_fn(t + h)), x4)
    return [x[i] + h / 6.0 * (k1[i] + 2.0 * k2[i] + 2.0 * k3[i] + k4[i]) for i in range(4)]


DEFAULT_SEEDS = 15
"""Noise draws behind every stochastic row (``guardid reproduce --seeds``): each such row is
printed as the median and the worst over this many seeds (one draw can be lucky: seed000-fast's
noisy beta = 1e-4 row reads amplitude ratio 1.000 with seed 0 and 0.969 with seed 1)."""


def noise_seeds(first: int, count: int) -> list[int]:
    """The seeds ``first`` .. ``first + count - 1`` (count >= 1)."""
    if count < 1:
        raise ValueError(f"--seeds must be >= 1, got {count}")
    return list(range(int(first), int(first) + int(count)))


def median_worst(values, worst: str = "max") -> tuple[float, float]:
    """(median, worst) of one figure over seeds. ``worst``: 'max' (largest), 'abs' (largest
    |x|, sign kept), 'dev1' (farthest from 1), 'time' (latest; None = never, the worst)."""
    x = np.array([math.inf if v is None else float(v) for v in values])
    med = float(np.median(x))
    if worst == "abs":
        return med, float(x[np.argmax(np.abs(x))])
    if worst == "dev1":
        return med, float(x[np.argmax(np.abs(x - 1.0))])
    return med, float(np.max(x))


def settle_time(t, err, threshold: float, t_from: float, t_to: float = math.inf):
    """(first, settled) times [s] after ``t_from`` at which ``err`` < threshold.

    ``first``: first sample in [t_from, t_to) below the threshold; ``settled``: start of the
    final stretch of that window that stays below it. Each is relative to ``t_from``, or
    None if never reached.
    """
    t = np.asarray(t)
    sel = (t >= t_from) & (t < t_to)
    tt, ee = t[sel], np.asarray(err)[sel]
    below = ee < threshold
    if not below.any():
        return None, None
    first = float(tt[np.argmax(below)] - t_from)
    if below[-1]:
        above = np.flatnonzero(~below)
        idx = 0 if above.size == 0 else above[-1] + 1
        settled = float(tt[idx] - t_from)
    else:
        settled = None
    return first, settled


def fmt_time_pi(t) -> str:
    """'0.48 pi s (1.51 s)' or 'never' (None or inf)."""
    if t is None or not math.isfinite(t):
        return "never"
    return f"{t / math.pi:.2f} pi s ({t:.2f} s)"


@dataclass
class Report:
    """What a reproduction prints: title, model repairs, assumptions, result tables.

    ``lines`` collect the result sections in order; ``summary`` holds the numbers the tests
    check (plain floats / dicts); ``series`` holds the time series the plots draw.
    """

    name: str
    title: str
    repairs: list[str] = field(default_factory=list)
    assumptions: list[str] = field(default_factory=list)
    lines: list[str] = field(default_factory=list)
    summary: dict = field(default_factory=dict)
    series: dict = field(default_factory=dict)
    wall_time_s: float = 0.0
    _t0: float = field(default_factory=time.perf_counter, repr=False)

    def add(self, *lines: str) -> None:
        """Append result lines."""
        self.lines.extend(lines)

    def table(self, header: list[str], rows: list[list], widths=None) -> None:
        """Append a fixed-width table; floats printed with 4 decimals, str as given."""
        cells = [[_cell(c) for c in r] for r in rows]
        if widths is None:
            widths = [max(len(h), *(len(r[i]) for r in cells)) for i, h in enumerate(header)]
        fmt = "  ".join(f"{{:>{w}}}" for w in widths)
        self.add(fmt.format(*header), fmt.format(*("-" * w for w in widths)))
        self.add(*(fmt.format(*r) for r in cells))

    def finish(self) -> Report:
        """Stamp the wall time since the report was created."""
        self.wall_time_s = time.perf_counter() - self._t0
        return self

    def text(self) -> str:
        """The printed form."""
        out = [f"== guardid reproduce {self.name}: {self.title}", ""]
        out.append("Model repairs:")
        out.extend(f"  - {r}" for r in self.repairs) if self.repairs else out.append("  none")
        out.append("Assumptions (where the paper is silent):")
        out.extend(f"  - {a}" for a in self.assumptions)
        out.append("")
        out.extend(self.lines)
        out.append("")
        out.append(f"wall time: {self.wall_time_s:.1f} s")
        return "\n".join(out)


def _cell(c) -> str:
    if isinstance(c, str):
        return c
    if c is None:
        return "-"
    if isinstance(c, (int, np.integer)):
        return str(c)
    return f"{c:.4f}"
