"""Open a serial port by device path or URL (``sim://`` for the built-in simulated robot)."""

from __future__ import annotations

import errno
import os
from pathlib import Path

import serial

from guardid.errors import ConfigError, GuardidError, LinkError

DEFAULT_PORT = "sim://guard"
_IN_USE = (errno.EAGAIN, errno.EWOULDBLOCK, errno.EBUSY)


def open_port(url: str = DEFAULT_PORT, baud: int = 115200, timeout_s: float = 0.1,
              reset: bool = True):  # fmt: skip
    """Open ``url`` (a device such as ``/dev/ttyUSB0`` or a pyserial URL) with 8N1 framing.

    ``reset=False`` opens a device with DTR and RTS released, so that an Arduino-class
    board is not reset by pyserial (the kernel may still pulse DTR on open unless the port's
    HUPCL is off: ``stty -F PORT -hupcl``); see :mod:`guardid.link.board`.

    A device path is opened exclusively (pyserial's ``exclusive=True``, an advisory lock
    that every guardid process and other pyserial programs asking for it respect); URL
    handlers (``sim://``, ``socket://``, ...) have no lock and are opened as they are.
    Raises :class:`LinkError` naming the port when it cannot be opened, saying so when
    another program holds it; :class:`ConfigError` (bad input, exit 2) for a malformed URL
    option or setting (``sim://guard?seed=abc``).
    """
    if url.startswith("sim://"):
        import guardid.fakeport  # noqa: F401  (registers the sim:// handler)
    extra = {} if "://" in url else {"exclusive": True}
    try:
        if reset or "://" in url:
            return serial.serial_for_url(
                url, baudrate=baud, timeout=timeout_s, write_timeout=2.0, **extra
            )
        port = serial.serial_for_url(url, baudrate=baud, timeout=timeout_s, write_timeout=2.0,
                                     do_not_open=True, **extra)  # fmt: skip
        port.dtr = port.rts = False
        port.open()
        return port
    except ValueError as exc:  # a bad URL option or setting: the user's input, not the link
        reason = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
        raise ConfigError(f"port {url}: {reason}") from None
    except (serial.SerialException, OSError) as exc:
        if _in_use(exc):
            raise LinkError(
                f"port {url}: already in use ({_holders(url) or 'by another program'}); "
                "close the other program and retry"
            ) from None
        reason = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
        if getattr(exc, "exit_code", None) == GuardidError.exit_code:  # a bad sim:// option
            raise GuardidError(f"port {url}: {reason}") from None
        raise LinkError(f"port {url}: cannot open: {reason}") from None


def _in_use(exc: Exception) -> bool:
    """True when ``exc`` says the port is locked or busy."""
    return getattr(exc, "errno", None) in _IN_USE or "exclusively lock" in str(exc)


def _holders(path: str, locks: Path = Path("/proc/locks")) -> str:
    """``locked by pid 123 name`` for the processes holding an flock on ``path``, as far
    as ``/proc/locks`` shows them (Linux), else an empty string."""
    try:
        st = os.stat(path)
        lines = locks.read_text().splitlines()
    except OSError:
        return ""
    key = f"{os.major(st.st_dev):02x}:{os.minor(st.st_dev):02x}:{st.st_ino}"
    found = []
    for line in lines:
        fields = line.split()
        if "FLOCK" in fields and key in fields:
            pid = fields[fields.index(key) - 1]
            try:
                name = (Path("/proc") / pid / "comm").read_text().strip()
            except OSError:
                name = "?"
            found.append(f"pid {pid} {name}")
    return f"locked by {', '.join(found)}" if found else ""
