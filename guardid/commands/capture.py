"""``guardid capture``: drive the robot along a trajectory and log its telemetry."""

from __future__ import annotations

import datetime as _dt
import math
import os
import sys
from pathlib import Path

import click

from guardid.commands._status import end_line, forget_line, line_open
from guardid.commands._types import POSITIVE
from guardid.commands.outputs import check_room, force_option, output_option
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
@click.option(
    "--no-reset",
    "no_reset",
    is_flag=True,
    help="Open a board's port without pulsing DTR and handshake at once (default: reset the "
    "Arduino-class board, wait out its boot loader for the firmware's INFO, then HELLO with "
    "retries; docs/REAL_ROBOT.md 'Connecting').",
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
    type=POSITIVE,
    default=None,
    help="Keep the robot on its excitation until every base parameter is identified to this "
    "relative standard deviation [%] (live least squares on the causal conditioning; a "
    "parameter within 3 std of zero counts when its std is this share of its kind's "
    "scale), at least one trajectory period; --duration / --periods is then the cap "
    f"[default cap: {UNTIL_STD_CAP_S:g} s]. Exit 4 when the cap comes first.",
)
@click.option(
    "--stream",
    "stream_url",
    default=None,
    metavar="udp://HOST:PORT",
    help="Also send every row, as it is logged, as one JSON datagram to HOST:PORT "
    "(PlotJuggler: Streaming > UDP Server, JSON, 'use field as timestamp' = timestamp; "
    "its default port is 9870). Fields group per joint: timestamp [s], tick, status, "
    "<joint>/q_rad, setpoint_rad, v_V, i_A, counts. Non-blocking: a datagram that cannot "
    "be sent is counted and skipped, never slowing the capture. docs/LIVE.md.",
)
@click.option(
    "--reconnect",
    "reconnect_s",
    type=POSITIVE,
    default=None,
    help="When the port vanishes mid-capture (a bumped USB cable; the robot's watchdog "
    "idles it), wait up to this long [s] for it to come back, handshake again and go on "
    "from the trajectory's next rest point (a period's start), approached slowly from "
    "where the robot rests; the rows in between are lost (a gap, which identify splits "
    "runs at) and the footer counts reconnects. A robot that restarted meanwhile (its "
    "tick went back: the encoder zero is lost) is not resumed. Without it (or when the "
    "port is not back in time, or does not answer) the capture ends, rows kept, exit 3.",
)
@click.option(
    "--feedforward",
    "feedforward_path",
    default=None,
    help="params.yaml (guardid identify): stream with each setpoint the motor voltage the "
    "trajectory needs by the identified model (its WLS, else LS, base parameters: rigid "
    "body, rotor inertia, friction; its motors' R and Ke; V = R i + Ke N q', i = tau / "
    "(N eta Kt) from the robot YAML's drive), evaluated on the trajectory's exact q, q', q'' "
    "at the middle of each tick's period; the firmware adds it to its PID output before "
    "the limits. Refused before anything moves (exit 2) when the trajectory needs more "
    "than a motor's supply voltage, or when the firmware's INFO lacks the feedforward "
    "capability (protocol version 2).",
)
@click.option(
    "--zero-rest",
    "zero_rest_s",
    type=click.FloatRange(min=0.0),
    default=None,
    help="After the trajectory (and before it with --zero-before), hold the motors at 0 V "
    "and, once the joints stand still, read the current sensors for this long [s]: their "
    "zero goes to the log's footer (current_zero) and identify subtracts it, every std "
    "counting its error (docs/IDENTIFY.md 'The current sensors' zero'). 0: not read. The "
    "rows read at rest are not logged; a stop (Ctrl-C) during a rest keeps what was read. "
    "[default: 10 % of the run's length, 2 s to 120 s; before the run, of the length "
    "asked for (--duration, --periods; with --until-std its cap)]",
)
@click.option(
    "--zero-before",
    is_flag=True,
    help="Read the current sensors' zero before the trajectory too (footer: "
    "current_zero_before): identify then subtracts the straight line between the two "
    "zeros, following a zero that drifts during the run (a Hall sensor warming up). An arm "
    "that sank at 0 V (or a trajectory that does not start where the robot rests) is led "
    "to the trajectory's first setpoint by an approach within half the joints' limits and "
    "a 0.5 s hold (its rows not logged; the footer's start_approach_ticks); a PID slow to "
    "hold the arm against gravity may still lag at the first row. Off by default: the log "
    "then starts as without it.",
)
def capture(
    port, baud, robot, trajectory_path, duration, periods, timeout, no_reset, output, force,
    quiet, online, online_effort, until_std, stream_url, reconnect_s, feedforward_path,
    zero_rest_s, zero_before,
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
            result, tracker, live, stream = _capture(
                port, baud, robot, trajectory_path, duration, periods, timeout, output,
                force, quiet, online, online_effort, stop, until_std, stream_url,
                reset=not no_reset, reconnect_s=reconnect_s,
                feedforward_path=feedforward_path, zero_rest_s=zero_rest_s,
                zero_before=zero_before,
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
    zeros = {k: result.extra.get(k) for k in ("current_zero_before", "current_zero")}
    if any(zeros.values()):
        click.echo(_zero_summary(zeros))
    if stream is not None:
        click.echo(stream.summary())
    if tracker is not None:
        _online_summary(tracker, output, force)
    if result.ended == "interrupted":
        sys.exit(stop.exit_code if stop else 130)
    if live is not None:
        verdict = live.verdict()
        click.echo(f"{verdict} (live estimate; guardid identify {output} confirms it)")
        if not live.done():
            sys.exit(4)


def _zero_summary(zeros: dict) -> str:
    """The capture's line on the current sensors' zeros it read at rest (``zeros``: the
    footer's ``current_zero_before`` and ``current_zero``, None when not read)."""
    read = [(k, zeros[k]) for k in ("current_zero_before", "current_zero") if zeros.get(k)]
    if len(read) == 1:
        return "current sensors' zero" + _zero_part(read[0][1], "; in the footer")
    parts = [("before the run" if k == "current_zero_before" else "after it") + _zero_part(z)
             for k, z in read]  # fmt: skip
    return f"current sensors' zero {'; '.join(parts)} (in the footer)"


def _zero_part(zero: dict, tail: str = "") -> str:
    if "not_measured" in zero:
        return f": not read ({zero['not_measured']})"
    parts = [f"{name} {1e3 * z['mean_a']:+.2f} mA" for name, z in zero.items()]
    rows = max(z["rows"] for z in zero.values())
    return f" at rest: {', '.join(parts)} ({rows} rows{tail})"


def _capture(
    port, baud, robot, trajectory_path, duration, periods, timeout, output, force, quiet,
    online, online_effort, stop, until_std=None, stream_url=None, reset=True,
    reconnect_s=None, feedforward_path=None, zero_rest_s=None, zero_before=False,
):  # fmt: skip
    """Check everything, then capture; return (CaptureResult, online tracker or None,
    :class:`guardid.online.information.UntilStd` or None, :class:`guardid.live.udp.UdpStream`
    or None)."""
    from guardid.capture import capture as run_capture
    from guardid.capture.checks import check_feedforward_capability, check_info, check_trajectory
    from guardid.capture.stop import StopAwarePort
    from guardid.commands.outputs import check_output, robot_file
    from guardid.link import Session, open_port
    from guardid.link.board import connect
    from guardid.robot import load_robot

    if port is not None and not port.strip():
        raise ConfigError(
            "--port: empty (an unset variable?); give a serial device such as /dev/ttyUSB0, "
            "or leave --port out for the simulated robot"
        )
    if feedforward_path is not None and reconnect_s is not None:
        raise ConfigError(
            "--feedforward with --reconnect: not supported yet (the slow approach that resumes "
            "a run after a reconnect has no feedforward); use one of them"
        )
    target = None
    if stream_url is not None:
        from guardid.live.udp import parse_stream_url

        target = parse_stream_url(stream_url)
    inputs = [("--trajectory", trajectory_path), ("--robot", robot_file(robot))]
    if feedforward_path is not None:
        inputs.append(("--feedforward", feedforward_path))
    check_output(output, inputs, force=force)
    description = load_robot(robot)
    trajectory = _load_trajectory(trajectory_path)
    if duration is not None and periods is not None:
        raise ConfigError("--duration and --periods: give one of them, not both")
    if zero_before and zero_rest_s == 0:
        raise ConfigError("--zero-before with --zero-rest 0: no zero would be read; give a rest")
    if duration is None and periods is None and until_std is not None:
        duration = UNTIL_STD_CAP_S
    if duration is None:
        duration = (periods or 1) * trajectory.period
    check_room(output, duration, description.sample_period,
               ROW_BYTES_BASE + ROW_BYTES_PER_JOINT * len(description.joints))  # fmt: skip
    check_trajectory(trajectory, description, duration, trajectory_path)
    feedforward = _feedforward(feedforward_path, description, trajectory)
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
    stream = _stream(target, description)
    try:
        stop.check()
        serial_port = open_port(port_url, baud, reset=reset)
    except BaseException:
        if stream is not None:
            stream.close()
        raise
    session = Session(StopAwarePort(serial_port, stop), timeout_s=timeout)
    reconnector = _Reconnector(session, serial_port, port_url, baud, reconnect_s, description,
                               stop)  # fmt: skip
    try:
        try:
            info = connect(session, port_url, reset=reset)
            check_info(info, description, port_url)
            if feedforward is not None:
                check_feedforward_capability(info, port_url)
        except BaseException:
            stop.disarm()
            session.finish()  # best effort: leave the robot idle whatever went wrong
            raise
        header = {
            "robot": description.name,
            # absolute: identify finds the robot from any directory
            "robot_source": str(Path(description.source).resolve()) if description.source else "",
            "port": port_url,
            "baud": baud,
            "protocol_version": info["protocol_version"],
            "firmware": {k: (list(v) if isinstance(v, tuple) else v) for k, v in info.items()},
            "sample_period_s": description.sample_period,
            "trajectory": trajectory.to_dict(),
            "duration_s": float(duration),
            "feedforward": None if feedforward is None else feedforward.label,
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
            on_record=None if stream is None else stream.send_row,
            reconnect=None if reconnect_s is None else reconnector.reconnect,
            notify=_notify,
            feedforward=feedforward,
            zero_rest_s=zero_rest_s,
            zero_before=zero_before,
        )
    finally:
        for p in reconnector.ports:
            p.close()
        if stream is not None:
            stream.close()
    return result, tracker, live, stream


def _stream(target, description):
    """The --stream sender to ``target`` (None: no --stream)."""
    if target is None:
        return None
    from guardid.live.udp import UdpStream

    return UdpStream(target, [j.name for j in description.joints])


def _notify(message: str) -> None:
    end_line()
    click.echo(f"guardid: {message}", err=True)


class _Reconnector:
    """``capture --reconnect``: wait for the port, re-attach the session, handshake and
    check INFO again; ``ports`` are every port opened (closed at the end)."""

    def __init__(self, session, port, url, baud, within_s, description, stop) -> None:
        self.session, self.ports, self.url, self.baud = session, [port], url, baud
        self.within_s, self.description, self.stop = within_s, description, stop

    def reconnect(self):
        from guardid.capture.checks import check_info
        from guardid.capture.stop import StopAwarePort
        from guardid.errors import LinkError
        from guardid.link.reconnect import wait_for_port

        self.stop.check()
        port = wait_for_port(
            self.ports[-1], self.url, self.baud, self.within_s, check=self.stop.check
        )
        if port is None:
            raise LinkError(f"port {self.url}: gone, not back within {self.within_s:g} s")
        if port is not self.ports[-1]:
            self.ports.append(port)
        self.session.reattach(StopAwarePort(port, self.stop))
        try:
            info = self.session.handshake()
        except LinkError as exc:
            raise LinkError(f"{exc} (the port came back, the robot did not answer)") from None
        check_info(info, self.description, self.url)
        return self.session


def _feedforward(path, description, trajectory):
    """The --feedforward model, checked against every motor's supply (None without it)."""
    if path is None:
        return None
    from guardid.feedforward import check_supply, load_feedforward

    model = load_feedforward(path, description)
    check_supply(model, trajectory, f"--feedforward {path}")
    return model


ROW_BYTES_BASE, ROW_BYTES_PER_JOINT = 30, 60
"""A log row's size at most [bytes]: tick, time and status, plus per joint counts, angle,
voltage, current and setpoint as :class:`guardid.log.LogWriter` formats them."""


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
