"""``guardid flash``: build the AVR firmware for the robot, flash it, check what runs."""

from __future__ import annotations

import click

from guardid.commands._types import POSITIVE


@click.command()
@click.option("--port", required=True, help="The board's serial device, e.g. /dev/ttyACM0.")
@click.option("--robot", default="guard", show_default=True, help="Shipped robot or YAML path.")
@click.option(
    "--board",
    "board_name",
    type=click.Choice(["uno", "nano", "nano-old", "mega"]),
    default="uno",
    show_default=True,
    help="uno/nano: ATmega328P with optiboot (nano-old: the 57600-baud loader of Nanos "
    "before 2018); mega: ATmega2560 with stk500v2. The pin map is "
    "firmware_proto/avr/board.h's for the board's MCU.",
)
@click.option("--avrdude", default="avrdude", show_default=True, help="The avrdude program to run.")
@click.option(
    "--timeout",
    type=POSITIVE,
    default=1.0,
    show_default=True,
    help="Longest wait for an answer from the new firmware [s] (after its boot loader).",
)
def flash(port, robot, board_name, avrdude, timeout):
    """Build the AVR firmware for ROBOT, flash and verify it, check INFO's firmware id.

    Steps: robot_config.h generated from the YAML (every robot number the firmware keeps);
    the firmware built for the board's MCU with its own firmware id; written through the
    board's serial boot loader with avrdude, which reads it back to verify; then the port
    opened again (the board resets, its boot loader hands over) and INFO must report the
    build's id. Exit 2: bad robot YAML, avrdude missing, a board of another kind answered;
    exit 3: the port, no answer from the boot loader, verification failed, or INFO reports
    another firmware.
    """
    from guardid.capture.checks import check_info
    from guardid.errors import LinkError
    from guardid.flash import BOARDS, build_for_robot, run_avrdude
    from guardid.flash.avrdude import require_avrdude
    from guardid.link import Session, open_port
    from guardid.link.board import connect
    from guardid.robot import load_robot

    board = BOARDS[board_name]
    require_avrdude(avrdude)
    description = load_robot(robot)
    build = build_for_robot(description, board.mcu)
    click.echo(
        f"built {build.robot} for {board.mcu} (--board {board.name}): {build.flash_bytes} "
        f"bytes of flash, firmware id {build.firmware_id:#010x}"
    )
    run_avrdude(board, port, build.hex, avrdude)
    click.echo(f"flashed and verified {build.hex.name} through {board.bootloader} on {port}")
    serial_port = open_port(port, 115200)
    try:
        session = Session(serial_port, timeout_s=timeout)
        info = connect(session, port)
    finally:
        serial_port.close()
    if info["firmware_id"] != build.firmware_id:
        raise LinkError(
            f"port {port}: INFO reports firmware id {info['firmware_id']:#010x}, the build "
            f"flashed is {build.firmware_id:#010x}: the board did not start the new firmware"
        )
    check_info(info, description, port)
    click.echo(f"INFO on {port}: firmware id {build.firmware_id:#010x}, the new build runs")
