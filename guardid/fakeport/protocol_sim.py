"""pyserial URL handler: ``serial.serial_for_url("sim://guard?seed=1")``.

Lock-step pacing: a read() short of bytes advances the device event by event until
enough bytes arrived or the read timeout, counted in SIMULATED seconds, is used up;
write() reaches the device at once. Real-time pacing: a thread runs the events on an
absolute wall-clock schedule (``pacing`` times faster) and reads wait on a condition.
"""

from __future__ import annotations

import threading
import time

from serial.serialutil import PortNotOpenError, SerialBase, SerialException, to_bytes

from guardid.fakeport.engine import Disconnected, LinkEngine
from guardid.fakeport.factory import make_device
from guardid.fakeport.options import SimOptions, parse_sim_url

#: A lock-step read without timeout gives up after this much simulated time [s].
MAX_BLOCK_S = 600.0


class Serial(SerialBase):
    """A serial port whose other end is an emulated device."""

    reads_ahead = True  #: read_some takes ahead_ticks (lock-step run-ahead)

    def __init__(self, *args, **kwargs) -> None:
        self.engine: LinkEngine | None = None
        self.options: SimOptions | None = None
        self._lock = threading.RLock()
        self._cond = threading.Condition(self._lock)  # lock-step paths take _lock alone
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self._t0 = 0.0
        self._runs_ahead = False
        super().__init__(*args, **kwargs)

    # -- opening and closing ------------------------------------------------------
    def open(self) -> None:
        """Parse the URL, build the device and start the clock."""
        if self.is_open:
            raise SerialException("Port is already open.")
        if self._port is None:
            raise SerialException("Port must be configured before it can be used.")
        self.options = parse_sim_url(self.portstr)
        device = make_device(self.options.robot, self.options)
        name = self.portstr.split("?", 1)[0]
        self.engine = LinkEngine(device, self.options.faults, self.options.seed, name)
        # read_some(ahead_ticks): lock-step, and a device that may run ahead
        self._runs_ahead = self.options.lockstep and getattr(device, "runs_ahead", False)
        self._dtr_was = self._dtr_state
        self.is_open = True
        self._stop.clear()
        self._t0 = time.monotonic()
        if not self.options.lockstep:
            self._thread = threading.Thread(target=self._run_realtime, daemon=True)
            self._thread.start()

    def close(self) -> None:
        """Stop the clock and close the device."""
        if self.is_open:
            self.is_open = False
            self._stop.set()
            with self._cond:
                self._cond.notify_all()
            if self._thread is not None:
                self._thread.join()
                self._thread = None
            self.engine.device.close()
        super().close()

    def _reconfigure_port(self, *args, **kwargs) -> None:
        """Line settings do not matter to the emulated device."""

    def _update_dtr_state(self) -> None:
        """DTR asserted again after being released: a board's auto-reset capacitor pulses
        RESET; a device with a ``reset()`` (``firmware=avr&bootloader=...``) restarts."""
        was, self._dtr_was = getattr(self, "_dtr_was", True), self._dtr_state
        reset = getattr(self.engine.device, "reset", None) if self.engine else None
        if self._dtr_state and not was and callable(reset):
            with self._lock:
                reset()
                self.engine.take()

    def _update_rts_state(self) -> None:
        pass

    def _update_break_state(self) -> None:
        pass

    # -- data ------------------------------------------------------------------------
    @property
    def in_waiting(self) -> int:
        """Bytes delivered to the host and not read yet (never advances time)."""
        self._check_open()
        with self._cond:
            return len(self.engine.rx)

    @property
    def out_waiting(self) -> int:
        """Always 0: writes reach the device at once."""
        self._check_open()
        return 0

    @property
    def fault_stats(self):
        """The injected damage so far (:class:`guardid.fakeport.faults.FaultStats`)."""
        return self.engine.stats

    @property
    def sim_time_s(self) -> float:
        """Simulated time [s] on the device side."""
        return self.engine.now_s

    def read(self, size: int = 1) -> bytes:
        """Read up to ``size`` bytes; see the module docstring for pacing."""
        self._check_open()
        with self._cond:
            if self.options.lockstep:
                self._fill_lockstep(size)
            else:
                self._fill_realtime(size)
            data = self.engine.take(size)
            if size > 0 and not data and self.engine.disconnected:
                raise Disconnected(f"{self.engine.name}: port disconnected")
            return data

    def read_some(self, ahead_ticks: int = 0) -> bytes:
        """What ``read(1)`` waits for, then every byte delivered so far: one call where a
        host would ask ``in_waiting``, ``read(1)`` and ``read(in_waiting)``.

        ``ahead_ticks`` (lock-step, a link without faults and a device that ``runs_ahead``
        only; ignored otherwise): once bytes arrived, the device runs that many ticks more
        (within the read's timeout) before the read returns, their bytes included: a host
        whose next bytes do not depend on what those ticks send (setpoints streamed ahead)
        takes several ticks' telemetry in one call."""
        self._check_open()
        with self._lock:  # the condition's lock (waits happen in _fill_realtime only)
            engine = self.engine
            if not engine.rx:
                if self.options.lockstep:
                    self._fill_lockstep(1)
                else:
                    self._fill_realtime(1)
            if ahead_ticks > 0 and engine.rx and engine.clean and self._runs_ahead:
                limit = MAX_BLOCK_S if self._timeout is None else self._timeout
                engine.run_ticks(ahead_ticks, engine.now_ns + round(limit * 1e9))
            data = engine.take()
            if not data and engine.disconnected:
                raise Disconnected(f"{engine.name}: port disconnected")
            return data

    def wait_link(self, timeout_s: float) -> bool:
        """After a disconnect: wait up to ``timeout_s`` [s] (simulated in lock-step, the
        device running on) for the link to come back (``reconnect_s``); True when it is."""
        self._check_open()
        engine = self.engine
        if self.options.lockstep:
            with self._lock:
                deadline = engine.now_ns + round(timeout_s * 1e9)
                while engine.reconnect_pending:
                    e = engine.next_event_ns()
                    if e is None or e > deadline:
                        engine.advance_to(deadline)
                        break
                    engine.step()
                return not engine.disconnected
        end = time.monotonic() + timeout_s
        with self._cond:
            while engine.disconnected and engine.reconnect_pending:
                remaining = end - time.monotonic()
                if remaining <= 0:
                    break
                self._cond.wait(min(remaining, 0.05))
            return not engine.disconnected

    def write(self, data) -> int:
        """Hand ``data`` to the device now (real-time: at the current wall-clock time)."""
        self._check_open()
        if type(data) is not bytes:
            data = to_bytes(data)
        with self._lock:  # the condition's lock
            if self.options.lockstep:  # nothing ever waits on the condition in lock-step
                self.engine.host_write(data)
            else:
                self.engine.advance_to(self._wall_ns())
                self.engine.host_write(data)
                self._cond.notify_all()
        return len(data)

    def flush(self) -> None:
        """Nothing to wait for."""

    def reset_input_buffer(self) -> None:
        """Discard bytes delivered to the host and not read yet."""
        self._check_open()
        with self._cond:
            self.engine.rx.clear()

    def reset_output_buffer(self) -> None:
        """Nothing is ever pending towards the device."""
        self._check_open()

    def cancel_read(self) -> None:
        """Wake a waiting real-time read."""
        with self._cond:
            self._cond.notify_all()

    @property
    def cts(self) -> bool:
        self._check_open()
        return True

    @property
    def dsr(self) -> bool:
        self._check_open()
        return True

    @property
    def ri(self) -> bool:
        self._check_open()
        return False

    @property
    def cd(self) -> bool:
        self._check_open()
        return True

    # -- pacing --------------------------------------------------------------------------
    def _check_open(self) -> None:
        if not self.is_open:
            raise PortNotOpenError()

    def _fill_lockstep(self, size: int) -> None:
        engine = self.engine
        if len(engine.rx) >= size or self._timeout == 0:
            return
        limit = MAX_BLOCK_S if self._timeout is None else self._timeout
        deadline = engine.now_ns + round(limit * 1e9)
        if engine.clean and self._timeout is not None:  # only device ticks can happen
            if not engine.tick_until_output(size, deadline):
                engine.advance_to(deadline)
            return
        while len(engine.rx) < size and not engine.disconnected:
            e = engine.next_event_ns()
            if self._timeout is None and self._idle_forever():
                raise SerialException(
                    f"{engine.name}: read() without timeout would block forever: the device is idle"
                )
            if e is None or e > deadline:
                if self._timeout is None:
                    raise SerialException(
                        f"{engine.name}: no data within {MAX_BLOCK_S:g} s simulated"
                    )
                engine.advance_to(deadline)
                return
            engine.step()

    def _idle_forever(self) -> bool:
        from guardid.fakeport.device import wants_time

        engine = self.engine
        return not (wants_time(engine.device) or engine.pending_bytes or engine.disconnect_pending)

    def _fill_realtime(self, size: int) -> None:
        end = None if self._timeout is None else time.monotonic() + self._timeout
        while len(self.engine.rx) < size and not self.engine.disconnected and self.is_open:
            remaining = None if end is None else end - time.monotonic()
            if remaining is not None and remaining <= 0:
                return
            self._cond.wait(remaining)

    def _wall_ns(self) -> int:
        return round((time.monotonic() - self._t0) * self.options.pacing * 1e9)

    def _run_realtime(self) -> None:
        """Run the events on an absolute schedule: event at t runs at t0 + t / pacing."""
        while not self._stop.is_set():
            with self._cond:
                e = self.engine.next_event_ns()
            if e is None:
                return
            wait = self._t0 + e * 1e-9 / self.options.pacing - time.monotonic()
            if wait > 0 and self._stop.wait(wait):
                return
            with self._cond:
                self.engine.advance_to(e)
                self._cond.notify_all()
