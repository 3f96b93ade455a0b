"""Run avrdude against a board's serial boot loader and say in one line what went wrong.

avrdude (Debian package ``avrdude``) writes the Intel HEX image through the boot loader
(``-D``: the boot loaders erase each page as they write it) and reads it back to verify
(its default). Its failures, by its own messages (7.1):

* the program is missing -> exit 2 (install it);
* the port cannot be opened -> exit 3;
* no answer from a boot loader (``not in sync``, ``not responding``, ``timeout``) -> exit
  3: not an Arduino boot loader at that baud, the wrong ``--board``, or no reset;
* another chip answered (``signature``) -> exit 2: the wrong ``--board``;
* read back differs (``verification error``, ``mismatch``) -> exit 3.
"""

from __future__ import annotations

import re
import shutil
import subprocess
from pathlib import Path

from guardid.errors import ConfigError, GuardidError, LinkError
from guardid.flash.boards import Board

TIMEOUT_S = 120.0  #: [s] an ATmega2560's 256 kB at 115200 baud take about 60 s


class AvrdudeError(LinkError):
    """avrdude failed talking to the board (exit 3)."""


_NO_ANSWER = re.compile(r"not in sync|not responding|timeout|no response|protocol e", re.I)
_OPEN = re.compile(r"ser_open|cannot open port|can't open device", re.I)
_SIGNATURE = re.compile(r"signature\s*=\s*(0x[0-9a-f]+|[0-9a-f ]{6,})", re.I)
_VERIFY = re.compile(r"verification error|verify error|mismatch", re.I)


def avrdude_command(board: Board, port: str, hex_path: Path, avrdude: str = "avrdude") -> list:
    """The avrdude command line that writes and verifies ``hex_path`` on ``board``."""
    return [avrdude, "-p", board.part, "-c", board.programmer, "-P", port, "-b",
            str(board.baud), "-D", "-U", f"flash:w:{hex_path}:i"]  # fmt: skip


def explain(board: Board, port: str, stderr: str) -> GuardidError:
    """The one-line error for avrdude's output ``stderr`` (module docstring)."""
    from guardid.flash.boards import MCU_NAMES

    lines = [ln.strip() for ln in stderr.splitlines() if ln.strip()]
    want = MCU_NAMES.get(board.mcu, board.mcu)
    if _VERIFY.search(stderr):
        return AvrdudeError(
            f"port {port}: the flash read back differs from the image written "
            "(verification failed): flash again; if it persists the board's flash or its "
            "lock bits refuse writes"
        )
    if any("expected signature" in ln.lower() or "invalid device signature" in ln.lower()
           for ln in lines):  # fmt: skip
        found = _SIGNATURE.search(stderr)
        sig = found.group(1).strip() if found else "unknown"
        return ConfigError(
            f"--board {board.name}: the board on {port} is not an {want} (device signature "
            f"{sig}); choose the matching --board"
        )
    if _OPEN.search(stderr):
        return AvrdudeError(f"port {port}: avrdude cannot open it ({_first_error(lines)})")
    if _NO_ANSWER.search(stderr):
        return AvrdudeError(
            f"port {port}: no answer from the {board.bootloader} boot loader of --board "
            f"{board.name} at {board.baud} baud (another board, a sketch without boot "
            "loader, or the reset on open did not reach it)"
        )
    return AvrdudeError(f"port {port}: avrdude failed: {_first_error(lines)}")


def _first_error(lines: list[str]) -> str:
    for ln in lines:
        if "error" in ln.lower():
            return ln
    return lines[-1] if lines else "no output"


def require_avrdude(avrdude: str = "avrdude") -> None:
    """ConfigError (exit 2) when the program ``avrdude`` cannot be found."""
    if shutil.which(avrdude) is None:
        raise ConfigError(f"{avrdude}: not found; install it (apt-get install avrdude)")


def run_avrdude(board: Board, port: str, hex_path: Path, avrdude: str = "avrdude") -> str:
    """Write and verify ``hex_path``; return avrdude's output. ConfigError when avrdude is
    missing, else :func:`explain`'s error when it fails."""
    require_avrdude(avrdude)
    cmd = avrdude_command(board, port, hex_path, avrdude)
    try:
        res = subprocess.run(cmd, capture_output=True, text=True, timeout=TIMEOUT_S)
    except subprocess.TimeoutExpired:
        raise AvrdudeError(f"port {port}: avrdude did not finish in {TIMEOUT_S:g} s") from None
    out = (res.stdout or "") + (res.stderr or "")
    if res.returncode != 0:
        raise explain(board, port, out)
    return out
