"""Tracking a logged run offline: the log replayed through the online tracker.

``guardid identify --method ...,rls,hopfield`` calls :func:`track_log`: the same causal
conditioning, estimators and change detector as ``guardid capture --online`` run over the
log's rows in order, so offline and live tracking give the same estimates and reports. The
replay computes what does not depend on the estimators over the whole log at once
(:mod:`guardid.online.replay`); only the estimators and the detectors go row by row.
"""

from __future__ import annotations

import click
import numpy as np

from guardid.online.tracker import DEFAULT_BETA, DEFAULT_LAM, ONLINE_METHODS, OnlineIdentifier


def _explicit(name: str) -> bool:
    """True when the running click command got option ``name`` on the command line."""
    ctx = click.get_current_context(silent=True)
    if ctx is None:
        return False
    source = ctx.get_parameter_source(name)
    return source is not None and source.name == "COMMANDLINE"


def log_highest_harmonic(path) -> float | None:
    """The excitation's highest frequency [Hz] named by a guardid log's header, or None."""
    from guardid.identify.runs import trajectory_highest_harmonic
    from guardid.log import read_log

    try:
        return trajectory_highest_harmonic(read_log(path).header.get("trajectory"))
    except Exception:  # not a guardid log: the tracker's default cut-off applies
        return None


def track_log(
    run, description, methods, lam=None, beta=None, log_path=None, echo=click.echo,
    effort="voltage", keep_history=True,
):  # fmt: skip
    """Replay ``run`` (:class:`guardid.identify.runs.Run`) through an :class:`OnlineIdentifier`.

    Only the methods of :data:`ONLINE_METHODS` in ``methods`` are tracked. ``lam`` (RLS
    forgetting factor per used 15 ms row) and ``beta`` (Hopfield gain [N^2 m^2 s]) default to
    the tracker's own (:data:`DEFAULT_LAM`, :data:`DEFAULT_BETA`); inside ``guardid
    identify`` the --lam / --beta values are used only when given on the command line (their
    defaults are the batch pipeline's: no forgetting would not track). Prints the settings
    and the change reports with ``echo``; returns the fed tracker, or None when the run
    cannot be replayed (foreign log without ticks or with measured torque). ``effort``: as
    :class:`OnlineIdentifier`'s; 'voltage' falls back to 'current' for a log without voltages.
    ``keep_history``: keep every estimate (for a plot; 200 bytes per row and method).
    The whole run is replayed, gaps and all: the causal conditioning restarts after every
    lost tick and every jump (:func:`guardid.online.replay.replay`,
    :mod:`guardid.identify.jumps`), which is stricter than the batch fit's split at long
    gaps (:mod:`guardid.identify.segments`); the estimators carry on.
    The cut-off follows the run's ``highest_harmonic_hz`` (read with the log, see
    :func:`guardid.identify.runs.load_run`); ``log_path`` is read for it only when the run
    does not carry it.
    """
    online = tuple(m for m in methods if m in ONLINE_METHODS)
    if not online:
        return None
    if run.ticks is None or getattr(run, "torque", False):
        echo("tracking: skipped (needs a log of motor currents on the robot's ticks)")
        return None
    if lam is None or (click.get_current_context(silent=True) and not _explicit("lam")):
        lam = DEFAULT_LAM
    if beta is None or (click.get_current_context(silent=True) and not _explicit("beta")):
        beta = DEFAULT_BETA
    harmonic = getattr(run, "highest_harmonic_hz", None)
    if not hasattr(run, "highest_harmonic_hz") and log_path is not None:
        harmonic = log_highest_harmonic(log_path)
    if run.voltage is None or np.asarray(run.voltage).shape != np.asarray(run.q).shape:
        effort = "current"
    tracker = OnlineIdentifier(
        description, online, lam=float(lam), beta=float(beta), highest_harmonic_hz=harmonic,
        effort=effort, keep_history=keep_history,
    )  # fmt: skip
    period = float(description.sample_period)
    if run.joint_names is not None and run.sample_period_s == period:  # a guardid log's
        # times are this product already: no second copy
        t = np.asarray(run.t)
    else:
        t = (np.asarray(run.ticks) - run.ticks[0]) * period
    from guardid.identify.jumps import drive_reach, find_jumps

    jumps = [j.index for j in find_jumps(run, drive_reach(description), period)]
    tracker.feed(t, run.q, run.current, run.voltage if effort == "voltage" else None, jumps)
    settings = []
    if "rls" in online:
        settings.append(f"RLS lambda {tracker.lam:g} per row")
    if "hopfield" in online:
        settings.append(f"Hopfield beta {tracker.beta:g}")
    settings.append(f"current from the {'motor equation' if effort == 'voltage' else 'sensor'}")
    gaps = int(np.count_nonzero(np.diff(np.asarray(run.ticks)) > 1))
    cuts = [f"{gaps} gaps"] * bool(gaps) + [f"{len(jumps)} jumps"] * bool(jumps)
    restarts = f"; its causal filter restarted after each of {' and '.join(cuts)}" if cuts else ""
    echo(
        f"tracking (the log replayed through the online tracker: {', '.join(settings)}, "
        f"cut-off {tracker.cutoff_hz:.3g} Hz, {tracker.used} of {tracker.rows} rows used"
        f"{restarts})"
    )
    for report in tracker.reports:
        echo(str(report))
    if not tracker.reports:
        echo("no parameter change detected")
    return tracker


class ForkedTracking:
    """:func:`track_log` running in a forked process while the caller goes on (the batch
    fit of ``guardid identify``): the replay is one core's work, the fit another's.

    :meth:`result` waits and returns (the lines :func:`track_log` printed, the change times
    [s] of its reports); an error in the replay is raised there. :meth:`cancel` ends the
    process if its result is not wanted (called when the click command closes)."""

    def __init__(self, run, description, methods, lam, beta, log_path, effort="voltage"):
        import multiprocessing

        ctx = multiprocessing.get_context("fork")
        self._recv, send = ctx.Pipe(duplex=False)

        def work():  # in the child: the inherited run, no copy through the pipe
            try:
                lines: list[str] = []
                tracker = track_log(
                    run, description, methods, lam, beta, log_path=log_path,
                    echo=lines.append, effort=effort, keep_history=False,
                )  # fmt: skip
                changes = [r.at_s for r in tracker.reports] if tracker is not None else []
                send.send(("ok", lines, changes))
            except BaseException as exc:  # noqa: BLE001 - handed to the parent as it is
                try:
                    send.send(("error", exc, None))
                except Exception:  # noqa: BLE001 - an exception that does not pickle
                    send.send(("error", RuntimeError(f"tracking: {exc!r}"), None))

        self._proc = ctx.Process(target=work, daemon=True)
        self._proc.start()
        send.close()
        click_ctx = click.get_current_context(silent=True)
        if click_ctx is not None:
            click_ctx.call_on_close(self.cancel)

    def result(self) -> tuple[list[str], list[float]]:
        try:
            kind, value, changes = self._recv.recv()
        except EOFError:
            self._proc.join()
            from guardid.errors import GuardidError

            raise GuardidError(
                f"tracking: the replay process ended without a result (exit code "
                f"{self._proc.exitcode})"
            ) from None
        finally:
            self._recv.close()
        self._proc.join()
        if kind == "error":
            raise value
        return value, changes

    def cancel(self) -> None:
        if self._proc.is_alive():
            self._proc.terminate()
        self._proc.join()
        self._recv.close()


def start_tracking(run, description, methods, lam=None, beta=None, log_path=None):
    """A :class:`ForkedTracking` of ``run`` when it is worth it (an online method asked for,
    more than one core to run on, ``fork`` available), else None (call :func:`track_log`)."""
    import os

    if not any(m in ONLINE_METHODS for m in methods) or not hasattr(os, "fork"):
        return None
    cores = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count()
    if (cores or 1) < 2:
        return None
    return ForkedTracking(run, description, methods, lam, beta, log_path)
