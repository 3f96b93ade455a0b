"""Seeded link faults: byte drops, bit flips, FTDI-like latency bunching, counted exactly.

Faults depend only on the seed and on the byte offsets in the clean stream, not on how
the stream is chunked (each fault kind draws from its own generator, one draw per byte).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

_BIT_WEIGHTS = np.array([1, 2, 4, 8, 16, 32, 64, 128], dtype=np.uint16)


@dataclass(frozen=True)
class FaultConfig:
    """What goes wrong on the link.

    drop: probability [0..1] that a byte is lost; flip: probability [0..1] per bit;
    latency_s [s]: FTDI-like latency timer for device->host bytes (0 = off), with
    ``packet_bytes`` bytes released at once when that many accumulate;
    disconnect_s [s, simulated]: the link dies at that time (None = never);
    reconnect_s [s, simulated]: and comes back this long after (None = never; the device
    runs on meanwhile and what it sends is lost);
    upstream: also drop/flip host->device bytes.
    """

    drop: float = 0.0
    flip: float = 0.0
    latency_s: float = 0.0
    packet_bytes: int = 62
    disconnect_s: float | None = None
    reconnect_s: float | None = None
    upstream: bool = False


@dataclass
class DirectionStats:
    """Injected damage in one direction; offsets index the clean (sent) stream."""

    bytes_in: int = 0  # bytes offered to the link
    bytes_out: int = 0  # bytes that left the corrupter (before latency buffering)
    bytes_dropped: int = 0
    bits_flipped: int = 0
    dropped_offsets: list[int] = field(default_factory=list)
    flipped: list[tuple[int, int]] = field(default_factory=list)  # (offset, xor mask)
    bytes_lost_at_disconnect: int = 0  # still buffered (latency) when the link died

    @property
    def bytes_flipped(self) -> int:
        """Number of delivered bytes with at least one flipped bit."""
        return len(self.flipped)


@dataclass
class FaultStats:
    """Damage in both directions plus link events."""

    down: DirectionStats = field(default_factory=DirectionStats)  # device -> host
    up: DirectionStats = field(default_factory=DirectionStats)  # host -> device
    bursts: list[tuple[float, int]] = field(default_factory=list)  # (time [s], bytes)
    disconnected_at_s: float | None = None
    reconnected_at_s: float | None = None
    bytes_lost_while_disconnected: int = 0  # device -> host, sent with the link down


class Corrupter:
    """Drops and flips bytes of one direction with a seeded generator."""

    def __init__(self, drop: float, flip: float, seed, stats: DirectionStats) -> None:
        drop_seq, flip_seq = np.random.SeedSequence(seed).spawn(2)
        self.drop, self.flip = float(drop), float(flip)
        self._drop_rng = np.random.default_rng(drop_seq)
        self._flip_rng = np.random.default_rng(flip_seq)
        self.stats = stats

    @property
    def passes_all(self) -> bool:
        """True when no byte is ever dropped or flipped (apply() only counts them)."""
        return self.drop <= 0.0 and self.flip <= 0.0

    def apply(self, data: bytes) -> bytes:
        """Return ``data`` after the faults, recording them in :attr:`stats`."""
        n, base = len(data), self.stats.bytes_in
        self.stats.bytes_in += n
        if n == 0 or self.passes_all:
            self.stats.bytes_out += n
            return data if type(data) is bytes else bytes(data)
        arr = np.frombuffer(data, dtype=np.uint8).copy()
        keep = np.ones(n, dtype=bool)
        if self.drop > 0.0:
            keep = self._drop_rng.random(n) >= self.drop
        if self.flip > 0.0:
            bits = self._flip_rng.random((n, 8)) < self.flip
            masks = (bits * _BIT_WEIGHTS).sum(axis=1).astype(np.uint8)
            hit = np.nonzero((masks != 0) & keep)[0]
            arr[hit] ^= masks[hit]
            self.stats.flipped.extend((base + int(i), int(masks[i])) for i in hit)
            self.stats.bits_flipped += int(bits[hit].sum())
        lost = np.nonzero(~keep)[0]
        self.stats.dropped_offsets.extend(base + int(i) for i in lost)
        self.stats.bytes_dropped += len(lost)
        out = arr[keep].tobytes()
        self.stats.bytes_out += len(out)
        return out


class LatencyBuffer:
    """FTDI-like buffering in simulated time [ns].

    Bytes wait until ``packet_bytes`` accumulate (released at once, per full packet) or
    until the latency timer, started when a byte enters the empty buffer or restarted
    after a packet went out, expires.
    """

    def __init__(self, latency_ns: int, packet_bytes: int = 62) -> None:
        self.latency_ns = latency_ns
        self.packet_bytes = packet_bytes
        self.buffer = bytearray()
        self.deadline_ns: int | None = None

    def push(self, data: bytes, now_ns: int) -> bytes:
        """Buffer ``data`` at time ``now_ns``; return full packets released now."""
        self.buffer += data
        out = bytearray()
        while len(self.buffer) >= self.packet_bytes:
            out += self.buffer[: self.packet_bytes]
            del self.buffer[: self.packet_bytes]
        if not self.buffer:
            self.deadline_ns = None
        elif out or self.deadline_ns is None:
            self.deadline_ns = now_ns + self.latency_ns
        return bytes(out)

    def flush(self) -> bytes:
        """Release everything (the timer expired)."""
        out = bytes(self.buffer)
        self.buffer.clear()
        self.deadline_ns = None
        return out
