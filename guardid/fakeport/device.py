"""The device side of the fake port: what a firmware emulator implements.

Time inside a device is counted in ticks of :attr:`Device.tick_period_s` seconds; the
transport (lock-step or real-time) decides when a tick happens.
"""

from __future__ import annotations

import struct
from typing import Protocol, runtime_checkable


@runtime_checkable
class Device(Protocol):
    """An emulated microcontroller behind the fake serial port.

    The transport calls :meth:`receive` with bytes from the host (after host->device
    faults), :meth:`advance` once per tick, and :meth:`take_output` after each of
    those to collect what the device emitted (before device->host faults).
    """

    tick_period_s: float  # [s] simulated time per advance(), e.g. 0.015
    # optional ``runs_ahead = True``: host frames are handled between ticks, by their
    # order alone (not by the tick they come at, but for the watchdog and late setpoints,
    # which the host guards): a lock-step read may run the device several ticks ahead
    # (``read_some(ahead_ticks)``); a device timing its UART by clock cycles must not;
    # optional ``advance_ticks(count) -> int``: up to count ticks as count advance() calls
    # in one call, returning how many ran (LinkEngine.run_ticks goes on tick by tick)

    def receive(self, data: bytes) -> None:
        """Accept bytes from the host; responses may be queued for take_output()."""

    def advance(self) -> None:
        """Advance simulated time by one tick; output (telemetry) may be queued."""

    def take_output(self) -> bytes:
        """Return and forget the bytes emitted since the previous call."""

    def wants_time(self) -> bool:
        """Hint: True when advancing time may produce output (e.g. streaming)."""

    def close(self) -> None:
        """Release resources; no further calls follow."""


def wants_time(device: Device) -> bool:
    """Call the optional :meth:`Device.wants_time` hint; True when not implemented."""
    hint = getattr(device, "wants_time", None)
    return True if hint is None else bool(hint())


class EchoDevice:
    """A deterministic test device, independent of the real protocol.

    It echoes every host byte at once. After it has seen ``b"START"`` in the host
    stream it emits one :data:`FRAME_LEN`-byte counter frame per tick until it sees
    ``b"STOP"``. Frame: ``0xA5``, tick (uint32 LE), sequence (uint16 LE), checksum
    (sum of the previous 7 bytes mod 256).
    """

    FRAME_LEN = 8
    _HEAD = struct.Struct("<BIH")

    def __init__(self, tick_period_s: float = 0.015) -> None:
        self.tick_period_s = tick_period_s
        self.tick = 0
        self.seq = 0
        self.streaming = False
        self.closed = False
        self._out = bytearray()
        self._tail = b""  # last host bytes, to find commands split across writes

    @classmethod
    def frame(cls, tick: int, seq: int) -> bytes:
        """The frame emitted at device tick ``tick`` with sequence number ``seq``."""
        head = cls._HEAD.pack(0xA5, tick & 0xFFFFFFFF, seq & 0xFFFF)
        return head + bytes([sum(head) & 0xFF])

    def receive(self, data: bytes) -> None:
        """Echo ``data`` and watch for START/STOP."""
        self._out += data
        window = self._tail + data
        start, stop = window.rfind(b"START"), window.rfind(b"STOP")
        if start > stop:
            self.streaming = True
        elif stop > start:
            self.streaming = False
        self._tail = window[-4:]

    def advance(self) -> None:
        """One tick; emit a frame while streaming."""
        self.tick += 1
        if self.streaming:
            self._out += self.frame(self.tick, self.seq)
            self.seq += 1

    def take_output(self) -> bytes:
        """Bytes emitted since the previous call."""
        out = bytes(self._out)
        self._out.clear()
        return out

    def wants_time(self) -> bool:
        """True while streaming."""
        return self.streaming

    def close(self) -> None:
        """Mark closed."""
        self.closed = True
