"""A protocol session with the microcontroller: handshake, commands, setpoint streaming.

Every command that gets an answer (HELLO -> INFO, PING -> PONG, the rest -> ACK/NAK carrying
its sequence number) is sent with :meth:`Session.command`: when no answer comes within a
wait, the SAME frame (same sequence number) is sent again, a bounded number of times with
growing waits (:class:`RetryPolicy`); the firmware answers a repeated frame again without
applying it again. Telemetry arriving meanwhile is kept. Streamed setpoints and voltages
are not answered and never resent. Times on the robot come from its tick counter, never
from host arrival times (USB adapters deliver frames bunched).
"""

from __future__ import annotations

import math
import time
from collections import deque
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np
import serial

from guardid.errors import LinkError
from guardid.protocol import (
    ENUMS,
    MESSAGES,
    MIN_PROTOCOL_VERSION,
    PROTOCOL_VERSION,
    Encoder,
    FrameParser,
    to_si,
)

M = MESSAGES
_ERROR_NAMES = {v: k for k, v in ENUMS["error"].items()}


class Telemetry(NamedTuple):
    """One TELEMETRY frame in raw units: counts, mV, mA (see ``guardid.protocol``).

    Built by the parser straight from the frame's unpacked values (fields in wire order,
    checked against the protocol below), one tuple per frame."""

    tick: int
    status: int
    mode: int
    counts: tuple[int, ...]
    voltage_mv: tuple[int, ...]
    current_ma: tuple[int, ...]
    setpoint_counts: tuple[int, ...]


_WIRE = M["TELEMETRY"].SPEC.fields
if [f.per_joint for f in _WIRE] != [False] * 3 + [True] * 4:
    raise ImportError("Telemetry no longer matches the protocol's TELEMETRY fields")


@dataclass(frozen=True)
class RetryPolicy:
    """How a command without an answer is sent again.

    At most ``attempts`` sends of the same frame; after send ``k`` (from 0) the host waits
    ``min(first_wait_s * backoff**k, max_wait_s)`` seconds [s] for the answer. The defaults
    (0.1, 0.2, 0.4, 0.8, 1.0 s with a 1 s ``max_wait_s``) ride out a lost reply within 0.1 s
    on a link whose replies take a tick (15 ms) plus a USB latency timer (16 ms).
    """

    attempts: int = 5
    first_wait_s: float = 0.1
    backoff: float = 2.0
    max_wait_s: float = 1.0

    def __post_init__(self) -> None:
        if self.attempts < 1 or self.first_wait_s <= 0 or self.backoff < 1 or self.max_wait_s <= 0:
            raise ValueError(f"invalid retry policy {self}")

    def waits_s(self) -> list[float]:
        """The wait after each send [s]."""
        return [
            min(self.first_wait_s * self.backoff**k, self.max_wait_s) for k in range(self.attempts)
        ]


class LazyRows:
    """Rows of a long trajectory made ``chunk`` at a time as a run reaches them (a capture
    of days would need gigabytes at once): ``make(start, stop)`` returns the integer rows
    [counts] of ticks ``start`` to ``stop`` - 1, as an (stop - start, n) array."""

    def __init__(self, n_rows: int, make, chunk: int = 4096) -> None:
        self.n_rows, self.make, self.chunk = n_rows, make, chunk
        self._start, self._rows = 0, []

    def __len__(self) -> int:
        return self.n_rows

    def __getitem__(self, k: int) -> list[int]:
        if not 0 <= k < self.n_rows:
            raise IndexError(k)
        if not self._start <= k < self._start + len(self._rows):
            self._start = k - k % self.chunk
            stop = min(self._start + self.chunk, self.n_rows)
            self._rows = np.asarray(self.make(self._start, stop), dtype=np.int64).tolist()
        return self._rows[k - self._start]


class Session:
    """The host end of the protocol over an open pyserial port.

    ``timeout_s`` bounds each wait for an answer or a telemetry frame (simulated time on a
    lock-step ``sim://`` port); ``retry`` says how unanswered commands are resent (default:
    :class:`RetryPolicy` with ``max_wait_s = timeout_s``). ``stats`` is the parser's error
    counters; ``resends`` counts commands sent again; ``telemetry`` queues frames received
    while waiting for answers; ``faults`` collects FAULT messages.
    """

    def __init__(self, port, timeout_s: float = 1.0, retry: RetryPolicy | None = None) -> None:
        self.port = port
        self.name = getattr(port, "portstr", None) or getattr(port, "name", "port")
        self.timeout_s = timeout_s
        self.retry = retry or RetryPolicy(first_wait_s=min(0.1, timeout_s), max_wait_s=timeout_s)
        self.parser = FrameParser()
        self.encoder = Encoder()
        self.telemetry: deque[Telemetry] = deque()
        self.parser.route(M["TELEMETRY"].MSG_ID, Telemetry, self.telemetry.append)
        # sim:// ports: one call per poll (looked up on the class, so that a proxy which
        # wraps read() only is read through read())
        self._read_some = port.read_some if hasattr(type(port), "read_some") else None
        self._reads_ahead = bool(getattr(type(port), "reads_ahead", False))
        self._watchdog_s: float | None = None  # the robot's host-silence timeout [s]
        self._setpoint_packers: dict = {}  # (values, feedforward) -> SETPOINT(_FF) packer
        self._lockstep = bool(getattr(getattr(port, "options", None), "lockstep", False))
        self.faults: list = []
        self.info = None
        self.resends = 0

    @property
    def stats(self):
        """Parser counters (CRC errors, framing errors, sequence gaps)."""
        return self.parser.stats

    # ------------------------------------------------------------------ bytes
    def send(self, msg) -> int:
        """Send ``msg`` once; return its sequence number."""
        seq = self.encoder.seq
        self._write(self.encoder.encode(msg))
        return seq

    def _write(self, frame: bytes) -> None:
        try:
            self.port.write(frame)
        except (serial.SerialException, OSError) as exc:
            raise LinkError(f"port {self.name}: write failed: {exc}") from None

    def poll(self, ahead_ticks: int = 0) -> list:
        """Read what is available (waiting up to the port's timeout); return the frames.
        ``ahead_ticks``: on a port that reads ahead (lock-step ``sim://``), let the robot
        run that many ticks more within this read (see :meth:`track`)."""
        try:
            if ahead_ticks and self._reads_ahead:
                data = self._read_some(ahead_ticks)
            elif self._read_some is not None:
                data = self._read_some()
            else:
                waiting = self.port.in_waiting
                data = self.port.read(waiting if waiting > 0 else 1)
                if data and not waiting:
                    rest = self.port.in_waiting  # the rest of what arrived with that byte
                    if rest:
                        data += self.port.read(rest)
        except (serial.SerialException, OSError) as exc:
            raise LinkError(f"port {self.name}: read failed (disconnected?): {exc}") from None
        if not data:
            return []
        frames = self.parser.feed(data)  # telemetry goes straight to self.telemetry
        if not frames:
            return frames
        others = []
        for f in frames:
            if type(f.msg) is M["FAULT"]:
                self.faults.append(f.msg)
            else:
                others.append(f)
        return others

    def _wait(self, match: Callable, wait_s: float):
        """The first frame ``match`` accepts within ``wait_s`` [s], else None."""
        deadline = self._clock() + wait_s
        while True:
            for frame in self.poll():
                if match(frame):
                    return frame
            if self._clock() >= deadline:
                return None

    def command(self, msg, match: Callable):
        """Send ``msg`` and return the first frame ``match(frame, seq)`` accepts, resending
        the same frame (same ``seq``) per :attr:`retry`; :class:`LinkError` naming the
        command and the port when no answer comes after the last attempt."""
        seq = self.encoder.seq
        frame = self.encoder.encode(msg)
        waits = self.retry.waits_s()
        for attempt, wait_s in enumerate(waits):
            if attempt:
                self.resends += 1
            self._write(frame)
            answer = self._wait(lambda f: match(f, seq), wait_s)
            if answer is not None:
                return answer
        raise LinkError(
            f"port {self.name}: no answer to {msg.SPEC.name} after {len(waits)} attempts "
            f"({sum(waits):g} s)"
        )

    def _clock(self) -> float:
        """Seconds: simulated time on a lock-step sim:// port, else the wall clock."""
        if self._lockstep:
            return self.port.sim_time_s
        return time.monotonic()

    def request(self, msg):
        """Send a command until its ACK comes (:class:`LinkError` on NAK or no answer)."""
        name = msg.SPEC.name
        frame = self.command(
            msg, lambda f, seq: type(f.msg) in (M["ACK"], M["NAK"]) and f.msg.ack_seq == seq
        )
        if type(frame.msg) is M["NAK"]:
            err = _ERROR_NAMES.get(frame.msg.error, str(frame.msg.error))
            raise LinkError(f"port {self.name}: {name} refused by the robot: {err}")
        return frame.msg

    # ------------------------------------------------------------------ commands
    def handshake(self):
        """HELLO -> INFO; check the protocol version. Returns INFO in SI (dict)."""
        frame = self.command(M["HELLO"](), lambda f, seq: type(f.msg) is M["INFO"])
        info = frame.msg
        if not MIN_PROTOCOL_VERSION <= info.protocol_version <= PROTOCOL_VERSION:
            raise LinkError(
                f"port {self.name}: robot speaks protocol version {info.protocol_version}, "
                f"guardid speaks {MIN_PROTOCOL_VERSION}..{PROTOCOL_VERSION}: update the "
                "firmware or guardid"
            )
        self.info = to_si(info)
        self._watchdog_s = self.info["watchdog_timeout"]
        return self.info

    def ping(self) -> int:
        """PING -> PONG; return the robot's current tick.

        The nonce is the frame's sequence number, so a late PONG of an earlier PING is
        never taken for this one's."""
        nonce = self.encoder.seq
        frame = self.command(
            M["PING"](nonce), lambda f, seq: type(f.msg) is M["PONG"] and f.msg.nonce == nonce
        )
        return frame.msg.tick

    def set_pid(self, joint: int, kp: float, ki: float, kd: float) -> None:
        """Set one joint's gains: kp [V/rad], ki [V/(rad s)], kd [V s/rad]."""
        self.request(M["SET_PID"](joint, *(int(round(g * 1e6)) for g in (kp, ki, kd))))

    def set_mode(self, mode: str) -> None:
        """Switch to ``idle``, ``position`` or ``voltage``."""
        self.request(M["SET_MODE"](ENUMS["mode"][mode]))

    def set_watchdog(self, timeout_s: float) -> None:
        """Host-silence timeout of the moving modes [s]."""
        self.request(M["SET_WATCHDOG"](int(round(timeout_s * 1000))))
        self._watchdog_s = round(timeout_s * 1000) * 1e-3

    def start_stream(self, decimation: int = 1) -> None:
        """Start telemetry, one frame every ``decimation`` ticks."""
        self.request(M["START_STREAM"](decimation))

    def stop_stream(self) -> None:
        """Stop telemetry."""
        self.request(M["STOP_STREAM"]())

    def estop(self) -> None:
        """Latch the emergency stop (motors 0 V at once)."""
        self.request(M["ESTOP"]())

    def clear_estop(self) -> None:
        """Clear a latched e-stop or tripped watchdog."""
        self.request(M["CLEAR_ESTOP"]())

    def send_setpoint(self, tick: int, counts, feedforward_mv=None) -> None:
        """Queue joint setpoints [counts] for ``tick`` (not acknowledged); with
        ``feedforward_mv`` (per joint [mV], firmware with the feedforward capability) as
        SETPOINT_FF."""
        values = [int(c) for c in counts]
        if feedforward_mv is not None:
            values += [int(v) for v in feedforward_mv]
        self._write(self._setpoint_packer(len(values), feedforward_mv is not None)(
            tick & 0xFFFFFFFF, 0, *values))  # fmt: skip

    def _setpoint_packer(self, n_values: int, feedforward: bool, rows: bool = False):
        """The bytes of encode(SETPOINT(tick, 0, counts)) (or SETPOINT_FF with the
        feedforward after the counts) from (tick, flags, *values), built once per kind;
        ``rows``: the :meth:`guardid.protocol.Encoder.rows_packer` of the kind instead."""
        key = (n_values, feedforward, rows)
        pack = self._setpoint_packers.get(key)
        if pack is None:
            msg, n = (M["SETPOINT_FF"], n_values // 2) if feedforward else (M["SETPOINT"], n_values)
            make = self.encoder.rows_packer if rows else self.encoder.packer
            pack = self._setpoint_packers[key] = make(msg, n)
        return pack

    def send_voltage(self, volts) -> None:
        """Open-loop motor voltages [V] (voltage mode)."""
        self.send(M["SET_VOLTAGE"](tuple(int(round(v * 1000)) for v in volts)))

    # ------------------------------------------------------------------ streaming
    def next_telemetry(self) -> Telemetry:
        """The next telemetry frame (raise :class:`LinkError` when none comes in time)."""
        deadline = self._clock() + self.timeout_s
        while not self.telemetry:
            self.poll()
            if not self.telemetry and self._clock() >= deadline:
                raise LinkError(
                    f"port {self.name}: telemetry stopped (no frame for {self.timeout_s:g} s)"
                )
        return self.telemetry.popleft()

    def track(
        self,
        setpoints_counts: np.ndarray | LazyRows,
        depth: int = 8,
        lead_ticks: int = 3,
        feedforward: bool = False,
        run_ahead: bool = False,
    ) -> Iterator:
        """Run a closed-loop trajectory: one row of joint setpoints [counts] per tick.

        Switches to position mode, streams setpoints ahead of their tick (at most
        ``depth`` buffered), starts telemetry, and yields ``(index, Telemetry)`` for every
        frame received, ``index`` being the trajectory row of the frame's tick (negative
        before the trajectory starts). Ends after the last row's tick; the caller puts the
        robot idle (see :meth:`finish`). ``lead_ticks``: the first row's tick after the
        PING's. START_STREAM goes right behind the first row's setpoint, ahead of the other
        ``depth - 1`` (~160 bytes, 14 ms at 115200 baud): behind them it reached the AVR
        binary in the loop (firmware=avr) after the first row's tick, which then had no
        telemetry. ``setpoints_counts``: an (N, n) array, or :class:`LazyRows` for a long
        run (made as the run reaches them, never all at once). ``feedforward``: each row is
        the n setpoints [counts] followed by the n feedforward voltages [mV], streamed as
        SETPOINT_FF (only to firmware whose INFO has the feedforward capability).

        ``run_ahead`` (for a caller that sends nothing in reaction to a frame before the
        run ends): on a lock-step ``sim://`` link without faults the robot runs up to
        ``depth - 1`` ticks beyond the frame just read in one read (never beyond the
        setpoints sent, never a host silence near the watchdog's timeout, one tick at a
        time over the last ``depth`` ticks), and the setpoints for all the frames read go
        in one write before they are yielded: the same bytes in both directions as one
        tick at a time, fewer calls per tick. A ``break`` or exception in the caller then
        comes up to that many ticks late for the robot (docs/lockstep_speed.md).
        """
        rows = setpoints_counts
        if not isinstance(rows, LazyRows):
            rows = np.asarray(rows, dtype=np.int64).tolist()  # Python ints per row
        self.telemetry.clear()
        self.set_mode("position")
        first = self.ping() + lead_ticks
        last = first + len(rows) - 1
        sent = first
        pack = self._setpoint_packer(len(rows[0]), feedforward)
        pack_rows = self._setpoint_packer(len(rows[0]), feedforward, rows=True)
        write, next_telemetry = self._write, self.next_telemetry
        write(pack(sent & 0xFFFFFFFF, 0, *rows[0]))
        self.start_stream()
        top = min(first + depth - 1, last)  # the rest of the first depth rows, in one write
        if sent < top:  # (so that they reach the robot within one tick over a pty too)
            write(b"".join([pack(k & 0xFFFFFFFF, 0, *rows[k - first])
                            for k in range(sent + 1, top + 1)]))  # fmt: skip
            sent = top
        # run-ahead: (ticks a read may run beyond its first frame's, host silence the
        # watchdog allows [ticks]); the host last wrote at tick wrote_at or later
        limits = self._ahead_limits(depth) if run_ahead else None
        queue, tick, wrote_at = self.telemetry, None, first - lead_ticks
        while True:
            if limits and not queue and tick is not None:
                # the read ends at tick + 1 + n at most (one frame per tick): not past the
                # setpoints sent, nor the watchdog's silence, nor the tick after which one
                # tick at a time sends nothing more (the last setpoint goes at that tick
                # as then: the robot's watchdog, should the end's silence trip it, trips
                # at the same tick)
                n = min(limits[0], last - depth - tick - 1, limits[1] - (tick + 1 - wrote_at))
                if n > 0:
                    self.poll(n)
                    if queue:  # the setpoints of every frame read, in one write
                        top = min(queue[-1].tick + depth, last)
                        if sent < top:
                            write(pack_rows(sent + 1, 0, rows, sent + 1 - first, top - sent))
                            sent, wrote_at = top, queue[-1].tick
            t = queue.popleft() if queue else next_telemetry()
            tick = t.tick
            while sent < last and sent < tick + depth:
                sent += 1
                write(pack(sent & 0xFFFFFFFF, 0, *rows[sent - first]))
                wrote_at = tick
            yield tick - first, t
            if tick >= last:
                return

    def _ahead_limits(self, depth: int) -> tuple[int, int] | None:
        """For :meth:`track`'s run-ahead: (ticks a lock-step read may run beyond its first
        frame's: the setpoints streamed ahead must cover them; ticks the host may stay
        silent: well within the robot's watchdog timeout), or None when the port cannot
        read ahead."""
        if not self._reads_ahead or self.info is None or self._watchdog_s is None:
            return None
        tick_s = self.info["tick_period"]
        if tick_s <= 0:
            return None
        watchdog_ticks = math.floor(self._watchdog_s / tick_s + 1e-9)  # trips at this silence
        return depth - 1, watchdog_ticks - 1

    def reattach(self, port) -> None:
        """Go on over ``port`` (the same robot's port opened again after an unplug): bytes
        of a frame cut by the unplug are dropped, counters and sequence numbers go on."""
        self.port = port
        self._read_some = port.read_some if hasattr(type(port), "read_some") else None
        self._reads_ahead = bool(getattr(type(port), "reads_ahead", False))
        self.parser.feed(b"\x00")  # end a frame cut by the unplug (counted as framing)
        self.telemetry.clear()

    def finish(self) -> None:
        """Best effort: stop streaming and put the robot idle (used on every exit path)."""
        for command in (lambda: self.set_mode("idle"), self.stop_stream):
            try:
                command()
            except LinkError:
                pass
