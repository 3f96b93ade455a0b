"""On-line identification: telemetry rows -> causal conditioning -> base regressor -> estimators.

:class:`OnlineIdentifier` is fed one telemetry row at a time (time [s], joint angles [rad],
period-mean motor currents [A] and voltages [V]) and keeps every requested estimator
(``rls``, ``hopfield``) up to date:

0. with ``effort='voltage'`` (the default) the current that goes on is the motor equation's,
   (V - Ke N dq/T) / R with R and Ke fitted online to the measured current
   (:class:`guardid.online.motor.MotorCurrent`): in the identification band it is several
   times less noisy than the current sensor; ``effort='current'`` uses the sensor alone;
1. :class:`guardid.conditioning.CausalConditioner` low-passes positions and currents
   (Butterworth, cut-off ``cutoff_hz``) and differentiates them; its output of row k
   describes the instant t_k - ``delay_s`` (the filter's group delay + one sample);
2. joint equations near stiction are held back: joint j's equation of a row is used only if
   no sample within ``guard_s`` of it has joint j slower than ``stiction_threshold`` [rad/s]
   or its encoder not counting in the period (the offline pipeline's rule, per joint: a
   stuck pan does not spoil the tilt's equation; ``per_joint=False`` drops whole rows). To
   know the flags ``guard_s`` after a row, rows wait that long in a short buffer, so
   estimates lag the motion by ``latency_s`` = ``delay_s`` + ``guard_s``; every estimate is
   time-stamped with the instant of the motion it describes (not the arrival time);
3. the base regressor rows A (m, b) of :func:`guardid.dynamics.build_model` (identified
   columns, :func:`guardid.identify.pipeline.identified_names`) and the joint torques
   y = N eta kt i [N m] (minus the described friction offsets a robot declares absent) go to
   ``estimator.update(A, y)``: RLS with forgetting, and the Hopfield network with windowed
   weights (:class:`guardid.estimators.Hopfield` with ``lam``), both with the memory
   :data:`DEFAULT_LAM` and regularised forgetting (:data:`DEFAULT_RHO`);
4. the :class:`guardid.online.detector.ChangeDetector` of each estimator watches its
   a-priori residuals. When it fires, the estimator goes back to its estimate before the
   change, discards what it knew of the parameters a payload changes (all but friction:
   :attr:`OnlineIdentifier.changing`), and takes the rows since the change again, except the
   first :data:`TRANSITION_PERIODS` cut-off periods, in which the causal filter still mixes
   the torques before and after it. Abrupt changes are thus tracked in a few seconds while
   the long memory keeps the estimates quiet; 5 s later the detector reports the change
   if the watched estimates moved beyond their uncertainty.

A gap in the telemetry (a lost row: time step > 1.5 sample periods) restarts the conditioner
(steady-state initialisation) and skips its warm-up; the estimators keep their state.

Defaults tuned on 60 s guard captures with a +1 kg payload at 30 s (tests/test_online.py).
"""

from __future__ import annotations

import csv
import math
import time
from collections import deque
from dataclasses import dataclass

import numpy as np

from guardid.conditioning import CausalConditioner, counts_per_joint_rev, drive_gain
from guardid.dynamics import build_model
from guardid.errors import ConfigError
from guardid.estimators import RLS, Hopfield
from guardid.online.detector import ChangeDetector, ChangeReport, DetectorSettings
from guardid.online.motor import MotorCurrent

ONLINE_METHODS = ("rls", "hopfield")
LIVE_LS = "ls"
"""Growing-window least squares on every k-th used row (:class:`guardid.online.information.
DecimatedLS`): the live parameter uncertainty of ``capture --until-std``; never restarted."""
DEFAULT_CUTOFF_HZ = 4.0
"""Cut-off [Hz] when the trajectory's highest harmonic is unknown (8 x 0.5 Hz, as offline)."""
HARMONIC_CUTOFF_FACTOR = 8.0
"""Cut-off = this x the trajectory's highest harmonic (the offline pipeline's rule) [-]."""
DEFAULT_LAM = 0.999
"""Forgetting factor per used row (RLS and the Hopfield network's windowed weights): memory
T / (1 - lambda) = 15 s of used rows at T = 15 ms. Long, for low-noise estimates of the
weakly excited parameters (MY2: with 0.998, RLS's MY2 left the 5 % band in steady state on
one of 15 seeds); abrupt changes are handled by the change detector's restart (module
docstring), slow drifts by the forgetting [-]."""
DEFAULT_RHO = 1.0
"""Regularised forgetting: the information forgotten per row, (1 - lambda) P^-1, is replaced
by (1 - lambda) R0, R0 = diag(1 / (rho h_i)^2) with h_i the prior half-widths of
:func:`prior_half_widths`. The information then obeys R_k >= (1 - lambda^k) R0, so the
covariance of a direction the rows do not excite stays below the prior box instead of
growing as lambda^-k (windup) [-]. Larger floors (rho 0.1-0.3) anchor the estimates and
slowed MY2 after a payload change from 5 s to 10-18 s."""
DEFAULT_BETA = 3.0
"""Hopfield gain beta [N^2 m^2 s] with the windowed weights: the network follows the window's
least-squares minimum with a lag that smooths the estimate (0.1 follows it within a row,
3 settled MY2 after a payload change 1-2 s sooner than 0.1 on five seeds)."""
DEFAULT_P0 = 1e2
"""RLS initial covariance (times the identity) [(unit of theta / N m)^2]."""
STICTION_FRACTION = 0.05
"""Stiction threshold = this x each joint's velocity limit (what ``guardid excite`` calls
slow), at least 3 encoder counts per sample period [-]."""
REPLAY_S = 5.0
"""Rows kept for a replay after a detected change [s of motion]."""
TRANSITION_PERIODS = 2.0
"""Cut-off periods after a detected change whose rows are not replayed [-]."""
GUARD_PERIODS = 0.6
"""Rows within this many cut-off periods of a flagged sample are not used [-]."""
WARMUP_PERIODS = 2.0
"""Cut-off periods after the start (or a gap) whose rows are not used [-]."""


@dataclass
class Track:
    """One estimator's trajectory: t (K,) [s] (instants of the motion), theta (K, b)."""

    method: str
    t: np.ndarray
    theta: np.ndarray


class OnlineIdentifier:
    """Online estimators fed one telemetry row at a time (see the module docstring).

    Parameters
    ----------
    description : ChainDescription
        The robot (joints with drives and encoders).
    methods : sequence of 'rls' | 'hopfield'
    cutoff_hz : float, optional
        Conditioning low-pass cut-off [Hz]; default :data:`HARMONIC_CUTOFF_FACTOR` x
        ``highest_harmonic_hz`` [Hz] if given, else :data:`DEFAULT_CUTOFF_HZ`.
    lam : float
        Forgetting factor per used row (RLS and the Hopfield weights), in (0, 1].
    beta : float
        Hopfield gain [N^2 m^2 s].
    p0 : float
        RLS initial covariance (times the identity).
    rho : float | None
        Regularised forgetting floor in prior half-widths (:data:`DEFAULT_RHO`; None = off).
    stiction_threshold : scalar or (n,) [rad/s], optional
        Default :data:`STICTION_FRACTION` x velocity limit (3 counts per period at least).
    detector : DetectorSettings | None | False
        Change-detector settings (None = defaults, False = no detection).
    keep_history : bool
        Keep every estimate (for :meth:`tracks` and :meth:`write_csv`).
    effort : 'voltage' | 'current'
        Current from the motor equation (needs the voltages) or from the current sensor.
    per_joint : bool
        Drop only the stuck joint's equation near stiction (False: the whole row).
    guard_periods : float
        Rows within this many cut-off periods of a flagged sample are not used
        (:data:`GUARD_PERIODS`; ``capture --until-std`` uses the batch pipeline's, so that its
        live standard deviations are not smaller than ``guardid identify``'s).
    """

    def __init__(
        self,
        description,
        methods=ONLINE_METHODS,
        *,
        cutoff_hz: float | None = None,
        highest_harmonic_hz: float | None = None,
        lam: float = DEFAULT_LAM,
        beta: float = DEFAULT_BETA,
        p0: float = DEFAULT_P0,
        rho: float | None = DEFAULT_RHO,
        stiction_threshold=None,
        detector: DetectorSettings | None | bool = None,
        keep_history: bool = True,
        effort: str = "voltage",
        per_joint: bool = True,
        guard_periods: float = GUARD_PERIODS,
    ):
        from guardid.identify.pipeline import identified_names

        unknown = [m for m in methods if m not in (*ONLINE_METHODS, LIVE_LS)]
        if unknown or not methods:
            raise ConfigError(
                f"--online: unknown {', '.join(unknown) or '(none given)'} "
                f"(known: {', '.join(ONLINE_METHODS)})"
            )
        self.methods = tuple(methods)
        self.description = description
        self.model = build_model(description)
        n = self.model.n_dof
        self.dt = float(description.sample_period)
        if cutoff_hz is None:
            cutoff_hz = (
                HARMONIC_CUTOFF_FACTOR * highest_harmonic_hz
                if highest_harmonic_hz
                else DEFAULT_CUTOFF_HZ
            )
        cutoff_hz = min(float(cutoff_hz), 0.4 / self.dt)
        self.cutoff_hz = cutoff_hz
        if stiction_threshold is None:
            stiction_threshold = default_threshold(description)
        self.threshold = np.broadcast_to(np.asarray(stiction_threshold, float), (n,)).copy()
        self.gain = drive_gain(description)
        if effort not in ("current", "voltage"):
            raise ConfigError(f"effort: expected 'current' or 'voltage', got {effort!r}")
        self.effort = effort
        self.per_joint = bool(per_joint)
        self.motor = MotorCurrent(description) if effort == "voltage" else None
        self.conditioner = CausalConditioner(
            n, self.dt, cutoff_hz, gain=self.gain, stiction_threshold=self.threshold
        )
        self.guard = max(1, int(round(guard_periods / cutoff_hz / self.dt)))
        self.warmup = int(round(WARMUP_PERIODS / cutoff_hz / self.dt))
        self._lag = int(round(self.conditioner.delay_samples))
        all_names = list(self.model.base.names)
        self.names = tuple(identified_names(description))
        self.free = [all_names.index(x) for x in self.names]
        fixed = [i for i in range(len(all_names)) if i not in self.free]
        values = self.model.base.values(self.model.params)
        self.nominal = values[self.free]
        self._fixed = (fixed, values[fixed]) if fixed else None
        probe = np.full((1, n), 0.3)
        self._known = bool(np.any(self.model.known_torque(probe, probe, probe)))
        self.half_widths = prior_half_widths(self.nominal, self.names)
        self.info_floor = 1.0 / (rho * self.half_widths) ** 2 if rho and lam < 1.0 else None
        self.lam, self.beta = float(lam), float(beta)
        self.estimators = {m: self._make(m, p0) for m in self.methods}
        #: parameters whose information a detected change discards: all but friction
        self.changing = np.array([i for i, x in enumerate(self.names) if not x.startswith("F")])
        if detector is False:
            self.detectors = {}
        else:
            settings = detector if isinstance(detector, DetectorSettings) else DetectorSettings()
            units = param_units(self.names)
            self.detectors = {
                m: ChangeDetector(self.names, n, m, settings, units=units)
                for m in self.methods
                if m in ONLINE_METHODS
            }
        self._replay_s = REPLAY_S
        #: rows this long after a detected change are not replayed: the causal filter
        #: still mixes the torque before and after the change [s]
        self.transition_s = TRANSITION_PERIODS / cutoff_hz
        self._rows_buf: deque = deque()  # (t, A, y) of the used rows of the last REPLAY_S
        self._hold_until = dict.fromkeys(self.methods, -math.inf)  # no rows before [s]
        self.keep_history = keep_history
        self._hist_t = _Growing(())
        self._hist = {m: _Growing((len(self.names),)) for m in self.methods}
        self.reports: list[ChangeReport] = []
        self.rows = 0  #: telemetry rows fed
        self.used = 0  #: rows given to the estimators
        self.busy_s = 0.0  #: wall-clock time spent in :meth:`update` [s]
        self._k = -1
        self._t_prev = None
        self._q_prev = None
        self._warm_until = self.warmup
        size = self._lag + 2 * self.guard + 8
        self._flags = np.zeros((size, n), dtype=bool)
        self._pending: deque = deque()
        self._replayed = False

    @classmethod
    def for_trajectory(cls, description, methods, trajectory, **kwargs) -> OnlineIdentifier:
        """The tracker for a capture along ``trajectory`` (:mod:`guardid.excitation`): the
        cut-off follows its highest harmonic (the default one if it has none)."""
        from guardid.identify.runs import trajectory_highest_harmonic

        to_dict = getattr(trajectory, "to_dict", None)
        harmonic = trajectory_highest_harmonic(to_dict() if to_dict else None)
        return cls(description, methods, highest_harmonic_hz=harmonic, **kwargs)

    # -- set-up ---------------------------------------------------------------------------
    def _make(self, method, p0):
        if method == LIVE_LS:
            from guardid.online.information import DecimatedLS

            return DecimatedLS(DecimatedLS.every_for(self.cutoff_hz, self.dt))
        if method == "rls":
            return RLS(lam=self.lam, p0=p0, theta0=self.nominal, info_floor=self.info_floor)
        return Hopfield(theta_n=self.nominal, half_widths=self.half_widths, beta=self.beta,
                        dt=self.dt, lam=self.lam, info_floor=self.info_floor)  # fmt: skip

    @property
    def latency_s(self) -> float:
        """Time [s] between a row's arrival and the estimator update it feeds."""
        return self.conditioner.delay_s + self.guard * self.dt

    @property
    def us_per_row(self) -> float:
        """Mean wall-clock cost of :meth:`update` per telemetry row [us]."""
        return 1e6 * self.busy_s / max(self.rows, 1)

    # -- the stream -----------------------------------------------------------------------
    def update(self, time_s: float, q_rad, current_a, voltage_v=None) -> list[ChangeReport]:
        """Feed one telemetry row: time [s], joint angles (n,) [rad], currents (n,) [A] and
        voltages (n,) [V] (period means; the voltages are needed with ``effort='voltage'``).

        Returns the change reports completed by this row (usually none).
        """
        if self._replayed:
            raise RuntimeError("a tracker that replayed a log takes no more rows")
        started = time.perf_counter()
        q = np.asarray(q_rad, dtype=float)
        effort = np.asarray(current_a, dtype=float)
        if self._t_prev is not None and time_s - self._t_prev > 1.5 * self.dt:
            self._restart()
        self._t_prev = float(time_s)
        self._k += 1
        k = self._k
        flags, size = self._flags, self._flags.shape[0]
        flags[k % size] = False
        q_prev = self._q_prev
        if q_prev is not None:
            flat = q == q_prev  # no encoder count in the period: held or reversing
            flags[k % size] |= flat
            flags[(k - 1) % size] |= flat
        if self.motor is not None:
            if voltage_v is None:
                raise ValueError("effort='voltage' needs the voltages of every row")
            effort = self.motor.update(voltage_v, q, effort)
        self._q_prev = q
        out = self.conditioner.update(q, effort)
        j = k - self._lag
        if j < self._warm_until:
            flags[j % size] = True
        else:
            flags[j % size] |= out.slow[0] if self.per_joint else out.stiction[0]
        t_j = float(time_s) - self.conditioner.delay_s
        self._pending.append((j, t_j, out.q[0], out.qd[0], out.qdd[0], out.tau[0]))
        reports: list[ChangeReport] = []
        if len(self._pending) > self.guard:
            j0, t0, q0, qd0, qdd0, tau0 = self._pending.popleft()
            g = self.guard
            idx = np.arange(j0 - g, j0 + g + 1) % size
            bad = flags[idx].any(axis=0)
            if not self.per_joint and bad.any():
                bad[:] = True
            if not bad.all():
                reports = self._estimate(t0, q0, qd0, qdd0, tau0, ~bad)
        self.rows += 1
        self.busy_s += time.perf_counter() - started
        return reports

    def feed(self, t_s, q_rad, current_a, voltage_v=None, restarts=()) -> list[ChangeReport]:
        """Feed many rows (N,), (N, n), (N, n), (N, n) in order (a replay); returns their
        reports. ``restarts``: indices of rows before which the conditioner restarts as
        after a gap (a log's jumps, :mod:`guardid.identify.jumps`).

        A fresh tracker replays a whole log at the estimators' cost
        (:func:`guardid.online.replay.replay`: everything that does not depend on the
        estimators' state is computed over all rows at once), with the estimates and
        reports that :meth:`update` row by row gives (to round-off); it then takes no more
        rows. Otherwise the rows go through :meth:`update` one by one."""
        if self.rows == 0 and len(t_s) > 0:
            from guardid.online.replay import replay

            return replay(self, t_s, q_rad, current_a, voltage_v, restarts)
        if self._replayed:
            raise RuntimeError("a tracker that replayed a log takes no more rows")
        reports: list[ChangeReport] = []
        cur = np.asarray(current_a)
        volts = np.asarray(voltage_v) if voltage_v is not None else [None] * len(cur)
        rows = zip(np.asarray(t_s, float), np.asarray(q_rad), cur, volts, strict=True)
        restart = set(int(k) for k in restarts)
        for k, (t, q, c, v) in enumerate(rows):
            if k in restart and self._t_prev is not None:
                self._restart()
            reports += self.update(float(t), q, c, v)
        return reports

    def _restart(self) -> None:
        """After a gap: fresh conditioner, no pending rows, a new warm-up."""
        self.conditioner.reset()
        if self.motor is not None:
            self.motor.reset()
        self._pending.clear()
        self._q_prev = None
        self._warm_until = self._k + 1 + self.warmup

    def _estimate(self, t, q, qd, qdd, tau, rows) -> list[ChangeReport]:
        """Update every estimator with the joint equations ``rows`` (n,) bool of one sample."""
        model = self.model
        A_all = model.base_regressor(q[None], qd[None], qdd[None])
        y = tau
        if self._known:
            y = y - model.known_torque(q[None], qd[None], qdd[None])[0]
        A_all = A_all[0]
        if self._fixed is not None:
            cols, vals = self._fixed
            y = y - A_all[:, cols] @ vals
        A = A_all[:, self.free]
        if not rows.all():
            A, y = A[rows], y[rows]
        A = np.ascontiguousarray(A)
        y = np.ascontiguousarray(y, dtype=float)
        return self._use_row(t, A, y, rows)

    def _use_row(self, t, A, y, rows) -> list[ChangeReport]:
        """Detectors and estimators on the joint equations A (m, b), y (m,) [N m] of the
        row at ``t`` [s] (``rows`` (n,) bool: which joints' equations they are)."""
        self.used += 1
        buf = self._rows_buf
        buf.append((t, A, y))
        while buf[0][0] < t - self._replay_s:
            buf.popleft()
        reports = []
        if self.keep_history:
            self._hist_t.append(t)
        for m, est in self.estimators.items():
            theta = self.estimate(m)
            det = self.detectors.get(m)
            alarm = det.update(t, rows, y - A @ theta, theta) if det is not None else None
            if t >= self._hold_until[m]:
                est.update(A, y)
            if alarm is not None:
                self._restart_at(m, est, alarm)
            theta = est.theta_
            if self.keep_history:
                self._hist[m].append(theta)
            rep = det.settled(t, theta) if det is not None else None
            if rep is not None:
                reports.append(rep)
        self.reports += reports
        return reports

    def _restart_at(self, method, est, alarm) -> None:
        """A change (:class:`guardid.online.detector.Alarm`): back to the estimate before it,
        the information on :attr:`changing` discarded (friction's kept), the rows since then
        replayed."""
        theta = alarm.theta_before
        if method == "rls":
            est.discard(self.changing, self.half_widths[self.changing] ** 2, theta=theta)
        else:
            est.discard(self.changing, theta=theta)
        # the change lies between alarm.time_s and alarm.latest_s (the alarmed joint's gap,
        # if any): the filter mixes the torques until a transition after the latest
        skip = self._hold_until[method] = alarm.latest_s + self.transition_s
        for tt, A, y in self._rows_buf:
            if tt >= skip:
                est.update(A, y)

    # -- results --------------------------------------------------------------------------
    def estimate(self, method: str) -> np.ndarray:
        """Current estimate (b,) of ``method`` (the nominal values before the first row)."""
        theta = getattr(self.estimators[method], "theta_", None)
        return self.nominal.copy() if theta is None else np.asarray(theta, dtype=float)

    def tracks(self) -> dict[str, Track]:
        """Every kept estimate per method (needs ``keep_history``)."""
        t = self._hist_t.array()
        return {m: Track(m, t, h.array()) for m, h in self._hist.items()}

    def status(self, names=("MX2R", "MY2")) -> str:
        """Compact progress text: selected current estimates per method, plus the last change."""
        shown = [x for x in names if x in self.names] or list(self.names[:2])
        parts = []
        for m in self.methods:
            theta = self.estimate(m)
            vals = " ".join(f"{x} {theta[self.names.index(x)]:.3f}" for x in shown)
            parts.append(f"{m.upper()} {vals}")
        text = " | ".join(parts)
        if self.reports:
            text += f" | change at {self.reports[-1].at_s:.1f} s"
        return text

    def write_csv(self, path) -> None:
        """Write the kept estimates: time_s, estimator, one column per base parameter [SI]."""
        tracks = self.tracks()
        with open(path, "w", newline="", encoding="utf-8") as f:
            w = csv.writer(f)
            w.writerow(["time_s", "estimator", *self.names])
            for m, tr in tracks.items():
                for t, row in zip(tr.t, tr.theta, strict=True):
                    w.writerow([f"{t:.4f}", m, *(f"{v:.6g}" for v in row)])


class _Growing:
    """Rows of one shape appended one by one into a float64 array that doubles when full
    (the history of a long replay: 8 bytes per number, not a Python object per row)."""

    def __init__(self, shape: tuple[int, ...]) -> None:
        self._buf = np.empty((256, *shape))
        self.n = 0

    def append(self, row) -> None:
        if self.n == len(self._buf):
            grown = np.empty((2 * self.n, *self._buf.shape[1:]))
            grown[: self.n] = self._buf
            self._buf = grown
        self._buf[self.n] = row
        self.n += 1

    def extend(self, rows) -> None:
        """Append the rows of ``rows`` (k, *shape) in order."""
        rows = np.asarray(rows, dtype=float)
        need = self.n + len(rows)
        if need > len(self._buf):
            grown = np.empty((max(2 * len(self._buf), need), *self._buf.shape[1:]))
            grown[: self.n] = self._buf[: self.n]
            self._buf = grown
        self._buf[self.n : need] = rows
        self.n = need

    def __len__(self) -> int:
        return self.n

    def array(self) -> np.ndarray:
        """A copy of the rows appended so far."""
        return self._buf[: self.n].copy()


def read_tracks_csv(path) -> tuple[tuple[str, ...], dict[str, Track]]:
    """Read a file of :meth:`OnlineIdentifier.write_csv`: (names, {method: Track})."""
    with open(path, newline="", encoding="utf-8") as f:
        rows = list(csv.reader(f))
    names = tuple(rows[0][2:])
    out: dict[str, list] = {}
    for r in rows[1:]:
        out.setdefault(r[1], []).append([float(x) for x in [r[0], *r[2:]]])
    tracks = {}
    for m, data in out.items():
        arr = np.asarray(data, dtype=float)
        tracks[m] = Track(m, arr[:, 0], arr[:, 1:])
    return names, tracks


def online_path(log_path) -> str:
    """Where the estimates of a capture to ``log_path`` go: run.csv -> run.online.csv."""
    s = str(log_path)
    return (s[:-4] if s.lower().endswith(".csv") else s) + ".online.csv"


def default_threshold(description) -> np.ndarray:
    """Stiction threshold (n,) [rad/s]: :data:`STICTION_FRACTION` x velocity limit, at least
    3 encoder counts per sample period."""
    res = 2.0 * math.pi / counts_per_joint_rev(description)
    floor = 3.0 * res / float(description.sample_period)
    vmax = np.array(
        [
            j.limits.velocity if j.limits is not None and j.limits.velocity else math.inf
            for j in description.joints
        ]
    )
    thr = np.where(np.isfinite(vmax), STICTION_FRACTION * vmax, floor)
    return np.maximum(thr, floor)


def prior_half_widths(nominal: np.ndarray, names) -> np.ndarray:
    """Prior ranges (b,) [SI]: +-100 % of each nominal value, and at least the largest
    |nominal| of the parameters with the same unit (so that a small parameter such as MY2
    gets the range of its kind, MX2R, and a Hopfield gain of the same order); 1 if all of a
    unit are zero. The Hopfield box half-widths."""
    nominal = np.asarray(nominal, dtype=float)
    units = np.array(param_units(names))
    out = np.abs(nominal).copy()
    for u in set(units.tolist()):
        same = units == u
        top = float(np.max(np.abs(nominal[same])))
        out[same] = np.maximum(out[same], top if top > 0 else 1.0)
    return out


def param_units(names) -> tuple[str, ...]:
    """SI unit of each base parameter by its name (inertia, first moment, mass, friction)."""
    out = []
    for x in names:
        if x.startswith(("MX", "MY", "MZ")):
            out.append("kg m")
        elif x.startswith(("XX", "XY", "XZ", "YY", "YZ", "ZZ", "Ia")):
            out.append("kg m^2")
        elif x.startswith("Fv"):
            out.append("N m s/rad")
        elif x.startswith(("Fc", "Fo")):
            out.append("N m")
        elif x.startswith("M"):
            out.append("kg")
        else:
            out.append("")
    return tuple(out)
