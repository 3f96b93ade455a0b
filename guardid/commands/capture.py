"""``guardid capture``: drive the robot along a trajectory and log its telemetry."""

from __future__ import annotations

import datetime as _dt
import math
import os
import sys

import click

from guardid.commands._status import end_line, forget_line, line_open
from guardid.commands._types import POSITIVE
from guardid.commands.outputs import force_option, output_option
from guardid.errors import ConfigError

TRACKING_PERIOD_S = 5.0
"""--online: excitation periods longer than this [s] get a note on tracking speed."""
UNTIL_STD_CAP_S = 1200.0
"""--until-std without --duration / --periods: the capture ends by this time at the latest [s]."""


def _load_trajectory(path: str):
    from guardid.excitation import load_trajectory

    return load_trajectory(path)


@click.command()
@click.option(
    "--port",
    default=None,
    help="Serial device or URL [default: sim://<robot>]; an empty value is refused (an unset "
    "$PORT must not silently mean the simulator).",
)
@click.option(
    "--baud", type=click.IntRange(min=50), default=115200, show_default=True, help="Baud rate."
)
@click.option("--robot", default="guard", show_default=True, help="Shipped robot or YAML path.")
@click.option(
    "--trajectory", "trajectory_path", required=True, help="Trajectory YAML (guardid excite)."
)
@click.option("--duration", type=POSITIVE, default=None, help="Capture length [s].")
@click.option(
    "--periods",
    type=click.IntRange(min=1),
    default=None,
    help="Capture length in trajectory periods.",
)
@click.option(
    "--timeout",
    type=POSITIVE,
    default=1.0,
    show_default=True,
    help="Longest wait for an answer or a telemetry frame [s]; unanswered commands are "
    "sent again, up to 5 times.",
)
@output_option("Log file (CSV)")
@force_option("an existing OUTPUT")
@click.option("--quiet", is_flag=True, help="No progress display.")
@click.option(
    "--online",
    default=None,
    help="Comma-separated online estimators run on the live telemetry (rls, hopfield); "
    "estimates go to OUTPUT's .online.csv, parameter changes are reported.",
)
@click.option(
    "--online-effort",
    type=click.Choice(["voltage", "current"]),
    default="voltage",
    show_default=True,
    help="Motor current for --online: from the motor equation (voltage, encoder, R and Ke "
    "fitted to the current sensor; less noisy) or from the current sensor alone.",
)
@click.option(
    "--until-std",
    "until_std",
    type=click.FloatRange(min=0, min_open=True),
    default=None,
    help="Keep the robot on its excitation until every base parameter is identified to this "
    "relative standard deviation [%] (live least squares on the causal conditioning; a "
    "parameter within 3 std of zero counts when its std is this share of its kind's "
    "scale), at least one trajectory period; --duration / --periods is then the cap "
    f"[default cap: {UNTIL_STD_CAP_S:g} s]. Exit 4 when the cap comes first.",
)
def capture(
    port, baud, robot, trajectory_path, duration, periods, timeout, output, force, quiet,
    online, online_effort, until_std,
):  # fmt: skip
    """Run the trajectory on the robot in closed loop and record telemetry to OUTPUT.

    The default port is the built-in simulated robot. Before anything moves, the
    trajectory is checked against the robot description (joint count; position,
    velocity and acceleration limits) and the robot's INFO against the same description.
    OUTPUT is created only after the handshake and never replaces a file without --force.
    Ctrl-C or SIGTERM puts the robot idle and closes the log properly; a vanished port or
    a full disk keeps the rows recorded so far.
    """
    from guardid.capture.stop import CaptureStopped, StopRequest

    stop = StopRequest()
    with stop.installed():
        try:
            result, tracker, live = _capture(
                port, baud, robot, trajectory_path, duration, periods, timeout, output,
                force, quiet, online, online_effort, stop, until_std,
            )  # fmt: skip
        except CaptureStopped:
            end_line()
            click.echo(
                f"guardid: interrupted ({stop.name}) before the capture started: nothing written",
                err=True,
            )
            sys.exit(stop.exit_code)
    end_line()
    errs = ", ".join(f"{math.degrees(e):.3f} deg" for e in result.rms_tracking_error_rad)
    if not result.rows:
        errs = "- (no rows)"
    st = result.link
    click.echo(
        f"{result.ended}: {result.rows} rows in {output} ({result.lost_rows} lost), "
        f"CRC errors {st['crc_errors']}, framing errors {st['framing_errors']}, "
        f"sequence gaps {st['seq_gaps']}, rms tracking error {errs}"
    )
    if tracker is not None:
        _online_summary(tracker, output, force)
    if result.ended == "interrupted":
        sys.exit(stop.exit_code if stop else 130)
    if live is not None:
        verdict = live.verdict()
        click.echo(f"{verdict} (live estimate; guardid identify {output} confirms it)")
        if not live.done():
            sys.exit(4)


def _capture(
    port, baud, robot, trajectory_path, duration, periods, timeout, output, force, quiet,
    online, online_effort, stop, until_std=None,
):  # fmt: skip
    """Check everything, then capture; return (CaptureResult, online tracker or None,
    :class:`guardid.online.information.UntilStd` or None)."""
    from guardid.capture import capture as run_capture
    from guardid.capture.checks import check_info, check_trajectory
    from guardid.capture.stop import StopAwarePort
    from guardid.commands.outputs import check_output, robot_file
    from guardid.link import Session, open_port
    from guardid.robot import load_robot

    if port is not None and not port.strip():
        raise ConfigError(
            "--port: empty (an unset variable?); give a serial device such as /dev/ttyUSB0, "
            "or leave --port out for the simulated robot"
        )
    inputs = [("--trajectory", trajectory_path), ("--robot", robot_file(robot))]
    check_output(output, inputs, force=force)
    description = load_robot(robot)
    trajectory = _load_trajectory(trajectory_path)
    if duration is not None and periods is not None:
        raise ConfigError("--duration and --periods: give one of them, not both")
    if duration is None and periods is None and until_std is not None:
        duration = UNTIL_STD_CAP_S
    if duration is None:
        duration = (periods or 1) * trajectory.period
    _check_room(output, duration, description)
    check_trajectory(trajectory, description, duration, trajectory_path)
    tracker = _tracker(online, description, trajectory, online_effort)
    live = None
    if until_std is not None:
        from guardid.online.information import UntilStd

        live = UntilStd(description, trajectory, until_std)
    if tracker is not None:
        from guardid.online import online_path

        check_output(online_path(output), inputs, option="--online output", force=force)
        if trajectory.period > TRACKING_PERIOD_S:
            click.echo(
                f"note: {trajectory_path} repeats every {trajectory.period:g} s; a change is "
                f"tracked within about one period (for {TRACKING_PERIOD_S:g} s: guardid excite "
                "--base-freq 0.2 --harmonics 3, docs/CAPTURE.md 'Excitation for tracking')",
                err=True,
            )
    port_url = f"sim://{robot}" if port is None else port
    stop.check()
    serial_port = open_port(port_url, baud)
    session = Session(StopAwarePort(serial_port, stop), timeout_s=timeout)
    try:
        try:
            info = session.handshake()
            check_info(info, description, port_url)
        except BaseException:
            stop.disarm()
            session.finish()  # best effort: leave the robot idle whatever went wrong
            raise
        header = {
            "robot": description.name,
            "robot_source": str(description.source),
            "port": port_url,
            "baud": baud,
            "protocol_version": info["protocol_version"],
            "firmware": {k: (list(v) if isinstance(v, tuple) else v) for k, v in info.items()},
            "sample_period_s": description.sample_period,
            "trajectory": trajectory.to_dict(),
            "duration_s": duration,
            "start_time": _dt.datetime.now(_dt.timezone.utc).isoformat(timespec="seconds"),
        }
        result = run_capture(
            session,
            description,
            trajectory,
            duration,
            output,
            header,
            progress=None if quiet else _progress_with(tracker, live),
            on_row=_on_row(tracker, live, quiet),
            stop=stop,
            overwrite=force,
            until=None if live is None else live.done,
        )
    finally:
        serial_port.close()
    return result, tracker, live


ROW_BYTES_BASE, ROW_BYTES_PER_JOINT = 30, 60
"""A log row's size at most [bytes]: tick, time and status, plus per joint counts, angle,
voltage, current and setpoint as :class:`guardid.log.LogWriter` formats them."""


def _check_room(output, duration_s: float, description) -> None:
    """ConfigError when the log of a ``duration_s`` [s] capture would not fit in the free
    space of ``output``'s file system (``--duration 1e9``: terabytes). Not for a device or
    a pipe given with --force (the log goes elsewhere)."""
    import shutil
    import stat
    from pathlib import Path

    if os.path.exists(output) and not stat.S_ISREG(os.stat(output).st_mode):
        return
    folder = Path(output).parent
    try:
        free = shutil.disk_usage(folder).free
    except OSError:
        return  # checked by check_output already; nothing more to say
    rows = duration_s / description.sample_period
    need = rows * (ROW_BYTES_BASE + ROW_BYTES_PER_JOINT * len(description.joints))
    if need > free:
        raise ConfigError(
            f"--duration {duration_s:g} s: the log {output} would need about "
            f"{_size(need)}, {_size(free)} free in {folder}"
        )


def _size(n_bytes: float) -> str:
    unit = "B"
    for unit in ("B", "kB", "MB", "GB", "TB"):
        if n_bytes < 1000 or unit == "TB":
            break
        n_bytes /= 1000
    return f"{n_bytes:.3g} {unit}"


def _progress(c: dict) -> None:
    errs = " ".join(f"{math.degrees(e):.2f}" for e in c["tracking_rms_rad"])
    click.echo(
        f"\rrows {c['rows']:6d}  lost {c['lost']:4d}  CRC {c['crc_errors']:3d}  "
        f"framing {c['framing_errors']:3d}  tracking rms [deg] {errs}   ",
        err=True,
        nl=False,
    )
    line_open(sys.stderr)


def _tracker(online, description, trajectory, effort):
    """The :class:`guardid.online.OnlineIdentifier` asked for by --online, or None."""
    if not online:
        return None
    from guardid.online import OnlineIdentifier

    methods = tuple(m.strip() for m in online.split(",") if m.strip())
    return OnlineIdentifier.for_trajectory(description, methods, trajectory, effort=effort)


def _progress_with(tracker, live=None):
    if live is not None:
        from guardid.online.information import LiveDisplay

        display = LiveDisplay(live, sys.stderr, tracker=tracker)

        def show_live(c: dict) -> None:
            display.show(c)
            if not display.tty:  # one line rewritten in place: still open
                line_open(sys.stderr)

        return show_live
    if tracker is None:
        return _progress

    def show(c: dict) -> None:
        click.echo(
            f"\rrows {c['rows']:6d}  lost {c['lost']:4d}  CRC {c['crc_errors']:3d}  "
            f"{tracker.status()}   ",
            err=True,
            nl=False,
        )
        line_open(sys.stderr)

    return show


def _on_row(tracker, live, quiet: bool):
    """The per-row callback feeding the --online tracker and the --until-std estimate."""
    if tracker is None and live is None:
        return None

    def feed(t_s, q, volts, amps) -> None:
        if live is not None:
            live.update(t_s, q, amps, volts)
        if tracker is not None:
            for report in tracker.update(t_s, q, amps, volts):
                click.echo(("" if quiet else "\r") + str(report), err=True)
                forget_line()  # the report overwrote the progress line and ended it

    return feed


def _online_summary(tracker, output: str, force: bool) -> None:
    from guardid.commands.outputs import EXISTS, replacing
    from guardid.online import online_path

    path = online_path(output)
    if not force and os.path.lexists(path):  # appeared during the capture
        raise ConfigError(EXISTS.format(option="--online output", path=path))
    with replacing(path, "--online output") as tmp:
        tracker.write_csv(tmp)
    final = "; ".join(
        f"{m.upper()} "
        + " ".join(f"{n} {v:.4g}" for n, v in zip(tracker.names, tracker.estimate(m), strict=True))
        for m in tracker.methods
    )
    click.echo(f"online estimates written to {path} ({tracker.used} of {tracker.rows} rows used)")
    click.echo(f"final online estimates: {final}")
    for report in tracker.reports:
        click.echo(str(report))
    if not tracker.reports:
        click.echo("no parameter change detected")
    click.echo(
        f"online step: {tracker.us_per_row:.0f} us per row on average "
        f"(sample period {tracker.dt * 1e3:.0f} ms), estimates lag the motion by "
        f"{tracker.latency_s:.3f} s"
    )
