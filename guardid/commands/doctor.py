"""``guardid doctor``: bring-up checks of a robot on the bench."""

from __future__ import annotations

import sys

import click

from guardid.commands._types import POSITIVE
from guardid.errors import ConfigError

CHECK_FAILED_EXIT = 1
"""Exit code when a check fails (the run itself worked; 2, 3 keep their meanings)."""


@click.command()
@click.option(
    "--port",
    default=None,
    help="Serial device or URL [default: sim://<robot>]; an empty value is refused.",
)
@click.option(
    "--baud", type=click.IntRange(min=50), default=115200, show_default=True, help="Baud rate."
)
@click.option("--robot", default="guard", show_default=True, help="Shipped robot or YAML path.")
@click.option(
    "--timeout",
    type=POSITIVE,
    default=1.0,
    show_default=True,
    help="Longest wait for an answer or a telemetry frame [s].",
)
def doctor(port, baud, robot, timeout):
    """Check a robot on the bench: wiring, sensors, link, watchdog, e-stop; one verdict each.

    The robot must be free to move a little: each joint in turn gets a voltage pulse each
    way (half the supply for 0.3 s, checked against its position limits first; motors idle
    at once if a joint goes further than the pulse allows or the robot reports a fault).
    Checks: the current sensors' zero at rest; the link's round trip and jitter (20
    PINGs); the USB adapter's latency timer (Linux sysfs; 'unknown' for a pty or URL);
    that ESTOP latches and CLEAR_ESTOP releases; that the watchdog idles the motors after
    host silence; per joint, from the motor equation V = R i + Ke w fitted over the pulses
    against the YAML: the encoder's direction against the motor voltage, its counts per
    revolution (the back-EMF is the known move), the current sensor's sign and gain, and
    that the encoder counts at all; the supply voltage. Each row gives a verdict (ok,
    warn, FAIL, unknown) and, when not ok, the fix. Exit code 1 when a check fails.

    On the simulated robot, wiring faults come from sim://guard?wiring=... (e.g.
    encoder_reversed:tilt,motor_reversed:pan,current_offset:pan=0.1,current_gain:tilt=0.5,
    cpr:pan=96,stuck:tilt; docs/REAL_ROBOT.md).
    """
    from guardid.capture.checks import check_info
    from guardid.doctor import latency_check, run_checks
    from guardid.link import Session, open_port
    from guardid.robot import load_robot

    if port is not None and not port.strip():
        raise ConfigError(
            "--port: empty (an unset variable?); give a serial device such as /dev/ttyUSB0, "
            "or leave --port out for the simulated robot"
        )
    description = load_robot(robot)
    port_url = f"sim://{robot}" if port is None else port
    serial_port = open_port(port_url, baud)
    try:
        session = Session(serial_port, timeout_s=timeout)
        try:
            info = session.handshake()
            check_info(info, description, port_url)
        except BaseException:
            session.finish()
            raise
        checks = run_checks(session, description, latency_check(port_url))
    finally:
        serial_port.close()
    _print_table(checks)
    failed = [c for c in checks if c.failed]
    if failed:
        click.echo(f"{len(failed)} of {len(checks)} checks failed: fix them before a capture")
        sys.exit(CHECK_FAILED_EXIT)
    click.echo(f"all {len(checks)} checks passed or warned")


def _print_table(checks) -> None:
    """One row per check: name, joint, verdict, measured; the fix below a row not ok."""
    w_name = max(len(c.name) for c in checks)
    w_joint = max([len(c.joint) for c in checks] + [5])
    click.echo(f"{'check':{w_name}}  {'joint':{w_joint}}  {'verdict':7}  measured")
    for c in checks:
        click.echo(f"{c.name:{w_name}}  {c.joint or '-':{w_joint}}  {c.verdict:7}  {c.measured}")
        if c.fix:
            click.echo(f"{'':{w_name}}  {'':{w_joint}}  {'':7}  fix: {c.fix}")
