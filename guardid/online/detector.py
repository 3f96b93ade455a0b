"""Change detection on a stream of online estimates: "payload changed at 31.2 s: ...".

:class:`ChangeDetector` watches the estimates theta(t) of one online estimator, by default
the first-moment (gravity) base parameters (names MX*, MY*, MZ*): they are the best
identified ones and any payload with a mass changes them. Per watched parameter i:

1. **Hold-off** (``holdoff_s`` after the first estimate): the estimator is still converging
   from its prior; nothing is watched.
2. **Reference** (the next ``reference_s``, one excitation period by default): the
   reference value r_i = mean of theta_i and the estimate's own spread
   sigma_i = std of theta_i over the window, floored at ``rel_floor`` x |r_i| and
   ``abs_floor`` (a steady estimator would otherwise give a spread near zero).
3. **Armed**: a two-sided CUSUM of the standardised deviation z_i = (theta_i - r_i) / sigma_i,
   integrated over time (dt between estimates, capped at ``max_step_s``):

       G+_i <- max(0, G+_i + (z_i - kappa) dt),   G-_i <- max(0, G-_i + (-z_i - kappa) dt)

   [G in sigma seconds]. An alarm is raised when some G exceeds ``h``. The estimate's
   fluctuations within +-kappa sigma (what the reference window showed, with margin) never
   accumulate; a step of Delta = m sigma reaches the alarm after about h / (m - kappa) s.
   The change time is the CUSUM change-point estimate refined: the last instant before the
   alarm at which that G was zero is where the estimate left the +-kappa sigma band; the
   change time is the last instant before that at which the estimate was still within
   ``onset_z`` sigma of the reference on that side (searched over ``lookback_s``).
4. **Settling**: the new values are the mean of theta over the last ``new_s`` before
   ``settle_s`` after the change time; the report is issued then, and the detector goes back
   to step 2 with a fresh reference (so a later change is reported too).

Times are those of the estimates, i.e. the instants of the motion the estimates describe
(the online tracker removes its conditioning and guard delays), not the arrival times.
"""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class DetectorSettings:
    """Tuning of :class:`ChangeDetector` (see the module docstring); times in s.

    ``watch``: names of the watched parameters (None = the first-moment ones, all if none).
    ``kappa`` [sigma], ``h`` [sigma s], ``rel_floor`` [-], ``abs_floor`` [unit of theta].
    """

    watch: tuple[str, ...] | None = None
    holdoff_s: float = 10.0
    reference_s: float = 10.0
    kappa: float = 3.0
    h: float = 1.0
    rel_floor: float = 0.03
    abs_floor: float = 1e-6
    settle_s: float = 5.0
    new_s: float = 1.0
    max_step_s: float = 0.1
    onset_z: float = 1.0
    lookback_s: float = 5.0


@dataclass(frozen=True)
class ChangeReport:
    """A detected change: ``time_s`` [s] change time, ``alarm_s`` when the CUSUM fired,
    ``report_s`` when the new values were taken; ``before``/``after`` of ``names`` (SI units
    ``units``); ``sigma`` the reference spread."""

    method: str
    time_s: float
    alarm_s: float
    report_s: float
    names: tuple[str, ...]
    before: np.ndarray
    after: np.ndarray
    sigma: np.ndarray
    units: tuple[str, ...]

    def __str__(self) -> str:
        vals = ", ".join(
            f"{n} {b:.4g} -> {a:.4g}{' ' + u if u else ''}"
            for n, b, a, u in zip(self.names, self.before, self.after, self.units, strict=True)
        )
        return f"payload changed at {self.time_s:.1f} s ({self.method.upper()}): {vals}"


class ChangeDetector:
    """CUSUM change detector on one estimator's estimates (module docstring).

    ``names`` (b,) names of the estimate's components; ``method`` a label for the reports;
    ``units`` (b,) their SI units (for the report text).
    """

    def __init__(self, names, method: str = "", settings: DetectorSettings | None = None,
                 units=None):  # fmt: skip
        self.settings = s = settings or DetectorSettings()
        names = tuple(names)
        watch = s.watch or tuple(x for x in names if x.startswith(("MX", "MY", "MZ"))) or names
        missing = [x for x in watch if x not in names]
        if missing:
            raise ValueError(f"watch: unknown parameters {', '.join(missing)}")
        self.index = np.array([names.index(x) for x in watch], dtype=int)
        self.names = tuple(watch)
        all_units = tuple(units) if units is not None else ("",) * len(names)
        self.units = tuple(all_units[i] for i in self.index)
        self.method = method
        self.reports: list[ChangeReport] = []
        self.state = "holdoff"
        self._t0: float | None = None
        self._t_prev: float | None = None
        self._phase_start = 0.0
        self._buf_t: list[float] = []
        self._buf: list[np.ndarray] = []
        self.ref = None
        self.sigma = None
        self.onset = None
        self.alarm = None

    def update(self, t: float, theta) -> ChangeReport | None:
        """One estimate at time ``t`` [s]; returns a report when one is completed."""
        s = self.settings
        x = np.asarray(theta, dtype=float)[self.index]
        if self._t0 is None:
            self._t0 = self._phase_start = t
            self._t_prev = t
        dt = min(max(t - self._t_prev, 0.0), s.max_step_s)
        self._t_prev = t
        if self.state == "holdoff":
            if t - self._t0 >= s.holdoff_s:
                self._start_reference(t)
            return None
        if self.state == "reference":
            self._buf_t.append(t)
            self._buf.append(x)
            if t - self._phase_start >= s.reference_s:
                window = np.asarray(self._buf)
                self.ref = window.mean(axis=0)
                spread = window.std(axis=0)
                self.sigma = np.maximum(spread, np.maximum(s.rel_floor * np.abs(self.ref),
                                                           s.abs_floor))  # fmt: skip
                n = len(self.index)
                self._g = np.zeros((2, n))
                self._recent = deque()
                self._zero_t = np.full((2, n), t)
                self.state = "armed"
                self._buf_t, self._buf = [], []
            return None
        if self.state == "armed":
            z = (x - self.ref) / self.sigma
            g = self._g
            g[0] = np.maximum(0.0, g[0] + (z - s.kappa) * dt)
            g[1] = np.maximum(0.0, g[1] + (-z - s.kappa) * dt)
            zero = g <= 0.0
            self._zero_t[zero] = t
            self._recent.append((t, z))
            while self._recent[0][0] < t - s.lookback_s:
                self._recent.popleft()
            fired = g > s.h
            if fired.any():
                self.onset = self._onset(fired)
                self.alarm = t
                self.state = "settling"
                self._buf_t, self._buf = [], []
            return None
        # settling: keep the last new_s of estimates until settle_s after the change time
        self._buf_t.append(t)
        self._buf.append(x)
        while self._buf_t and self._buf_t[0] < t - s.new_s:
            self._buf_t.pop(0)
            self._buf.pop(0)
        if t - self.onset < s.settle_s:
            return None
        rep = ChangeReport(
            method=self.method,
            time_s=self.onset,
            alarm_s=self.alarm,
            report_s=t,
            names=self.names,
            before=self.ref.copy(),
            after=np.asarray(self._buf).mean(axis=0),
            sigma=self.sigma.copy(),
            units=self.units,
        )
        self.reports.append(rep)
        self._start_reference(t)
        return rep

    def _onset(self, fired: np.ndarray) -> float:
        """Change time [s]: per fired (side, parameter), the last recent instant before G left
        zero with the standardised deviation on that side at most ``onset_z``; the earliest."""
        times = []
        for side, i in zip(*np.nonzero(fired), strict=True):
            left = self._zero_t[side, i]
            sign = 1.0 if side == 0 else -1.0
            best = left
            for t, z in reversed(self._recent):
                if t <= left and sign * z[i] <= self.settings.onset_z:
                    best = t
                    break
            times.append(best)
        return float(min(times))

    def _start_reference(self, t: float) -> None:
        self.state = "reference"
        self._phase_start = t
        self._buf_t, self._buf = [], []


def detect_changes(t, theta, names, method: str = "", settings=None, units=None):
    """Run a :class:`ChangeDetector` over a whole track: t (K,) [s], theta (K, b)."""
    det = ChangeDetector(names, method, settings, units)
    for ti, th in zip(np.asarray(t, float), np.asarray(theta, float), strict=True):
        det.update(float(ti), th)
    return det.reports
