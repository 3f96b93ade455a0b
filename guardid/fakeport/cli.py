"""The ``fake-port`` click command (registered as ``guardid fake-port``).

Runnable alone as ``python -m guardid.fakeport.cli`` (same options).
"""

from __future__ import annotations

import signal
import sys

import click

from guardid.errors import report_errors
from guardid.fakeport.engine import LinkEngine
from guardid.fakeport.factory import DEVICE_ENV, make_device
from guardid.fakeport.options import parse_options
from guardid.fakeport.pty_server import PtyServer

_FAULTS = {
    "drop": "byte drop probability [0..1]",
    "flip": "bit flip probability [0..1]",
    "latency_ms": "FTDI-like latency timer [ms] (0 = off)",
    "disconnect_s": "disconnect after this simulated time [s]",
    "reconnect_s": "with --disconnect-s: the pty comes back (a new one, see --link) after "
    "this outage [s]; the robot runs on meanwhile",
    "payload_time": "attach the payload at this simulated time [s]",
    "payload_mass": "payload mass [kg]",
    "payload_com": "payload centre of mass x,y,z [m]",
    "start": "start each joint at a seeded point within +-this many encoder counts (<= 2^30)",
    "supply": "this run's supply voltage within +-this fraction of nominal (seeded)",
    "ripple": "supply ripple from tick to tick, std as a fraction of the supply (seeded)",
    "params": "serve a twin: the rigid body and friction of a params.yaml from guardid identify "
    "or a reference values file (docs/REPLAY.md)",
    "method": "with --params: the params file's method [default: its first]",
    "wiring": "wiring faults, comma-separated kind:joint[=value] (encoder_reversed, "
    "motor_reversed, current_offset=A, current_drift=A_PER_S, current_gain=G, cpr=COUNTS, "
    "stuck; guardid doctor)",
}


def _flag(name: str) -> str:
    return "--" + name.replace("_", "-")


def _fault_options(func):
    for name, help_text in reversed(_FAULTS.items()):
        func = click.option(_flag(name), name, default=None, help=help_text)(func)
    return func


class _Command(click.Command):
    """Report GuardidError as one line also when run without the guardid group."""

    def invoke(self, ctx: click.Context):
        return report_errors(super().invoke, ctx)


@click.command("fake-port", cls=_Command)
@click.option("--robot", default="guard", show_default=True, help="Robot name or YAML path.")
@click.option("--seed", default="0", show_default=True, help="Seed for noise and faults.")
@click.option(
    "--pacing", default="lockstep", show_default=True, help="lockstep, realtime or a factor."
)
@click.option("--noise/--no-noise", default=True, help="Sensor noise in the emulator.")
@click.option(
    "--firmware",
    type=click.Choice(["py", "c", "avr"]),
    default="py",
    show_default=True,
    help="Python emulator, C core (host build) or the AVR port's binary in simavr.",
)
@click.option(
    "--mcu",
    type=click.Choice(["atmega328p", "atmega2560"]),
    default=None,
    help="With --firmware avr: the simulated MCU [default: atmega328p].",
)
@click.option(
    "--bootloader",
    type=click.Choice(["optiboot", "stk500v2"]),
    default=None,
    help="With --firmware avr: run the Arduino boot loader from every reset (optiboot: "
    "atmega328p, stk500v2: atmega2560, the default --mcu for it); each program that opens "
    "the pty resets the MCU as a board's DTR line does, so avrdude can flash it.",
)
@click.option("--upstream", is_flag=True, help="Also corrupt host->device bytes.")
@click.option(
    "--phase",
    is_flag=True,
    help="Start each joint at a seeded random point within one encoder count (as a real "
    "robot, zeroed where it rests; then seeds differ in quantisation and motion too).",
)
@_fault_options
@click.option(
    "--idle-ms",
    default=100.0,
    show_default=True,
    help="Lock-step: step anyway after this much host silence [ms] (0 = never).",
)
@click.option(
    "--settle-ms",
    default=2.0,
    show_default=True,
    help="Lock-step: host silence after its answer before a step [ms].",
)
@click.option(
    "--link",
    default=None,
    help="Keep a symlink at this path to the pty (as /dev/serial/by-id/... does), moved "
    "to the new pty when it comes back after --reconnect-s; removed at exit.",
)
@click.option("--device", "device_name", default=None, hidden=True, envvar=DEVICE_ENV)
def fake_port(
    robot,
    seed,
    pacing,
    noise,
    firmware,
    mcu,
    bootloader,
    upstream,
    phase,
    idle_ms,
    settle_ms,
    link,
    device_name,
    **faults,
):
    """Serve the emulated robot on a pseudo-terminal until SIGINT/SIGTERM.

    The first stdout line is the device path (e.g. /dev/pts/5) to open with pyserial.
    """
    raw = {"seed": seed, "pacing": pacing, "noise": "1" if noise else "0", "firmware": firmware}
    raw["upstream"] = "1" if upstream else "0"
    raw["phase"] = "1" if phase else "0"
    if mcu is not None:
        raw["mcu"] = mcu
    if bootloader is not None:
        raw["bootloader"] = bootloader
    raw.update({k: v for k, v in faults.items() if v is not None})
    options = parse_options(robot, raw, label=_flag)
    device = make_device(options.robot, options, name=device_name)
    engine = LinkEngine(device, options.faults, options.seed, name="fake-port")
    server = PtyServer(
        engine, options.pacing, idle_s=idle_ms / 1000.0, settle_s=settle_ms / 1000.0, link=link
    )
    stop = []

    def on_signal(signum, frame):
        stop.append(signum)

    previous = {sig: signal.signal(sig, on_signal) for sig in (signal.SIGINT, signal.SIGTERM)}
    try:
        click.echo(server.path)
        sys.stdout.flush()
        reason = server.serve(lambda: bool(stop))
    finally:
        server.close()
        device.close()
        for sig, handler in previous.items():
            signal.signal(sig, handler)
    if reason == "disconnected":
        click.echo(f"fake-port: link disconnected at {engine.now_s:.3f} s simulated", err=True)


if __name__ == "__main__":
    fake_port()
