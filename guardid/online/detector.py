"""Change detection for online identification: "payload changed at 31.2 s: ...".

:class:`ChangeDetector` watches one online estimator through its a-priori prediction
residuals e_j = y_j - A_j theta (per joint equation j, before the row updates theta): a
payload changes the torque the model predicts at once, long before an estimator with a
long memory has moved. Per estimator:

1. **Hold-off** (``holdoff_s`` after the first row): the estimator is still converging from
   its prior; nothing is watched.
2. **Reference** (the next ``reference_s``): each joint's residual scale sigma_j = RMS of
   e_j over the window, and the watched estimates' (by default the first moments MX*, MY*,
   MZ*: any payload with a mass changes them) mean and spread.
3. **Armed**: a two-sided CUSUM per joint of z_j = e_j / sigma_j over the rows,

       G+_j <- max(0, G+_j + z_j - kappa),   G-_j <- max(0, G-_j - z_j - kappa)

   [sigma x rows]; residuals within +-``kappa`` sigma never accumulate, a bias of m sigma
   reaches the alarm ``h`` after about h / (m - kappa) rows. At the alarm the change time
   is the CUSUM change-point estimate: the last row of that joint before the alarm at which
   that G was zero. When the joint had no rows for a while (held near stiction: a robot
   often picks a load up at rest) the change lies somewhere in that gap, so the alarm also
   gives the first row of the joint after it, and the report names the interval. The
   caller (:class:`guardid.online.OnlineIdentifier`) then discards the estimator's
   information on the changed parameters and replays the rows since that time.
4. **Settling**: the new values are the mean of the watched estimates over the last
   ``new_s`` before ``settle_s`` after the change time (after the end of the gap, if any).
   They are reported when some watched estimate moved beyond its uncertainty: by more than
   ``n_sigma`` x its spread in the reference window and more than ``rel_floor`` x its old
   value. Either way the detector then re-arms at once with the residual scales it had (a
   payload hardly changes the noise) while it learns a fresh reference over the next
   ``reference_s``, which then replaces them: a later change is caught from ``settle_s``
   after the last one on.

Times are those of the rows, i.e. the instants of the motion they describe (the tracker
removes its conditioning and guard delays), not the arrival times.
"""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass

import numpy as np

MIN_REFERENCE_ROWS = 10
"""A joint equation needs this many rows in the reference window to be watched [-]."""


@dataclass(frozen=True)
class DetectorSettings:
    """Tuning of :class:`ChangeDetector` (see the module docstring); times in s.

    ``watch``: names of the watched parameters (None = the first-moment ones, all if none).
    ``kappa`` [sigma], ``h`` [sigma x rows], ``n_sigma`` [-], ``rel_floor`` [-].
    """

    watch: tuple[str, ...] | None = None
    holdoff_s: float = 10.0
    reference_s: float = 5.0
    kappa: float = 4.0
    h: float = 40.0
    settle_s: float = 5.0
    new_s: float = 1.0
    n_sigma: float = 3.0
    rel_floor: float = 0.03


GAP_S = 0.5
"""A change whose joint had no rows for longer than this [s] is reported as an interval
(shorter gaps, e.g. the stiction guard around a velocity reversal, as its middle)."""


@dataclass(frozen=True)
class ChangeReport:
    """A detected change: ``time_s`` [s] change time (the earliest it can have been),
    ``latest_s`` [s] the latest (the first row of the alarmed joint after it), ``alarm_s``
    when the CUSUM fired, ``report_s`` when the new values were taken; ``before``/``after``
    of ``names`` (SI units ``units``); ``sigma`` the watched estimates' spread in the
    reference window."""

    method: str
    time_s: float
    alarm_s: float
    report_s: float
    names: tuple[str, ...]
    before: np.ndarray
    after: np.ndarray
    sigma: np.ndarray
    units: tuple[str, ...]
    latest_s: float

    @property
    def at_s(self) -> float:
        """The change time [s]: the middle of [``time_s``, ``latest_s``]."""
        return 0.5 * (self.time_s + self.latest_s)

    def __str__(self) -> str:
        vals = ", ".join(
            f"{n} {b:.4g} -> {a:.4g}{' ' + u if u else ''}"
            for n, b, a, u in zip(self.names, self.before, self.after, self.units, strict=True)
        )
        if self.latest_s - self.time_s > GAP_S:
            when = f"between {self.time_s:.1f} and {self.latest_s:.1f} s (joint at rest in between)"
        else:
            when = f"at {self.at_s:.1f} s"
        return f"payload changed {when} ({self.method.upper()}): {vals}"


@dataclass(frozen=True)
class Alarm:
    """The CUSUM fired at ``alarm_s`` [s]; the change happened at ``time_s`` [s] at the
    earliest and ``latest_s`` [s] at the latest; ``theta_before`` (b,) is the estimate fed
    to the last row before the change time."""

    time_s: float
    alarm_s: float
    theta_before: np.ndarray
    latest_s: float


class ChangeDetector:
    """Residual CUSUM change detector of one estimator (module docstring).

    ``names`` (b,) names of the estimate's components; ``n_joints`` joint equations per row;
    ``method`` a label for the reports; ``units`` (b,) their SI units (for the report text).
    Feed every row with :meth:`update` (before the estimator uses it).
    """

    def __init__(self, names, n_joints: int, method: str = "", settings=None, units=None):
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
        self.n = int(n_joints)
        self.reports: list[ChangeReport] = []
        self.alarms: list[Alarm] = []
        self.state = "holdoff"
        self._t0: float | None = None
        self._phase_start = 0.0
        self._recent: deque = deque()  # (t, theta) of the last settle_s or reference_s + 1 s
        self._keep_s = max(s.settle_s, s.reference_s) + 1.0
        self._refreshing = False
        self._start_reference(0.0)

    # -- the stream -----------------------------------------------------------------------
    def update(self, t: float, rows, residual, theta) -> Alarm | None:
        """One row at time ``t`` [s]: ``rows`` (n,) bool joint equations present,
        ``residual`` (m,) a-priori residuals of those equations, ``theta`` (b,) the estimate
        before the row. Returns an :class:`Alarm` when the CUSUM fires."""
        s = self.settings
        theta = np.asarray(theta, dtype=float)
        if self._t0 is None:
            self._t0 = t
        recent = self._recent
        recent.append((t, theta))
        oldest = t - self._keep_s
        while recent[0][0] < oldest:
            recent.popleft()
        if self.state == "armed" and not self._refreshing:  # most rows: the CUSUM alone
            return self._cusum(t, rows, residual)
        rows = np.asarray(rows, dtype=bool)
        x = theta[self.index]
        if self.state == "holdoff":
            if t - self._t0 >= s.holdoff_s:
                self._start_reference(t)
            return None
        if self.state == "reference":
            self._accumulate(rows, residual, x)
            if t - self._phase_start >= s.reference_s:
                self._arm(t)
            return None
        if self.state == "armed":
            if self._refreshing:
                self._accumulate(rows, residual, x)
                if t - self._phase_start >= s.reference_s:
                    self._set_reference()
                    self._refreshing = False
            return self._cusum(t, rows, residual)
        return None

    def settled(self, t: float, theta) -> ChangeReport | None:
        """After an alarm: the estimate (b,) after the row at ``t`` [s]; returns the report
        when the new values are taken and the change is significant."""
        if self.state != "settling":
            return None
        s = self.settings
        self._new.append((t, np.asarray(theta, dtype=float)[self.index]))
        while self._new and self._new[0][0] < t - s.new_s:
            self._new.popleft()
        if t - self.settle_from < s.settle_s:
            return None
        after = np.mean([x for _, x in self._new], axis=0)
        alarm = self.alarms[-1]
        self._start_reference(t)
        self._arm(t, refresh=True)
        moved = np.abs(after - self.before)
        bar = np.maximum(s.n_sigma * self.spread, s.rel_floor * np.abs(self.before))
        if not np.any(moved > bar):
            return None
        rep = ChangeReport(
            method=self.method,
            time_s=alarm.time_s,
            alarm_s=alarm.alarm_s,
            report_s=t,
            names=self.names,
            before=self.before.copy(),
            after=after,
            sigma=self.spread.copy(),
            units=self.units,
            latest_s=alarm.latest_s,
        )
        self.reports.append(rep)
        return rep

    # -- phases ---------------------------------------------------------------------------
    def _start_reference(self, t: float) -> None:
        if self._t0 is not None:
            self.state = "reference"
        self._phase_start = t
        self._sq = np.zeros(self.n)
        self._count = np.zeros(self.n)
        self._ref_x: list[np.ndarray] = []

    def _accumulate(self, rows, residual, x) -> None:
        self._sq[rows] += np.asarray(residual, dtype=float) ** 2
        self._count[rows] += 1
        self._ref_x.append(x)

    def _set_reference(self) -> None:
        """Residual scales ``sigma`` (n,) and estimate spreads from the reference window."""
        rms = np.sqrt(self._sq / np.maximum(self._count, 1))
        floor = max(float(np.max(rms)) * 1e-3, 1e-12)
        # a joint with (almost) no rows in the window has no scale: not watched (z = 0)
        self.sigma = np.where(self._count >= MIN_REFERENCE_ROWS, np.maximum(rms, floor), np.inf)
        self._sigma_list = [float(x) for x in self.sigma]
        ref = np.asarray(self._ref_x)
        self.spread = ref.std(axis=0) if len(ref) else np.zeros(len(self.index))

    def _arm(self, t: float, refresh: bool = False) -> None:
        """Start the CUSUM; ``refresh``: with the previous reference while a new one is
        learned (after a change), else with the window just learned."""
        self._refreshing = refresh
        if not refresh:
            self._set_reference()
        n = self.n
        # per joint j: CUSUM G+ and G- [sigma x rows], the last row with G = 0 and the
        # joint's first row after it [s]; Python floats (a few per row: cheaper than arrays)
        self._g = [[0.0] * n, [0.0] * n]
        self._zero_t = [[t] * n, [t] * n]
        self._rise_t = [[t] * n, [t] * n]
        self.state = "armed"

    def _cusum(self, t: float, rows, residual) -> Alarm | None:
        """One CUSUM step on the present joints' residuals; an :class:`Alarm` when it fires.

        Joint j present in ``rows`` takes z = e_j / sigma_j; G+ <- max(0, G+ + z - kappa),
        G- <- max(0, G- - z - kappa); the first joint and side over ``h`` (earliest last
        zero, then G+ before G-, then joint order) gives the change time."""
        s = self.settings
        kappa, h = s.kappa, s.h
        g_up, g_down = self._g
        zero_up, zero_down = self._zero_t
        rise_up, rise_down = self._rise_t
        sigma = self._sigma_list
        res = residual.tolist() if hasattr(residual, "tolist") else list(residual)
        fired = False
        m = 0
        for j, present in enumerate(rows.tolist() if hasattr(rows, "tolist") else rows):
            if not present:
                continue
            z = res[m] / sigma[j]
            m += 1
            for g, zero_t, rise_t, sign in ((g_up, zero_up, rise_up, 1.0),
                                            (g_down, zero_down, rise_down, -1.0)):  # fmt: skip
                was_zero = g[j] <= 0.0
                v = (g[j] + z if sign > 0 else g[j] - z) - kappa  # the arrays' rounding order
                if not v > 0.0:  # max(0, v), NaN to 0 as well
                    v = 0.0
                g[j] = v
                if v <= 0.0:
                    zero_t[j] = t
                elif was_zero:
                    rise_t[j] = t
                fired = fired or v > h
        if not fired:
            return None
        return self._fire(t)

    def _fire(self, t: float) -> Alarm:
        """The alarm at ``t`` [s] from the CUSUM state (some G over ``h``): the change time,
        the estimate before it; the detector goes to settling."""
        h = self.settings.h
        g_arr = np.array(self._g)
        zero = np.array(self._zero_t)
        first = np.argmin(np.where(g_arr > h, zero, np.inf))
        onset = float(zero.flat[first])
        before = [x for tt, x in self._recent if tt < onset] or [self._recent[0][1]]
        alarm = Alarm(onset, t, before[-1], latest_s=float(np.array(self._rise_t).flat[first]))
        self.alarms.append(alarm)
        self.before = alarm.theta_before[self.index]
        #: the estimates can learn the change only once its joint moves again
        self.settle_from = alarm.latest_s
        self._new: deque = deque()
        self.state = "settling"
        return alarm
