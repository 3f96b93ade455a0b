"""Connecting to an Arduino-class board: the reset on open and the handshake after it.

Opening the USB serial port of an Uno, Nano or Mega resets its microcontroller (the
adapter's DTR line drives RESET through a capacitor); the boot loader then listens for a
programmer (optiboot about 1.4 s with its LED flashes, the Mega's stk500v2 about 0.9 s)
before the firmware starts and sends INFO. Bytes sent meanwhile go to the boot loader
(optiboot takes a stray byte for a bad command; stk500v2 for the start of a message), so
after a reset the host:

1. pulses DTR (released for :data:`DTR_PULSE_S`, asserted again), a reset also when the
   line was already asserted (an adapter opened before with HUPCL off);
2. waits silently up to ``boot_wait_s`` for the firmware's first byte (it sends INFO
   after reset; the byte is kept for the parser);
3. then sends HELLO until INFO comes (the one sent at reset counts), with
   :data:`BOOT_RETRY` (longer waits than a running link's, for a boot loader that took
   the first HELLO for itself). A ``sim://`` session without a boot loader goes the same
   way from its first tick, so both see the same bytes.

Device paths (``/dev/ttyACM0``, a fake-port pty) and ``sim://...&bootloader=...`` reset
this way unless ``reset=False`` (``--no-reset``: the port opened with DTR and RTS released,
HELLO at once: a board whose auto-reset is cut, or a firmware that must keep running).
Other URLs (``sim://`` without a boot loader, ``socket://``) handshake at once as before.
"""

from __future__ import annotations

import time

import serial

from guardid.errors import LinkError
from guardid.link.session import RetryPolicy, Session

DTR_PULSE_S = 0.1  #: [s] DTR released this long: RESET's capacitor discharges
BOOT_WAIT_S = 3.0  #: [s] longest silent wait for the firmware's INFO after a reset
#: HELLO's resends after a reset: 0.25, 0.5, 1, 1, 1, 1 s (4.75 s in all).
BOOT_RETRY = RetryPolicy(attempts=6, first_wait_s=0.25, backoff=2.0, max_wait_s=1.0)


def resets_on_open(url: str) -> bool:
    """True when opening ``url`` resets the board: a device path, or a simulated board
    with a boot loader (``sim://...&bootloader=...``)."""
    if "://" not in url:
        return True
    if url.startswith("sim://"):
        from guardid.fakeport.options import parse_sim_url

        return parse_sim_url(url).bootloader is not None
    return False


def pulse_dtr(port, wall_clock: bool = True) -> bool:
    """Release DTR, wait :data:`DTR_PULSE_S` (``wall_clock``; a lock-step ``sim://`` port
    needs no wait), assert it again: the board resets. False when the port has no modem
    lines (a pseudo-terminal: its server resets the simulated board on open instead)."""
    try:
        port.dtr = False
        if wall_clock:
            time.sleep(DTR_PULSE_S)
        port.dtr = True
    except (OSError, serial.SerialException):
        return False
    return True


def wait_for_first_byte(session: Session, wait_s: float, lockstep: bool = False) -> bool:
    """Wait up to ``wait_s`` [s] (simulated on a lock-step port) for the robot's first
    byte, sending nothing; the byte goes to the session's parser. True when it came."""
    port = session.port
    clock = (lambda: port.sim_time_s) if lockstep else time.monotonic
    deadline = clock() + wait_s
    while clock() < deadline:
        try:
            data = port.read(1)
        except (OSError, serial.SerialException) as exc:
            raise LinkError(f"port {session.name}: read failed (disconnected?): {exc}") from None
        if data:
            session.parser.feed(data)  # one byte: never a whole frame
            return True
    return False


def connect(session: Session, url: str, reset: bool = True,
            boot_wait_s: float = BOOT_WAIT_S) -> dict:  # fmt: skip
    """The robot's INFO (SI dict, see :meth:`Session.handshake`) on a freshly opened port,
    after the reset on open where ``url`` has one and ``reset`` (module docstring)."""
    if not (reset and resets_on_open(url)):
        return session.handshake()
    lockstep = bool(getattr(getattr(session.port, "options", None), "lockstep", False))
    pulse_dtr(session.port, wall_clock=not lockstep)
    wait_for_first_byte(session, boot_wait_s, lockstep)
    retry, session.retry = session.retry, BOOT_RETRY
    try:
        return session.handshake()
    finally:
        session.retry = retry
