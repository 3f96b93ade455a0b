"""``guardid ports``: the serial ports, with a latency-timer check."""

from __future__ import annotations

import click


@click.command()
def ports():
    """List serial ports; warn when a USB-serial adapter's latency timer is above 2 ms.

    The built-in simulated robot is always available as sim://guard (or sim://<robot>).
    """
    from guardid.link.ports import serial_ports

    found = serial_ports()
    for p in found:
        latency = "" if p.latency_ms is None else f"  latency {p.latency_ms} ms"
        click.echo(f"{p.device}  {p.description}  [{p.hwid}]{latency}")
    if not found:
        click.echo("no serial ports found")
    click.echo("sim://guard  built-in simulated guard robot (any robot: sim://<name or YAML>)")
    for p in found:
        if p.latency_warning:
            click.echo(f"warning: {p.latency_warning}", err=True)
