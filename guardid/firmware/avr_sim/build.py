"""Build what ``firmware=avr`` runs: the AVR ELF (``make -C firmware_proto/avr``) and the host
shim that binds it to simavr (``firmware_proto/simavr/avr_sim.c``), cached like the C core.

Both go to the cache directory of :func:`guardid.firmware.c_core.cache_dir`, under names that
carry a hash of every source, the flags and the compiler, so a changed file rebuilds and
concurrent builders agree (atomic rename).
"""

from __future__ import annotations

import hashlib
import os
import shutil
import subprocess
import tempfile
from pathlib import Path

from guardid.firmware.c_core import (
    FIRMWARE_DIR,
    FirmwareBuildError,
    build_cached,
    cache_dir,
    find_compiler,
)

MCUS = ("atmega328p", "atmega2560")
AVR_DIR = FIRMWARE_DIR / "avr"
SHIM = FIRMWARE_DIR / "simavr" / "avr_sim.c"
SHIM_CFLAGS = ("-std=c99", "-Wall", "-Wextra", "-Werror", "-pedantic", "-O2", "-shared", "-fPIC")
SHIM_LIBS = ("-lsimavr", "-lm")
SIMAVR_HEADER = Path("/usr/include/simavr/sim_avr.h")
AVR_TOOLS = ("avr-gcc", "avr-objcopy", "avr-nm", "make")
F_CPU = 16_000_000
BOOTLOADER_DIR = Path("/usr/share/arduino/hardware/arduino/avr/bootloaders")
#: The Arduino boot loaders (Debian's arduino-core-avr) per name: the MCU and the image.
BOOTLOADERS = {
    "optiboot": ("atmega328p", BOOTLOADER_DIR / "optiboot" / "optiboot_atmega328.hex"),
    "stk500v2": ("atmega2560", BOOTLOADER_DIR / "stk500v2" / "stk500boot_v2_mega2560.hex"),
}


def bootloader_hex(name: str, mcu: str) -> Path:
    """The boot loader image ``name`` for ``mcu`` (FirmwareBuildError naming the fix)."""
    if name not in BOOTLOADERS:
        raise FirmwareBuildError(
            f"bootloader={name}: unknown boot loader (known: {', '.join(BOOTLOADERS)})"
        )
    want, path = BOOTLOADERS[name]
    if mcu != want:
        raise FirmwareBuildError(f"bootloader={name}: runs on mcu={want}, not mcu={mcu}")
    if not path.is_file():
        raise FirmwareBuildError(
            f"bootloader={name}: {path} missing (apt-get install arduino-core-avr)"
        )
    return path


def missing_toolchain() -> list[str]:
    """What ``firmware=avr`` lacks on this machine (empty when it can run)."""
    missing = [t for t in AVR_TOOLS if shutil.which(t) is None]
    if find_compiler() is None:
        missing.append("a host C compiler (gcc)")
    if not SIMAVR_HEADER.is_file():
        missing.append("libsimavr-dev (simavr headers)")
    return missing


def _require_toolchain() -> None:
    missing = missing_toolchain()
    if missing:
        raise FirmwareBuildError(
            f"firmware=avr: {', '.join(missing)} missing "
            "(apt-get install gcc-avr avr-libc binutils-avr simavr libsimavr-dev), "
            "or use firmware=py|c"
        )


def _digest(paths, extra: str) -> str:
    h = hashlib.sha256()
    for path in sorted(paths):
        h.update(str(path.relative_to(FIRMWARE_DIR)).encode() + b"\0" + path.read_bytes())
    h.update(extra.encode())
    return h.hexdigest()[:16]


def _firmware_sources() -> list[Path]:
    files = [*AVR_DIR.glob("*.[ch]"), AVR_DIR / "Makefile"]
    files += [FIRMWARE_DIR / n for n in ("guard_proto.c", "guard_proto.h", "guard_proto_msgs.h")]
    files += [FIRMWARE_DIR / "core" / n for n in ("guard_fw.c", "guard_fw.h")]
    return files


def _run(cmd, what: str) -> None:
    res = subprocess.run(cmd, capture_output=True, text=True)
    if res.returncode != 0:
        lines = (res.stderr or res.stdout).strip().splitlines() or ["(no output)"]
        raise FirmwareBuildError(f"firmware=avr: {what} failed: {lines[0]}")


def build_elf(mcu: str = "atmega328p", extra_cflags: str = "", robot_header: str = "") -> Path:
    """The AVR firmware's ELF for ``mcu`` (built with the port's own Makefile on first use).

    ``extra_cflags`` (tests) is appended to the compiler flags, e.g.
    ``-DBOARD_ENC0_SIGN=-1`` to build a deliberately broken port. ``robot_header``: the
    text of a ``robot_config.h`` generated for another robot (``guardid flash``), used in
    place of the port's own."""
    if mcu not in MCUS:
        raise FirmwareBuildError(f"mcu={mcu}: unknown MCU (known: {', '.join(MCUS)})")
    _require_toolchain()
    avr_gcc = os.path.realpath(shutil.which("avr-gcc") or "avr-gcc")
    tag = _digest(_firmware_sources(), f"{mcu}|{extra_cflags}|{avr_gcc}|{robot_header}")
    out = cache_dir() / f"guard-avr-{mcu}-{tag}.elf"
    if out.is_file():
        return out
    out.parent.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory(dir=out.parent) as tmp:
        cmd = ["make", "-s", "-f", str(AVR_DIR / "Makefile"), f"MCU={mcu}", f"BUILD={tmp}"]
        if extra_cflags:
            cmd.append(f"EXTRA_CFLAGS={extra_cflags}")
        if robot_header:
            header = Path(tmp) / "robot_config.h"
            header.write_text(robot_header)
            cmd.append(f"ROBOT_CONFIG={header}")
        cmd.append(f"{tmp}/guard.elf")
        _run(cmd, f"building the AVR firmware for {mcu}")
        os.replace(Path(tmp) / "guard.elf", out)
    return out


def source_digest() -> str:
    """A digest of the firmware's sources (not of the compiler): part of a build's id."""
    return _digest(_firmware_sources(), "")


def build_hex(elf: Path) -> Path:
    """The flash image of ``elf`` as Intel HEX beside it (``avr-objcopy``, no EEPROM)."""
    out = elf.with_suffix(".hex")
    if not out.is_file():
        tmp = out.with_suffix(f".{os.getpid()}.tmp")
        _run(["avr-objcopy", "-O", "ihex", "-R", ".eeprom", str(elf), str(tmp)],
             "converting the ELF to Intel HEX")  # fmt: skip
        os.replace(tmp, out)
    return out


def build_shim() -> Path:
    """The host shim library (simavr binding) for the current sources and compiler."""
    _require_toolchain()
    cc = find_compiler()
    tag = _digest([SHIM], " ".join((os.path.realpath(cc), *SHIM_CFLAGS, *SHIM_LIBS)))
    lib = cache_dir() / f"libguard_avr_sim-{tag}.so"
    return build_cached(lib, lambda out: [cc, *SHIM_CFLAGS, str(SHIM), "-o", out, *SHIM_LIBS],
                        "firmware=avr: building the simavr shim")  # fmt: skip


def ram_symbols(elf: Path, names) -> dict[str, int]:
    """Data-space addresses of the firmware's static variables ``names`` (``avr-nm``;
    link-time-optimisation suffixes such as ``.lto_priv.3`` are ignored)."""
    res = subprocess.run(["avr-nm", str(elf)], capture_output=True, text=True, check=True)
    found: dict[str, int] = {}
    for line in res.stdout.splitlines():
        parts = line.split()
        if len(parts) == 3 and parts[1] in "bBdD":
            base = parts[2].split(".")[0]
            if base in names:
                found[base] = int(parts[0], 16) - 0x800000
    return found


def read_ihex(path: Path) -> tuple[int, bytes]:
    """An Intel HEX image as (byte address of its first byte, contiguous bytes; gaps 0xFF).

    Data (00), end (01), extended segment (02) and linear (04) address records; start
    addresses (03, 05) are ignored. FirmwareBuildError naming the file and line when a
    record is malformed or its checksum is wrong."""
    chunks: dict[int, int] = {}
    upper = 0
    for n, line in enumerate(Path(path).read_text().splitlines(), 1):
        line = line.strip()
        if not line:
            continue
        try:
            raw = bytes.fromhex(line[1:]) if line[0] == ":" else b""
        except ValueError:
            raw = b""
        if len(raw) < 5 or len(raw) != raw[0] + 5 or sum(raw) & 0xFF:
            raise FirmwareBuildError(f"{path}: line {n}: not an Intel HEX record")
        kind, addr, data = raw[3], int.from_bytes(raw[1:3], "big"), raw[4:-1]
        if kind == 0:
            for i, b in enumerate(data):
                chunks[upper + addr + i] = b
        elif kind == 1:
            break
        elif kind == 2:
            upper = int.from_bytes(data, "big") << 4
        elif kind == 4:
            upper = int.from_bytes(data, "big") << 16
    if not chunks:
        raise FirmwareBuildError(f"{path}: no data records")
    lo, hi = min(chunks), max(chunks)
    image = bytearray(b"\xff" * (hi - lo + 1))
    for a, b in chunks.items():
        image[a - lo] = b
    return lo, bytes(image)
