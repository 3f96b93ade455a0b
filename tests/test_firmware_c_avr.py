"""The AVR example port (firmware_proto/avr) builds warning-free and fits an ATmega328P.

Skipped when avr-gcc (gcc-avr, avr-libc, binutils-avr) or make is not installed.
"""

from __future__ import annotations

import shutil
import subprocess
from pathlib import Path

import pytest

AVR = Path(__file__).resolve().parents[1] / "firmware_proto" / "avr"
TOOLS = ("avr-gcc", "avr-size", "avr-objcopy", "make")
missing = [t for t in TOOLS if shutil.which(t) is None]
if missing:
    pytest.skip(
        f"AVR port not built: {', '.join(missing)} not on PATH "
        "(apt-get install gcc-avr avr-libc binutils-avr make)",
        allow_module_level=True,
    )

# ATmega328P: 32 KB flash (0.5 KB of it for a bootloader), 2 KB RAM shared with the stack
LIMITS = {"atmega328p": (32 * 1024, 2 * 1024), "atmega2560": (256 * 1024, 8 * 1024)}


def avr_size(elf: Path) -> tuple[int, int]:
    """(flash, static RAM) in bytes from ``avr-size -A``: .text + .data, .data + .bss."""
    out = subprocess.run(["avr-size", "-A", str(elf)], capture_output=True, text=True, check=True)
    sizes = {}
    for line in out.stdout.splitlines():
        parts = line.split()
        if len(parts) >= 2 and parts[0].startswith(".") and parts[1].isdigit():
            sizes[parts[0]] = int(parts[1])
    flash = sizes.get(".text", 0) + sizes.get(".data", 0)
    ram = sizes.get(".data", 0) + sizes.get(".bss", 0) + sizes.get(".noinit", 0)
    return flash, ram


@pytest.mark.parametrize("mcu", ["atmega328p", "atmega2560"])
def test_avr_port_builds_warning_free_and_fits(tmp_path, mcu):
    build = tmp_path / mcu
    res = subprocess.run(
        ["make", "-s", "-f", str(AVR / "Makefile"), f"MCU={mcu}", f"BUILD={build}"],
        capture_output=True,
        text=True,
    )
    assert res.returncode == 0, res.stdout + res.stderr
    assert res.stderr == "" and "warning" not in res.stdout.lower(), res.stdout + res.stderr
    assert (build / "guard.hex").is_file()
    flash, ram = avr_size(build / "guard.elf")
    flash_max, ram_max = LIMITS[mcu]
    print(f"{mcu}: flash {flash} B of {flash_max}, static RAM {ram} B of {ram_max}")
    assert 0 < flash and 0 < ram
    # room to spare: a quarter of the flash free (bootloader, additions) and at least
    # 768 B of the ATmega328P's RAM left for the stack (deepest path < 0.5 KB)
    assert flash < 0.75 * 32 * 1024
    assert ram < 2 * 1024 - 768
