"""Run a closed-loop capture over a :class:`guardid.link.Session` into a log file.

The robot's PID gains come from the robot description; setpoints (joint angles of the
trajectory at each tick) are streamed ahead of their tick; every telemetry frame becomes
one log row at once. Whatever ends the run (the trajectory's end, Ctrl-C or SIGTERM, a
vanished port, a full disk) the robot is put idle first when possible, then the log gets
its footer.
"""

from __future__ import annotations

import contextlib
import math
import time
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from guardid.capture.checks import counts_per_rad
from guardid.capture.resume import link_lost, next_rest_index, resume_rows
from guardid.capture.stop import CaptureStopped, StopRequest
from guardid.errors import LinkError
from guardid.link import Session
from guardid.link.session import LazyRows
from guardid.log import LogWriteError, LogWriter

PROGRESS_EVERY_S = 0.25  #: wall-clock interval of progress reports [s]


@dataclass
class CaptureResult:
    """What a capture did: rows written, link counters, tracking error, how it ended."""

    rows: int
    ticks_expected: int
    link: dict
    rms_tracking_error_rad: list[float]
    ended: str  # 'complete' | 'interrupted' | 'link error: ...'
    extra: dict = field(default_factory=dict)

    @property
    def lost_rows(self) -> int:
        return self.ticks_expected - self.rows


def setpoint_counts(trajectory, description, n_ticks: int, start: int = 0) -> np.ndarray:
    """(n_ticks, n) integer setpoints [counts] of the trajectory at t = k * sample period,
    k = start .. start + n_ticks - 1."""
    t = np.arange(start, start + n_ticks) * description.sample_period
    return np.rint(trajectory.positions(t) * counts_per_rad(description)).astype(np.int64)


def setpoint_rows(trajectory, description, n_ticks: int, feedforward=None) -> LazyRows:
    """The setpoints of :func:`setpoint_counts`, made a few thousand ticks at a time as the
    capture reaches them (memory does not grow with ``--duration``); with ``feedforward``
    (a :class:`guardid.feedforward.FeedforwardModel`) each row is followed by the joints'
    feedforward voltages [mV] (:func:`guardid.feedforward.feedforward_mv`)."""
    period = description.sample_period

    def make(start: int, stop: int) -> np.ndarray:
        counts = setpoint_counts(trajectory, description, stop - start, start)
        if feedforward is None:
            return counts
        from guardid.feedforward import feedforward_mv

        return np.hstack([counts, feedforward_mv(feedforward, trajectory, period, start, stop)])

    return LazyRows(n_ticks, make)


class TrackingError:
    """Per joint the rms and the largest |setpoint - measured angle| [rad] over the rows."""

    def __init__(self, n: int) -> None:
        self.sq = np.zeros(n)
        self.max = np.zeros(n)
        self.n = 0

    def add(self, sp_rad: np.ndarray, q_rad: np.ndarray) -> None:
        err = sp_rad - q_rad
        self.sq += err * err
        np.maximum(self.max, np.abs(err), out=self.max)
        self.n += 1

    def rms(self) -> list[float]:
        return [math.sqrt(s / self.n) if self.n else float("nan") for s in self.sq]

    def footer(self, names) -> dict:
        """``{joint: {rms_rad, max_rad}}`` (None without rows)."""
        if not self.n:
            return {name: None for name in names}
        return {
            name: {"rms_rad": float(r), "max_rad": float(m)}
            for name, r, m in zip(names, self.rms(), self.max, strict=True)
        }


def capture(
    session: Session,
    description,
    trajectory,
    duration_s: float,
    log_path,
    header: dict,
    progress: Callable[[dict], None] | None = None,
    on_row: Callable[[float, np.ndarray, np.ndarray, np.ndarray], None] | None = None,
    stop: StopRequest | None = None,
    overwrite: bool = False,
    until: Callable[[], bool] | None = None,
    on_record: Callable[..., None] | None = None,
    reconnect: Callable[[], Session] | None = None,
    notify: Callable[[str], None] | None = None,
    feedforward=None,
    zero_rest_s: float | None = 0.0,
    zero_before: bool = False,
) -> CaptureResult:
    """Capture ``duration_s`` seconds of ``trajectory``; write ``log_path``.

    The trajectory must have been checked against the description
    (:func:`guardid.capture.checks.check_trajectory`) and the session's handshake done.
    ``progress`` (if given) is called every PROGRESS_EVERY_S of wall-clock time with a dict of
    counters (rows, lost, crc_errors, framing_errors, tracking error [rad]).
    ``on_row`` (if given) is called with every logged row as it arrives: time [s], joint
    angles (n,) [rad], period-mean motor voltages (n,) [V] and currents (n,) [A] (online
    identification, :mod:`guardid.online`); it runs in the capture loop, so it must be fast.
    ``on_record`` (if given) is called with every row just written, with the arguments of
    :meth:`guardid.log.LogWriter.write_row` (``capture --stream``); fast, never raising.
    ``stop`` (if given) is checked at every tick: once set, the capture ends as
    'interrupted' (the robot idle, the footer written). ``until`` (if given) is asked after
    every row's ``on_row``: True ends the capture early as 'identified' (``capture
    --until-std``), the robot put idle as at the end. ``overwrite`` False refuses an
    existing ``log_path``. ``feedforward`` (a :class:`guardid.feedforward.FeedforwardModel`,
    checked with :func:`guardid.feedforward.check_supply`, the firmware's INFO having the
    feedforward capability): each setpoint goes with its feedforward voltage (SETPOINT_FF).
    The footer's ``tracking_error`` holds each joint's rms and largest |setpoint - angle|
    [rad] over the rows, whatever ended the run. ``zero_rest_s`` > 0: once the trajectory
    is done (or ``until`` ended it), and with ``zero_before`` before it too, the motors are
    held at 0 V and, when the joints stand still, the current sensors are read for this
    long [s] (None: :func:`guardid.capture.zero.default_rest_s` of the run's length, the
    planned one before; 0: not read); their zeros go to the footer's ``current_zero``
    and ``current_zero_before``, each joint's with ``t_s``, the readings' mean time on the
    log's clock [s] (:func:`guardid.capture.zero.measure_current_zero`; a link error there
    leaves ``not_measured``, a stop keeps what was read; the rows are kept; whatever ends
    the run, the zeros read go to its footer). When the robot does not rest at the
    trajectory's first setpoint after the rest before (an arm sunk onto its stop at 0 V),
    the first leg approaches it from there (its rows not logged; the footer's
    ``start_approach_ticks``). Raises
    :class:`LinkError` after closing the log when the link fails, :class:`LogWriteError`
    (after putting the robot idle) when the log cannot be written; the rows written until
    then stay in the file.

    ``reconnect`` (if given, ``capture --reconnect``): when the link is lost mid-run it is
    called to wait for the port, re-attach the session and handshake (it raises
    :class:`LinkError` when the port does not come back in time or does not answer); the
    run then goes on from the trajectory's next rest point (:mod:`guardid.capture.resume`),
    the rows in between lost (a gap in the tick column), each reconnect said to ``notify``
    and counted in the footer (``reconnects``, ``gaps``).
    """
    period = description.sample_period
    n_ticks = int(round(duration_s / period))
    if feedforward is not None and reconnect is not None:
        raise ValueError("capture: feedforward with reconnect is not supported (a resumed "
                         "leg's approach has no feedforward)")  # fmt: skip
    rows = setpoint_rows(trajectory, description, n_ticks, feedforward)
    per_rad = counts_per_rad(description)
    names = [j.name for j in description.joints]
    started = time.monotonic()
    try:
        writer = LogWriter(log_path, names, header, overwrite=overwrite)
    except LogWriteError:
        _idle(session, stop)  # nothing moved yet; leave the robot idle all the same
        raise
    err = TrackingError(len(names))
    ended = "complete"
    first_tick = None
    reached = 0  # ticks of the trajectory reached so far (an interrupted run's length)
    next_report = started
    legs = _Legs(rows, reconnect is not None)
    # the zero's readings at rest before and after the run (kept when a stop cuts a rest)
    rests = {"current_zero_before": _Rest(before=True), "current_zero": _Rest()}

    def footer_of(ended: str) -> dict:
        """The footer as the run ended, the zeros read so far in it."""
        footer = _footer(session, n_ticks, ended, started, err, names, legs)
        for key, rest in rests.items():
            _zero_into(footer, key, rest, first_tick, period)
        return footer

    try:
        _configure(session, description)
        if zero_before:
            if _current_zero(session, description, zero_rest_s, duration_s, notify,
                             rests["current_zero_before"]) is not None:  # fmt: skip
                legs.approach(session, description, feedforward is not None)
        while legs.rows is not None:
            try:
                # run-ahead unless a row's answer (--until-std) may end the run at its
                # tick, or a caller's work on each row (on_row) may take the robot's time
                ahead = until is None and on_row is None
                track = session.track(legs.rows, feedforward=feedforward is not None,
                                      run_ahead=ahead)  # fmt: skip
                for index, t in track:
                    legs.last_tick = t.tick
                    index += legs.resume_at - legs.lead  # the trajectory's row
                    if not legs.resume_at <= index < n_ticks:
                        continue  # before the trajectory (or its approach), or past its end
                    if first_tick is None:
                        first_tick = t.tick - index
                    reached = max(reached, index + 1)
                    counts = np.asarray(t.counts)
                    q = counts / per_rad
                    sp = np.asarray(t.setpoint_counts) / per_rad
                    volts = np.asarray(t.voltage_mv) * 1e-3
                    amps = np.asarray(t.current_ma) * 1e-3
                    t_s = (t.tick - first_tick) * period
                    writer.write_row(t.tick, t_s, counts, q, volts, amps, sp, t.status)
                    if on_record is not None:
                        on_record(t.tick, t_s, counts, q, volts, amps, sp, t.status)
                    if on_row is not None:
                        on_row(t_s, q, volts, amps)
                    err.add(sp, q)
                    now = time.monotonic()
                    if progress is not None and (now >= next_report or index == n_ticks - 1):
                        next_report = now + PROGRESS_EVERY_S
                        progress(_counters(session, writer.rows, index + 1, err))
                    if until is not None and until():
                        ended, n_ticks = "identified", index + 1  # the ticks this run was to have
                        break
                    if stop is not None:
                        stop.check()  # after this tick's row is written, before the next tick
                legs.rows = None
            except LinkError as exc:
                if reconnect is None or not link_lost(exc):
                    raise
                session = legs.resume(session, reconnect, exc, trajectory, description,
                                      reached, n_ticks, notify)  # fmt: skip
                if legs.rows is not None:
                    _configure(session, description)
        _current_zero(session, description, zero_rest_s, reached * period, notify,
                      rests["current_zero"])  # fmt: skip
        _idle(session, stop)
    except (CaptureStopped, KeyboardInterrupt) as exc:
        ended, n_ticks = "interrupted", reached  # the ticks this run came to
        _idle(session, stop)
        signal = str(exc) if isinstance(exc, CaptureStopped) else "SIGINT"
        for rest in rests.values():
            if rest.started and rest.zero is None:  # stopped during it: the zero read so far
                from guardid.capture.zero import zero_of

                rest.zero = (
                    zero_of(description, rest.readings) if len(rest.readings) >= 2
                    else {"not_measured": f"stopped ({signal}) during the rest"}
                )  # fmt: skip
        footer = footer_of(ended)
        footer["signal"] = signal
        writer.close(footer)
        return _result(session, writer, n_ticks, err, ended)
    except LinkError as exc:
        _idle(session, stop)
        ended = f"link error: {exc}"
        writer.close(footer_of(ended))
        raise LinkError(f"{exc} ({writer.rows} rows kept in {log_path})") from None
    except LogWriteError as exc:
        _idle(session, stop)  # the motors first, the file after
        try:
            ended = f"log write error: {exc}"
            writer.close(footer_of(ended))
            footer = "footer written"
        except LogWriteError:
            footer = "no footer"
        raise LogWriteError(f"{exc} ({footer}; the robot was put idle)") from None
    except BaseException as exc:  # anything else: the motors first, the file after
        _idle(session, stop)
        with contextlib.suppress(LogWriteError):
            ended = f"error: {type(exc).__name__}: {exc}"
            writer.close(footer_of(ended))
        raise
    footer = footer_of(ended)
    result = _result(session, writer, n_ticks, err, ended)
    result.extra.update({k: footer[k] for k in rests if k in footer})
    writer.close(footer)
    return result


class _Rest:
    """A rest before (``before``) or after the run: ``started``, the ``readings`` so far
    and their ``ticks``, the ``zero`` read (None: not yet, or not asked for)."""

    def __init__(self, before: bool = False) -> None:
        self.before = before
        self.started = False
        self.readings: list = []
        self.ticks: list = []
        self.zero: dict | None = None


def _zero_into(footer: dict, key: str, rest: _Rest, first_tick, period: float) -> None:
    """``rest``'s zero into ``footer[key]``, each joint's with ``t_s``: its readings' mean
    time on the log's clock [s] (none when the run logged no row or no tick was read)."""
    if rest.zero is None:
        return
    zero = rest.zero
    ticks = rest.ticks[: len(rest.readings)]
    if "not_measured" not in zero and first_tick is not None and ticks:
        t_s = (sum(ticks) / len(ticks) - first_tick) * period
        zero = {name: {**entry, "t_s": round(t_s, 6)} for name, entry in zero.items()}
    footer[key] = zero


def _current_zero(session: Session, description, rest_s: float | None, run_s: float,
                  notify=None, rest: _Rest | None = None) -> dict | None:  # fmt: skip
    """The current sensors' zero read at rest (None when ``rest_s`` is 0: not asked for;
    None: the default rest for a run of ``run_s`` seconds), said to ``notify`` first;
    ``rest`` (:class:`_Rest`) gets the readings as they come and the zero; before the run
    (``rest.before``) the telemetry is started first."""
    from guardid.capture.zero import default_rest_s, measure_current_zero

    rest = _Rest() if rest is None else rest
    if rest_s is None:
        rest_s = default_rest_s(run_s)
    if rest_s <= 0:
        return None
    if notify is not None:
        when = "before the trajectory" if rest.before else "trajectory done"
        notify(f"{when}; the motors at 0 V: reading the current sensors' zero at rest "
               f"for {rest_s:g} s (--zero-rest)")  # fmt: skip
    try:
        rest.started = True
        if rest.before:
            session.start_stream()
        rest.zero = measure_current_zero(session, description, rest_s, rest.readings,
                                         rest.ticks)  # fmt: skip
    except LinkError as exc:
        rest.zero = {"not_measured": f"link error: {exc}"}
    return rest.zero


def _idle(session: Session, stop: StopRequest | None) -> None:
    """Put the robot idle and stop the stream (best effort; stop requests no longer raise)."""
    if stop is not None:
        stop.disarm()
    session.finish()


def _result(session, writer, n_ticks, err, ended) -> CaptureResult:
    rms = err.rms()
    link = {**session.stats.as_dict(), "framing_errors": session.stats.framing_errors}
    return CaptureResult(writer.rows, n_ticks, link, rms, ended)


def _counters(session: Session, rows: int, ticks: int, err: TrackingError) -> dict:
    st = session.stats
    return {
        "rows": rows,
        "ticks": ticks,
        "lost": ticks - rows,
        "crc_errors": st.crc_errors,
        "framing_errors": st.framing_errors,
        "tracking_rms_rad": [r if err.n else 0.0 for r in err.rms()],
    }


def _footer(session: Session, n_ticks: int, ended: str, started: float,
            err: TrackingError, names, legs=None) -> dict:  # fmt: skip
    st = session.stats
    footer = {
        "ended": ended,
        "ticks_expected": n_ticks,
        "wall_time_s": round(time.monotonic() - started, 3),
        "link": {**st.as_dict(), "framing_errors": st.framing_errors},
        "faults": [list(f) for f in session.faults],
        "tracking_error": err.footer(names),
    }
    if legs is not None and legs.counted:
        footer["reconnects"] = len(legs.gaps)
        footer["gaps"] = legs.gaps
    if legs is not None and legs.start_approach:
        footer["start_approach_ticks"] = legs.start_approach
    return footer


def _configure(session: Session, description) -> None:
    """The watchdog and the PID gains of the description (at the start, after a reconnect)."""
    session.set_watchdog(0.25)
    for j, joint in enumerate(description.joints):
        if joint.pid is not None:
            session.set_pid(j, joint.pid.kp, joint.pid.ki, joint.pid.kd)


class _Legs:
    """The run's legs: the setpoint ``rows`` of the current one (None once done), its
    approach length ``lead`` and the trajectory row ``resume_at`` it takes up; the
    reconnects' ``gaps`` (for the footer when ``counted``)."""

    def __init__(self, rows, counted: bool) -> None:
        self.rows, self.lead, self.resume_at = rows, 0, 0
        self.counted = counted
        self.gaps: list[dict] = []
        self.last_tick: int | None = None
        self.start_approach = 0  # ticks of the approach before the first leg

    def approach(self, session, description, feedforward: bool) -> None:
        """After the rest before the run: the first leg approaches the trajectory's start
        from where the robot rests (:func:`~guardid.capture.resume.start_rows`; with
        ``feedforward`` each approach row carries the first row's feedforward voltages,
        which hold the arm there). A lost link leaves the leg as it is: its tracking meets
        the error, where a reconnect can take it up."""
        from guardid.capture.resume import start_rows

        try:
            counts = session.next_telemetry().counts
        except LinkError:
            return
        n = len(description.joints)
        first = self.rows[0]
        self.rows, self.lead = start_rows(self.rows, description, counts, first[:n],
                                          first[n:] if feedforward else ())  # fmt: skip
        self.start_approach = self.lead

    def resume(self, session, reconnect, exc, trajectory, description, reached, n_ticks,
               notify) -> Session:  # fmt: skip
        """Wait for the port, handshake, and plan the next leg (module resume)."""
        session.finish()  # best effort: the port is gone, the robot's watchdog idles it
        session = reconnect()
        tick = session.ping()
        if self.last_tick is not None and ((tick - self.last_tick) & 0xFFFFFFFF) >= 1 << 31:
            raise LinkError(
                f"port {session.name}: the robot restarted while the port was gone (its tick "
                f"went back from {self.last_tick} to {tick}): its encoder zero is lost; not resumed"
            )
        previous = self.resume_at if self.gaps else None
        resume_at = next_rest_index(trajectory, description, reached, previous)
        if resume_at is None:
            raise LinkError(f"{exc}; the trajectory has no rest point to resume from")
        lost = None if self.last_tick is None else (tick - self.last_tick) & 0xFFFFFFFF
        gap = {"after_row": reached, "resume_row": resume_at, "ticks_away": lost}
        self.gaps.append(gap)
        if resume_at >= n_ticks:
            self.rows = None
            return session
        session.set_mode("idle")
        session.start_stream()
        counts = session.next_telemetry().counts
        self.rows, self.lead = resume_rows(trajectory, description, counts, resume_at, n_ticks)
        self.resume_at = resume_at
        if notify is not None:
            period = description.sample_period
            away = "" if lost is None else f" after {lost * period:.3g} s"
            notify(
                f"{exc}; back{away}: resuming the trajectory at {resume_at * period:g} s "
                "(its next rest point)"
            )
        return session
