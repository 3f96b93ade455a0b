"""The simulated-time core of the fake link, shared by ``sim://`` ports and the pty server.

Time is an integer number of nanoseconds since the link started. Events, in order at
equal times: the disconnect (or the reconnect), the latency-timer flush, the device tick
(tick k happens at k * tick period). Host writes reach the device at the current time.
With a reconnect scheduled the device runs on while the link is down (its watchdog idles
it), what it sends meanwhile is lost, and the link comes back at its time.
"""

from __future__ import annotations

import serial

from guardid.fakeport.device import Device
from guardid.fakeport.faults import Corrupter, FaultConfig, FaultStats, LatencyBuffer


class Disconnected(serial.SerialException):
    """The emulated link is gone (``... port disconnected``)."""


class LinkEngine:
    """A device plus a faulty link, advanced event by event in simulated time."""

    def __init__(self, device: Device, faults: FaultConfig, seed: int, name: str = "sim") -> None:
        self.device = device
        self.name = name
        self.tick_ns = round(float(device.tick_period_s) * 1e9)
        if self.tick_ns <= 0:
            raise ValueError(f"device tick_period_s must be > 0, got {device.tick_period_s!r}")
        self.now_ns = 0
        self.ticks = 0
        self.stats = FaultStats()
        down_seed, up_seed = (seed, 0), (seed, 1)
        self._down = Corrupter(faults.drop, faults.flip, down_seed, self.stats.down)
        up_drop, up_flip = (faults.drop, faults.flip) if faults.upstream else (0.0, 0.0)
        self._up = Corrupter(up_drop, up_flip, up_seed, self.stats.up)
        latency_ns = round(faults.latency_s * 1e9)
        self._latency = LatencyBuffer(latency_ns, faults.packet_bytes) if latency_ns > 0 else None
        self._disconnect_ns = (
            None if faults.disconnect_s is None else round(faults.disconnect_s * 1e9)
        )
        self._reconnect_ns = (
            None
            if faults.reconnect_s is None or self._disconnect_ns is None
            else self._disconnect_ns + round(faults.reconnect_s * 1e9)
        )
        self.disconnected = False
        self.rx = bytearray()  # delivered to the host, not yet read
        # no fault of any kind configured: bytes pass straight through, counted as the
        # corrupters count them (see tick_until_output, host_write, _emit)
        self.clean = (
            self._down.passes_all and self._up.passes_all and self._latency is None
            and self._disconnect_ns is None
        )  # fmt: skip

    @property
    def now_s(self) -> float:
        """Simulated time [s]."""
        return self.now_ns * 1e-9

    @property
    def pending_bytes(self) -> int:
        """Bytes held in the latency buffer (not yet visible to the host)."""
        return len(self._latency.buffer) if self._latency else 0

    @property
    def disconnect_pending(self) -> bool:
        """True when a disconnect is scheduled and has not happened yet."""
        return self._disconnect_ns is not None and not self.disconnected

    @property
    def reconnect_pending(self) -> bool:
        """True while the link is down and will come back."""
        return self.disconnected and self._reconnect_ns is not None

    def next_event_ns(self) -> int | None:
        """Time [ns] of the next event, or None when nothing will ever happen."""
        if self.disconnected:
            if self._reconnect_ns is None:
                return None
            return min((self.ticks + 1) * self.tick_ns, self._reconnect_ns)
        if self._latency is None and self._disconnect_ns is None:
            return (self.ticks + 1) * self.tick_ns  # a clean link: only device ticks
        times = [(self.ticks + 1) * self.tick_ns]
        if self._latency is not None and self._latency.deadline_ns is not None:
            times.append(self._latency.deadline_ns)
        if self._disconnect_ns is not None:
            times.append(self._disconnect_ns)
        return min(times)

    def step(self) -> None:
        """Run the next event (all parts due at its time)."""
        if self._latency is None and self._disconnect_ns is None and not self.disconnected:
            # a clean link: the next event is the device's next tick
            t = (self.ticks + 1) * self.tick_ns
            if t > self.now_ns:
                self.now_ns = t
            self.ticks += 1
            self.device.advance()
            self._emit(self.device.take_output())
            return
        t = self.next_event_ns()
        if t is None:
            return
        self.now_ns = max(self.now_ns, t)
        if self.disconnected:  # a reconnect is due: the device runs on, unheard
            if t >= self._reconnect_ns:
                self._reconnect()
            else:
                self.ticks += 1
                self.device.advance()
                self.stats.bytes_lost_while_disconnected += len(self.device.take_output())
            return
        if self._disconnect_ns is not None and t >= self._disconnect_ns:
            self._disconnect()
            return
        lat = self._latency
        if lat is not None and lat.deadline_ns is not None and lat.deadline_ns <= t:
            self._deliver(lat.flush())
        if (self.ticks + 1) * self.tick_ns <= t:
            self.ticks += 1
            self.device.advance()
            self._emit(self.device.take_output())

    def advance_to(self, t_ns: int) -> None:
        """Run every event due at or before ``t_ns``; then the clock reads ``t_ns``. A
        disconnect on the way ends the call there (the host must see it before a
        reconnect)."""
        was_down = self.disconnected
        while (e := self.next_event_ns()) is not None and e <= t_ns:
            self.step()
            if self.disconnected and not was_down:
                return
        self.now_ns = max(self.now_ns, t_ns)

    def advance_until_output(self, max_ns: int) -> None:
        """Run events until bytes reach the host, the link dies, or ``max_ns`` elapse."""
        start = self.now_ns
        while (
            not self.rx
            and not self.disconnected
            and (e := self.next_event_ns()) is not None
            and e - start <= max_ns
        ):
            self.step()

    def tick_until_output(self, size: int, deadline_ns: int) -> bool:
        """On a :attr:`clean` link: run device ticks until ``size`` bytes wait for the host
        (True) or the next tick would come after ``deadline_ns`` (False); what
        :meth:`step` does there, without its general event bookkeeping."""
        rx, device, tick_ns, down = self.rx, self.device, self.tick_ns, self.stats.down
        while len(rx) < size:
            t = (self.ticks + 1) * tick_ns
            if t > deadline_ns:
                return False
            if t > self.now_ns:
                self.now_ns = t
            self.ticks += 1
            device.advance()
            out = device.take_output()
            if out:
                n = len(out)
                down.bytes_in += n
                down.bytes_out += n
                rx += out
        return True

    def run_ticks(self, ticks: int, deadline_ns: int) -> None:
        """On a :attr:`clean` link: run ``ticks`` more device ticks (none due after
        ``deadline_ns``), their output delivered to the host (lock-step run-ahead)."""
        tick_ns, advance = self.tick_ns, self.device.advance
        many = getattr(self.device, "advance_ticks", None)  # several ticks in one call
        if many is not None:
            due = min(ticks, deadline_ns // tick_ns - self.ticks)  # ticks due by the deadline
            done = many(due) if due > 0 else 0
            if done:
                self.ticks += done
                self.now_ns = max(self.now_ns, self.ticks * tick_ns)
                ticks -= done
        for _ in range(ticks):
            t = (self.ticks + 1) * tick_ns
            if t > deadline_ns:
                break
            if t > self.now_ns:
                self.now_ns = t
            self.ticks += 1
            advance()
        out = self.device.take_output()  # the ticks' bytes, in order, in one piece
        if out:
            down, n = self.stats.down, len(out)
            down.bytes_in += n
            down.bytes_out += n
            self.rx += out

    def host_write(self, data: bytes) -> None:
        """Bytes from the host reach the device now; its responses enter the link."""
        if self.disconnected:
            raise Disconnected(f"{self.name}: port disconnected")
        if type(data) is not bytes:
            data = bytes(data)
        if self.clean:
            up = self.stats.up
            up.bytes_in += len(data)
            up.bytes_out += len(data)
        else:
            data = self._up.apply(data)
        if data:
            device = self.device
            device.receive(data)
            out = device.take_output()
            if out:
                self._emit(out)

    def take(self, size: int | None = None) -> bytes:
        """Remove and return up to ``size`` delivered bytes (all when None)."""
        if size is None or size >= len(self.rx):
            out = bytes(self.rx)
            self.rx.clear()
            return out
        n = size
        out = bytes(self.rx[:n])
        del self.rx[:n]
        return out

    def _emit(self, raw: bytes) -> None:
        if not raw:
            return
        if self.clean:
            down = self.stats.down
            down.bytes_in += len(raw)
            down.bytes_out += len(raw)
            self.rx += raw
            return
        data = self._down.apply(raw)
        if self._latency is not None:
            data = self._latency.push(data, self.now_ns)
        self._deliver(data)

    def _deliver(self, data: bytes) -> None:
        if data:
            self.rx += data
            if self._latency is not None:
                self.stats.bursts.append((self.now_s, len(data)))

    def _reconnect(self) -> None:
        self.disconnected = False
        self._disconnect_ns = self._reconnect_ns = None
        self.stats.reconnected_at_s = self.now_s
        self.rx.clear()

    def _disconnect(self) -> None:
        self.disconnected = True
        self.stats.disconnected_at_s = self.now_s
        if self._latency is not None:
            self.stats.down.bytes_lost_at_disconnect += len(self._latency.flush())
