"""The AVR firmware built for one robot: its ``robot_config.h`` generated from the YAML, the
board's pin map (``firmware_proto/avr/board.h`` for the MCU), and an id of its own.

The id (INFO's ``firmware_id``) is the first 32 bits of a SHA-256 over the generated header,
the MCU and the firmware sources: the same robot and sources give the same id on any
machine, and INFO after flashing says which build runs.
"""

from __future__ import annotations

import hashlib
from dataclasses import dataclass
from pathlib import Path

from guardid.errors import ConfigError
from guardid.firmware.avr_sim.build import build_elf, build_hex, source_digest
from guardid.firmware.avr_sim.robot_header import RobotHeaderError, render


@dataclass(frozen=True)
class FirmwareBuild:
    """A build: robot name, MCU, ``firmware_id``, ELF and Intel HEX paths, flash bytes."""

    robot: str
    mcu: str
    firmware_id: int
    elf: Path
    hex: Path
    flash_bytes: int


def firmware_id(header: str, mcu: str) -> int:
    """The build's id (module docstring)."""
    h = hashlib.sha256(f"{header}\0{mcu}\0{source_digest()}".encode()).digest()
    return int.from_bytes(h[:4], "big")


def build_for_robot(description, mcu: str) -> FirmwareBuild:
    """Build the firmware for ``description`` (a loaded robot) on ``mcu``.

    ConfigError naming the YAML field the AVR port cannot take (two quadrature joints, 8-bit
    PWM, 10-bit ADC sensors, a 1..32 ms sample period)."""
    try:
        header = render(description, str(description.source))
    except RobotHeaderError as exc:
        raise ConfigError(f"{description.source}: {exc}") from None
    fid = firmware_id(header, mcu)
    elf = build_elf(mcu, f"-DFIRMWARE_ID={fid:#010x}UL", robot_header=header)
    hex_path = build_hex(elf)
    size = sum(int(line[1:3], 16) for line in hex_path.read_text().splitlines()
               if line.startswith(":") and line[7:9] == "00")  # fmt: skip
    return FirmwareBuild(description.name, mcu, fid, elf, hex_path, size)
