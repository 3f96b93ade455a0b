"""Open a serial port by device path or URL (``sim://`` for the built-in simulated robot)."""

from __future__ import annotations

import serial

from guardid.errors import LinkError

DEFAULT_PORT = "sim://guard"


def open_port(url: str = DEFAULT_PORT, baud: int = 115200, timeout_s: float = 0.1):
    """Open ``url`` (a device such as ``/dev/ttyUSB0`` or a pyserial URL) with 8N1 framing.

    Raises :class:`LinkError` naming the port when it cannot be opened.
    """
    if url.startswith("sim://"):
        import guardid.fakeport  # noqa: F401  (registers the sim:// handler)
    try:
        return serial.serial_for_url(url, baudrate=baud, timeout=timeout_s, write_timeout=2.0)
    except (serial.SerialException, ValueError, OSError) as exc:
        reason = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
        raise LinkError(f"port {url}: cannot open: {reason}") from None
