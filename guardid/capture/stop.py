"""Ctrl-C (SIGINT), SIGTERM and SIGHUP (a closed terminal, a dropped ssh session) during a
capture: a flag, checked at safe points.

Python's default SIGINT handler raises KeyboardInterrupt at whatever bytecode the main
thread is running. In a capture that may be inside ``with lock:`` of a real-time
``sim://`` port (right after the lock was taken, leaking it, so that closing the port
waits forever for its clock thread), or half-way through a simulated tick. So while a
capture runs, these signals only set :class:`StopRequest`; the capture raises
:class:`CaptureStopped` at points where stopping is safe: at every tick of the capture
loop, before every write to the port and before every read of it that would wait
(:class:`StopAwarePort`); such reads return within the port's read timeout (0.1 s) even
when the robot is silent.
"""

from __future__ import annotations

import signal
import threading
from collections.abc import Iterator
from contextlib import contextmanager

STOP_SIGNALS = (signal.SIGINT, signal.SIGTERM, signal.SIGHUP)


class CaptureStopped(BaseException):  # noqa: N818  (a request, like KeyboardInterrupt)
    """Raised at a safe point once a stop was requested; ``signum`` says by which signal.

    A BaseException, like KeyboardInterrupt, so that no ``except Exception`` on the way
    (retry loops, libraries) can swallow it."""

    def __init__(self, signum: int) -> None:
        super().__init__(signal.Signals(signum).name)
        self.signum = signum


class StopRequest:
    """Set by the signal handlers (:meth:`installed`) or :meth:`request`; polled."""

    def __init__(self) -> None:
        self.signum: int | None = None
        self.armed = True  # False while the robot is being put idle: reads must go on

    def __bool__(self) -> bool:
        return self.signum is not None

    @property
    def exit_code(self) -> int:
        """Shell convention 128 + signal number (130 SIGINT, 143 SIGTERM, 129 SIGHUP)."""
        return 128 + (self.signum or 0)

    @property
    def name(self) -> str:
        """SIGINT, SIGTERM, SIGHUP, or '' when no stop was requested."""
        return signal.Signals(self.signum).name if self.signum else ""

    def request(self, signum: int = signal.SIGINT, _frame=None) -> None:
        """Ask the capture to stop (the signal handler; safe at any bytecode)."""
        if self.signum is None:
            self.signum = signum

    def check(self) -> None:
        """Raise :class:`CaptureStopped` if a stop was requested and checks are armed."""
        if self.signum is not None and self.armed:
            raise CaptureStopped(self.signum)

    def disarm(self) -> None:
        """Stop raising (the capture is winding down: idle command, footer)."""
        self.armed = False

    @contextmanager
    def installed(self) -> Iterator[StopRequest]:
        """Route SIGINT, SIGTERM and SIGHUP to :meth:`request` inside the block (main thread
        only; elsewhere signals cannot be handled and the block runs unchanged). A SIGHUP
        left ignored (``nohup``) stays ignored."""
        if threading.current_thread() is not threading.main_thread():
            yield self
            return
        old = {
            s: signal.signal(s, self.request)
            for s in STOP_SIGNALS
            if not (s == signal.SIGHUP and signal.getsignal(s) is signal.SIG_IGN)
        }
        try:
            yield self
        finally:
            for s, handler in old.items():
                signal.signal(s, handler)


class StopAwarePort:
    """A pyserial port that checks a :class:`StopRequest` before every write and before
    every read that would wait.

    Every other attribute is the wrapped port's. A read checks only when no byte is
    waiting: bytes already received are always handed over (a reader may take a frame in
    two reads, and raising between them would drop the first part). No lock is held
    when :class:`CaptureStopped` is raised.
    """

    def __new__(cls, port, stop: StopRequest):
        if cls is StopAwarePort and hasattr(type(port), "read_some"):
            cls = _StopAwareSomeReader  # keep the port's one-call read for Session.poll
        return super().__new__(cls)

    def __init__(self, port, stop: StopRequest) -> None:
        self._port = port
        self._stop = stop

    def read(self, size: int = 1) -> bytes:
        if self._stop and self._stop.armed and not self._port.in_waiting:
            self._stop.check()
        return self._port.read(size)

    def write(self, data) -> int:
        self._stop.check()  # nothing more goes to the robot once a stop is requested
        return self._port.write(data)

    def __getattr__(self, name: str):
        return getattr(self._port, name)


class _StopAwareSomeReader(StopAwarePort):
    """:class:`StopAwarePort` over a port with ``read_some`` (``sim://``): the same check
    before a read that would wait."""

    reads_ahead = True  #: passed on to the port when it reads ahead (else plain reads)

    def read_some(self, ahead_ticks: int = 0) -> bytes:
        if self._stop and self._stop.armed and not self._port.in_waiting:
            self._stop.check()
        if ahead_ticks and getattr(type(self._port), "reads_ahead", False):
            return self._port.read_some(ahead_ticks)
        return self._port.read_some()
