"""Serve a device on a pseudo-terminal, for hosts that open a real port path.

Lock-step over the pty (the rule that makes a host that answers every burst of
telemetry see the same device tick sequence as through ``sim://`` in lock-step):

* the clock stands still until the host has written its first byte (pyserial flushes
  the input when it opens the pty, so the device must not emit before);
* the server makes a STEP -- runs events until bytes reach the host, exactly what a
  lock-step ``sim://`` read() short of data does -- only when all of these hold:
  the device wants time (:func:`~guardid.fakeport.device.wants_time`); everything sent
  has been written to the pty and consumed by the host (FIONREAD on the slave is 0,
  checked twice 1 ms apart); the host has written at least one byte since the previous
  step (its answer) and then stayed silent for ``settle_s``;
* fallback for hosts that never answer: after ``idle_s`` of host silence with all
  output consumed the server steps anyway (then the tick sequence depends on timing;
  ``idle_s = 0`` disables the fallback).

A device with a ``reset()`` (``firmware=avr`` with a boot loader) is reset whenever a
program opens the pty, as a board's USB port resets its MCU through DTR (avrdude's DTR
ioctl fails on a pty). Each open is a fresh bench session: the robot is back at its start
(power cycle; the MCU's flash keeps what was written), so a capture after flashing meets
the robot a ``sim://`` capture meets. Output not read by the previous program is dropped.
While the MCU boots (boot loader) its clock follows the wall clock, whatever the pacing:
a boot loader's wait for a programmer is real time on a board, and a host's silence after
its open (avrdude's DTR handling, guardid's wait for INFO) must not outlast it in
simulated time; from the firmware's first tick on the pacing rules above hold, the
fallback's ``idle_s`` counted from that tick (a host that wrote during the boot, or not at
all, gets its ``idle_s`` to answer the firmware's first bytes).

Host bytes reach the device as soon as they arrive. Real-time pacing: events run on
the wall clock (times the factor) from the host's first byte on. A simulated disconnect
closes the master side, which the host sees as a SerialException on read.

A disconnect with a reconnect (``reconnect_s``) is an unplugged cable: the pty goes away
(and ``link``, a stable symlink to it such as /dev/serial/by-id/... gives, with it), the
device runs on in real time (times the pacing factor) for the outage, then a new pty
comes up, ``link`` points to it and the server serves it as a new host's.
"""

from __future__ import annotations

import errno
import fcntl
import os
import select
import struct
import termios
import time
import tty
from collections.abc import Callable

from guardid.fakeport.device import wants_time
from guardid.fakeport.engine import LinkEngine
from guardid.fakeport.pty_opens import OpenWatch

MAX_OUTBUF = 1 << 20  # [bytes] unread output kept for a host that does not read
STEP_LIMIT_S = 1.0  # [s simulated] a lock-step step gives up after this long


class PtyServer:
    """A pseudo-terminal whose far end is ``engine``'s device."""

    def __init__(
        self,
        engine: LinkEngine,
        pacing: float | None = None,
        idle_s: float = 0.1,
        settle_s: float = 0.002,
        link: str | None = None,
    ) -> None:
        self.engine = engine
        self.pacing = pacing
        self.idle_s = idle_s
        self.settle_s = settle_s
        self.link = link
        self.overflow = 0  # [bytes] discarded because the host did not read
        self.resets = 0  #: device resets on a program's open
        self._open_pty()

    def _open_pty(self) -> None:
        self.master, self.slave = os.openpty()
        tty.setraw(self.slave)
        os.set_blocking(self.master, False)
        self.path = os.ttyname(self.slave)
        self._out = bytearray()
        resets = callable(getattr(self.engine.device, "reset", None))
        self._opens = OpenWatch(self.path) if resets else None
        if self.link is not None:
            tmp = f"{self.link}.{os.getpid()}.tmp"
            os.symlink(self.path, tmp)
            os.replace(tmp, self.link)  # the link never missing while it moves

    def close(self) -> None:
        """Close both ends and remove ``link`` (idempotent)."""
        if self._opens is not None:
            self._opens.close()
        for fd in (self.master, self.slave):
            if fd >= 0:
                try:
                    os.close(fd)
                except OSError:
                    pass
        self.master = self.slave = -1
        if self.link is not None and os.path.islink(self.link):
            os.unlink(self.link)

    def unread(self) -> int:
        """Bytes the host has not consumed yet (ours plus the slave's input queue)."""
        buf = fcntl.ioctl(self.slave, termios.FIONREAD, b"\0\0\0\0")
        return len(self._out) + struct.unpack("i", buf)[0]

    def serve(self, should_stop: Callable[[], bool]) -> str:
        """Serve until ``should_stop()`` or a simulated disconnect not followed by a
        reconnect; return the reason."""
        while True:
            reason = self._serve_host(should_stop)
            if reason != "disconnected" or not self.engine.reconnect_pending:
                return reason
            if not self._outage(should_stop):
                return "stopped"
            self._open_pty()

    def _outage(self, should_stop: Callable[[], bool]) -> bool:
        """The cable is out: run the device in real time (times the pacing factor) until
        the link is back (True) or ``should_stop()`` (False)."""
        rate = self.pacing or 1.0
        t0, sim0 = time.monotonic(), self.engine.now_ns
        while self.engine.disconnected:
            if should_stop():
                return False
            self.engine.advance_to(sim0 + round((time.monotonic() - t0) * rate * 1e9))
            time.sleep(0.005)
        self.engine.take()
        return True

    def _serve_host(self, should_stop: Callable[[], bool]) -> str:
        talked = answered = False
        last_host = last_step = time.monotonic()
        t0 = 0.0
        boot_origin = (0, last_host)  # (engine ns, wall s) of the last reset
        while not should_stop():
            now = time.monotonic()
            if self._opens is not None and self._opens.opened():
                self._reset_device()
                talked, answered, last_host = True, False, now
                t0 = now - (0.0 if self.pacing is None else self.engine.now_s / self.pacing)
                boot_origin = (self.engine.now_ns, now)
            if self._booting():
                self._boot_to(boot_origin[0] + round((now - boot_origin[1]) * 1e9))
                if not self._booting():  # the firmware's first tick: its INFO is out, and
                    last_step = now  # the host's silence counts from here, not its open
            elif self.pacing is not None and talked:
                self.engine.advance_to(self._sim_ns(t0, now))
                self._collect()
            if self.engine.disconnected:
                return self._disconnect()
            data = self._pump(self._poll_timeout(talked, t0, now))
            if data:
                now = time.monotonic()
                if not talked:
                    talked, t0 = True, now
                answered, last_host = True, now
                if self.pacing is not None:
                    self.engine.advance_to(self._sim_ns(t0, now))
                self.engine.host_write(data)
                self._collect()
                continue
            if self.pacing is not None or not talked or self._out:
                continue
            quiet = now - last_host
            waited = now - max(last_host, last_step)
            due = (answered and quiet >= self.settle_s) or (0 < self.idle_s <= waited)
            if due and wants_time(self.engine.device) and not self._booting() and self._drained():
                self.engine.advance_until_output(round(STEP_LIMIT_S * 1e9))
                self._collect()
                answered, last_step = False, time.monotonic()
        return "stopped"

    def _booting(self) -> bool:
        return self._opens is not None and getattr(self.engine.device, "booting", False)

    def _boot_to(self, t_ns: int) -> None:
        """Run the booting MCU's ticks due by ``t_ns``; stop at the firmware's first."""
        engine = self.engine
        while self._booting() and (e := engine.next_event_ns()) is not None and e <= t_ns:
            engine.step()
        self._collect()

    def _reset_device(self) -> None:
        """A program opened the pty: reset the MCU (DTR), drop the old session's output."""
        self.engine.device.reset(power_cycle=True)
        self.engine.take()
        self._out.clear()
        termios.tcflush(self.slave, termios.TCIFLUSH)
        self.resets += 1

    def _drained(self) -> bool:
        if self.unread():
            return False
        time.sleep(0.001)
        return self.unread() == 0

    def _sim_ns(self, t0: float, now: float) -> int:
        return round((now - t0) * self.pacing * 1e9)

    def _poll_timeout(self, talked: bool, t0: float, now: float) -> float:
        """[s] how long poll() may block."""
        if not talked:
            return 0.02
        if self.pacing is None:
            return 0.001
        e = self.engine.next_event_ns()
        if e is None:
            return 0.02
        return min(max(t0 + e * 1e-9 / self.pacing - now, 0.0), 0.02)

    def _collect(self) -> None:
        self._out += self.engine.take()
        if len(self._out) > MAX_OUTBUF:
            extra = len(self._out) - MAX_OUTBUF
            del self._out[:extra]
            self.overflow += extra

    def _pump(self, timeout_s: float) -> bytes:
        """Write pending output, wait up to ``timeout_s`` for host bytes, return them."""
        poller = select.poll()
        poller.register(self.master, select.POLLIN | (select.POLLOUT if self._out else 0))
        got = bytearray()
        for _fd, mask in poller.poll(timeout_s * 1000.0):
            if mask & select.POLLOUT and self._out:
                try:
                    del self._out[: os.write(self.master, self._out)]
                except BlockingIOError:
                    pass
            if mask & select.POLLIN:
                try:
                    got += os.read(self.master, 4096)
                except BlockingIOError:
                    pass
                except OSError as exc:  # EIO: nobody has the slave open (we do)
                    if exc.errno != errno.EIO:
                        raise
        return bytes(got)

    def _disconnect(self) -> str:
        deadline = time.monotonic() + 0.5
        while self._out and time.monotonic() < deadline:
            self._pump(0.01)
        self.close()
        return "disconnected"
