"""The boards ``guardid flash`` knows: MCU, avrdude part and programmer, boot loader baud."""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class Board:
    """An Arduino-class board: ``mcu`` (avr-gcc name; the pin map is ``board.h``'s for it),
    ``part`` and ``programmer`` (avrdude's ``-p``/``-c``), ``baud`` [bit/s] of its boot
    loader, ``bootloader`` the boot loader's name (messages, docs)."""

    name: str
    mcu: str
    part: str
    programmer: str
    baud: int
    bootloader: str


BOARDS = {
    b.name: b
    for b in (
        Board("uno", "atmega328p", "m328p", "arduino", 115200, "optiboot"),
        Board("nano", "atmega328p", "m328p", "arduino", 115200, "optiboot"),
        Board("nano-old", "atmega328p", "m328p", "arduino", 57600, "ATmegaBOOT"),
        Board("mega", "atmega2560", "m2560", "wiring", 115200, "stk500v2"),
    )
}
"""By ``--board`` name; ``nano-old``: Nanos sold before 2018 (the old 57600-baud loader)."""

MCU_NAMES = {"atmega328p": "ATmega328P", "atmega2560": "ATmega2560"}
