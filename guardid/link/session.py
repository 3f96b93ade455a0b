"""A protocol session with the microcontroller: handshake, commands, setpoint streaming.

Every command that the firmware acknowledges is sent with :meth:`Session.request`, which
waits for the ACK/NAK carrying its sequence number (or the answer message) and keeps any
telemetry that arrives meanwhile. Times on the robot come from its tick counter, never
from host arrival times (USB adapters deliver frames bunched).
"""

from __future__ import annotations

import time
from collections import deque
from collections.abc import Callable, Iterator
from dataclasses import dataclass

import numpy as np
import serial

from guardid.errors import LinkError
from guardid.protocol import ENUMS, MESSAGES, PROTOCOL_VERSION, Encoder, FrameParser, to_si

M = MESSAGES
_ERROR_NAMES = {v: k for k, v in ENUMS["error"].items()}


@dataclass(frozen=True)
class Telemetry:
    """One TELEMETRY frame in raw units: counts, mV, mA (see ``guardid.protocol``)."""

    tick: int
    status: int
    mode: int
    counts: tuple[int, ...]
    voltage_mv: tuple[int, ...]
    current_ma: tuple[int, ...]
    setpoint_counts: tuple[int, ...]


class Session:
    """The host end of the protocol over an open pyserial port.

    ``timeout_s`` bounds each wait for an answer (simulated time on a lock-step ``sim://``
    port). ``stats`` is the parser's error counters; ``telemetry`` queues frames received
    while waiting for answers; ``faults`` collects FAULT messages.
    """

    def __init__(self, port, timeout_s: float = 1.0) -> None:
        self.port = port
        self.name = getattr(port, "portstr", None) or getattr(port, "name", "port")
        self.timeout_s = timeout_s
        self.parser = FrameParser()
        self.encoder = Encoder()
        self.telemetry: deque[Telemetry] = deque()
        self.faults: list = []
        self.info = None

    @property
    def stats(self):
        """Parser counters (CRC errors, framing errors, sequence gaps)."""
        return self.parser.stats

    # ------------------------------------------------------------------ bytes
    def send(self, msg) -> int:
        """Send ``msg``; return its sequence number."""
        seq = self.encoder.seq
        try:
            self.port.write(self.encoder.encode(msg))
        except (serial.SerialException, OSError) as exc:
            raise LinkError(f"port {self.name}: write failed: {exc}") from None
        return seq

    def poll(self) -> list:
        """Read what is available (waiting up to the port's timeout); return the frames."""
        try:
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
        frames = self.parser.feed(data)
        others = []
        for f in frames:
            msg = f.msg
            if type(msg) is M["TELEMETRY"]:
                self.telemetry.append(Telemetry(*msg))
            elif type(msg) is M["FAULT"]:
                self.faults.append(msg)
            else:
                others.append(f)
        return others

    def _wait(self, match: Callable, what: str):
        deadline = self._clock() + self.timeout_s
        while True:
            for frame in self.poll():
                if match(frame):
                    return frame
            if self._clock() >= deadline:
                raise LinkError(
                    f"port {self.name}: no answer to {what} within {self.timeout_s:g} s"
                )

    def _clock(self) -> float:
        """Seconds: simulated time on a lock-step sim:// port, else the wall clock."""
        if getattr(getattr(self.port, "options", None), "lockstep", False):
            return self.port.sim_time_s
        return time.monotonic()

    def request(self, msg):
        """Send a command and wait for its ACK (raise :class:`LinkError` on NAK/timeout)."""
        seq = self.send(msg)
        name = msg.SPEC.name
        frame = self._wait(
            lambda f: type(f.msg) in (M["ACK"], M["NAK"]) and f.msg.ack_seq == seq, name
        )
        if type(frame.msg) is M["NAK"]:
            err = _ERROR_NAMES.get(frame.msg.error, str(frame.msg.error))
            raise LinkError(f"port {self.name}: {name} refused by the robot: {err}")
        return frame.msg

    # ------------------------------------------------------------------ commands
    def handshake(self):
        """HELLO -> INFO; check the protocol version. Returns INFO in SI (dict)."""
        self.send(M["HELLO"]())
        frame = self._wait(lambda f: type(f.msg) is M["INFO"], "HELLO")
        info = frame.msg
        if info.protocol_version != PROTOCOL_VERSION:
            raise LinkError(
                f"port {self.name}: robot speaks protocol version {info.protocol_version}, "
                f"guardid speaks {PROTOCOL_VERSION}: update the firmware or guardid"
            )
        self.info = to_si(info)
        return self.info

    def ping(self, nonce: int = 0x1234) -> int:
        """PING -> PONG; return the robot's current tick."""
        self.send(M["PING"](nonce))
        frame = self._wait(lambda f: type(f.msg) is M["PONG"] and f.msg.nonce == nonce, "PING")
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

    def send_setpoint(self, tick: int, counts) -> None:
        """Queue joint setpoints [counts] for ``tick`` (not acknowledged)."""
        self.send(M["SETPOINT"](tick & 0xFFFFFFFF, 0, tuple(int(c) for c in counts)))

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

    def track(self, setpoints_counts: np.ndarray, depth: int = 8, lead_ticks: int = 3) -> Iterator:
        """Run a closed-loop trajectory: one row of joint setpoints [counts] per tick.

        Switches to position mode, streams setpoints ahead of their tick (at most
        ``depth`` buffered), starts telemetry, and yields ``(index, Telemetry)`` for every
        frame received, ``index`` being the trajectory row of the frame's tick (negative
        before the trajectory starts). Ends after the last row's tick; the caller puts the
        robot idle (see :meth:`finish`). ``lead_ticks``: the first row's tick after the
        PING's. START_STREAM goes right behind the first row's setpoint, ahead of the other
        ``depth - 1`` (~160 bytes, 14 ms at 115200 baud): behind them it reached the AVR
        binary in the loop (firmware=avr) after the first row's tick, which then had no
        telemetry.
        """
        rows = np.asarray(setpoints_counts, dtype=np.int64)
        self.telemetry.clear()
        self.set_mode("position")
        first = self.ping() + lead_ticks
        last = first + len(rows) - 1
        sent = first
        self.send_setpoint(sent, rows[0])
        self.start_stream()
        while sent < min(first + depth - 1, last):
            sent += 1
            self.send_setpoint(sent, rows[sent - first])
        while True:
            t = self.next_telemetry()
            while sent < min(t.tick + depth, last):
                sent += 1
                self.send_setpoint(sent, rows[sent - first])
            yield t.tick - first, t
            if t.tick >= last:
                return

    def finish(self) -> None:
        """Best effort: stop streaming and put the robot idle (used on every exit path)."""
        for command in (lambda: self.set_mode("idle"), self.stop_stream):
            try:
                command()
            except LinkError:
                pass
