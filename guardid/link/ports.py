"""List serial ports and check USB-serial adapters' latency timers."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from serial.tools import list_ports

SYSFS_USB_SERIAL = Path("/sys/bus/usb-serial/devices")
MAX_LATENCY_MS = 2  #: above this an adapter holds frames longer than a fraction of a tick


@dataclass(frozen=True)
class PortInfo:
    """A serial port: device path, description, hardware id, latency timer [ms] if known."""

    device: str
    description: str
    hwid: str
    latency_ms: int | None

    @property
    def latency_warning(self) -> str | None:
        """A one-line warning with the fix when the latency timer is too long."""
        if self.latency_ms is None or self.latency_ms <= MAX_LATENCY_MS:
            return None
        name = Path(self.device).name
        return (
            f"{self.device}: USB latency timer {self.latency_ms} ms (> {MAX_LATENCY_MS} ms) "
            f"bunches telemetry; fix: echo 1 | sudo tee "
            f"{SYSFS_USB_SERIAL / name / 'latency_timer'}"
        )


def latency_timer_ms(device: str, sysfs: Path = SYSFS_USB_SERIAL) -> int | None:
    """The adapter's latency timer [ms] from sysfs (FTDI and similar), or None."""
    path = sysfs / Path(device).name / "latency_timer"
    try:
        return int(path.read_text().strip())
    except (OSError, ValueError):
        return None


def serial_ports(sysfs: Path = SYSFS_USB_SERIAL) -> list[PortInfo]:
    """All serial ports pyserial finds, sorted by device path."""
    ports = []
    for p in sorted(list_ports.comports(), key=lambda p: p.device):
        ports.append(PortInfo(p.device, p.description, p.hwid, latency_timer_ms(p.device, sysfs)))
    return ports
