"""The host side's checks: the USB adapter's latency timer (Linux sysfs)."""

from __future__ import annotations

import os
from pathlib import Path

from guardid.doctor.checks import OK, UNKNOWN, WARN, Check
from guardid.link.ports import MAX_LATENCY_MS, SYSFS_USB_SERIAL, latency_timer_ms


def latency_check(port: str, sysfs: Path = SYSFS_USB_SERIAL) -> Check:
    """The latency timer of ``port``'s USB-serial adapter (FTDI and alike; symlinks such
    as /dev/serial/by-id/... followed): ok at most 2 ms, warn above; a CDC-ACM board
    (the Uno's and Mega's own USB chip) has none; 'unknown' for a URL or a pty."""
    name = "USB latency timer"
    if "://" in port:
        return Check(name, "", UNKNOWN, f"{port} is not a device")
    device = os.path.realpath(port)
    ms = latency_timer_ms(device, sysfs)
    if ms is None:
        if Path(device).name.startswith("ttyACM"):
            return Check(name, "", OK, "none (CDC-ACM device)")
        return Check(name, "", UNKNOWN, f"{device}: no latency_timer in {sysfs}")
    measured = f"{ms} ms"
    if ms <= MAX_LATENCY_MS:
        return Check(name, "", OK, measured)
    path = sysfs / Path(device).name / "latency_timer"
    return Check(
        name, "", WARN, measured + f" (> {MAX_LATENCY_MS} ms: telemetry arrives in bursts)",
        f"echo 1 | sudo tee {path} (or a udev rule setting ATTR{{latency_timer}}=\"1\")",
    )  # fmt: skip
