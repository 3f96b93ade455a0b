"""Notice when a program opens a pseudo-terminal's slave (Linux inotify, through libc).

A board's USB serial port resets the microcontroller when a program opens it (DTR); a
pty has no modem lines (avrdude's ``ioctl("TIOCMGET")`` fails on it), so the server that
plays the board watches the slave's device node for opens and resets the MCU itself.
"""

from __future__ import annotations

import ctypes
import os
import struct

IN_OPEN = 0x20
_EVENT = struct.Struct("iIII")  # wd, mask, cookie, name length


class OpenWatch:
    """Counts opens of ``path`` since the last :meth:`opened` call (``available`` is False
    where inotify is not: then no open is ever reported)."""

    def __init__(self, path: str) -> None:
        self.fd = -1
        try:
            libc = ctypes.CDLL(None, use_errno=True)
            fd = libc.inotify_init1(os.O_NONBLOCK | os.O_CLOEXEC)
        except (OSError, AttributeError):
            return
        if fd < 0:
            return
        if libc.inotify_add_watch(fd, os.fsencode(path), IN_OPEN) < 0:
            os.close(fd)
            return
        self.fd = fd

    @property
    def available(self) -> bool:
        """True when opens are watched."""
        return self.fd >= 0

    def opened(self) -> int:
        """How many times the path was opened since the previous call (never blocks)."""
        if self.fd < 0:
            return 0
        n = 0
        while True:
            try:
                data = os.read(self.fd, 4096)
            except BlockingIOError:
                return n
            at = 0
            while at + _EVENT.size <= len(data):
                _wd, mask, _cookie, length = _EVENT.unpack_from(data, at)
                n += bool(mask & IN_OPEN)
                at += _EVENT.size + length

    def close(self) -> None:
        """Stop watching (idempotent)."""
        if self.fd >= 0:
            os.close(self.fd)
            self.fd = -1
