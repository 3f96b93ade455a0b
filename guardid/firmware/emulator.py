"""Firmware emulator: the microcontroller's protocol state machine on a simulated plant.

It implements the :class:`guardid.fakeport.device.Device` interface. Per tick ``k``
(``advance``) it does what the firmware does at its 15 ms interrupt:

1. read the sensors for the period that just ended (encoder counts at ``k``; motor
   voltage and current as their means over ``k-1 .. k``, as the oversampling ADC gives);
2. check the watchdog (moving mode and no host frame for ``watchdog_ms``: 0 V, idle,
   watchdog bit latched, FAULT sent);
3. take the setpoint stamped for tick ``k`` from the buffer (none: hold the last one and
   flag ``setpoint_underrun``), with its feedforward voltage (SETPOINT_FF; 0 for SETPOINT);
4. compute the motor voltage (idle: 0; position: fixed-point PID plus the feedforward,
   before the output limit; voltage: the host's
   value), stop a joint from driving further past its position limit, quantise to the PWM
   duty, and hold it over ``k .. k+1``;
5. send TELEMETRY for tick ``k`` while streaming.

Ticks are a u32 counter compared with serial arithmetic (:func:`tick_diff`), as the README's
timing rules require. The portable C core (``firmware_proto/core``, in the loop through
:mod:`guardid.firmware.c_core`) implements the same state machine with the same integer
arithmetic; tests/test_firmware_c.py holds both to identical bytes. Steps 4 and 5 of a position-mode
tick run in the host's C extension when it is built (:mod:`guardid.protocol.fastcodec`:
``pid_pwm``, ``telemetry``; the same integers and bytes, tests/test_firmware_fast.py); so
does a whole position-mode tick (``fw_tick``; several in a row, ``fw_ticks``, for
:meth:`FirmwareEmulator.advance_ticks`) and the queueing of SETPOINT / SETPOINT_FF frames
(``fw_setpoints``), which read and write this object's attributes and leave every other
case to the Python path: a NAK, a retry, the watchdog's trip, another mode, a value of
another kind or range (tests/test_firmware_fast_tick.py).

Host frames are handled as they arrive (between ticks). A frame equal to the previous host
frame (same id, sequence number and payload: the host retrying a command whose ACK was lost)
that was answered by ACK or NAK gets that answer again and is not applied again. Unlike
the hardware, the emulator sends no INFO at reset: nothing is sent before the host talks,
since opening a pty flushes its input and the unsolicited frame would only show up as a
sequence gap.
"""

from __future__ import annotations

import math
import struct
from collections import deque
from functools import cache
from math import floor

from guardid.errors import ConfigError
from guardid.firmware.pid import FixedPid, counts_per_joint_rev, mv_from_volts, pid_gains_q16
from guardid.protocol import ENUMS, PROTOCOL_VERSION, Encoder, FrameParser, fastcodec
from guardid.protocol import MESSAGES as M
from guardid.protocol.codec import MAX_JOINTS
from guardid.protocol.codec import _fast_config as fast_config

MODE = ENUMS["mode"]
ERR = ENUMS["error"]
SETPOINT_FLAGS = ENUMS["setpoint_flags"]
FAULT = ENUMS["fault"]
STATUS = ENUMS["status"]
CAP = ENUMS["capability"]
TELEMETRY = M["TELEMETRY"]
UNDERRUN_BIT = 1 << STATUS["setpoint_underrun"]
WATCHDOG_BIT = 1 << STATUS["watchdog_tripped"]
ESTOP_BIT = 1 << STATUS["estop"]
SATURATED_BITS = [1 << v for k, v in sorted(STATUS.items()) if k.startswith("saturated_j")]
LIMIT_BITS = [1 << v for k, v in sorted(STATUS.items()) if k.startswith("limit_j")]
HOLD_BIT = 1 << SETPOINT_FLAGS["hold"]
if [f.name for f in M["SETPOINT"].SPEC.fields] != ["tick", "flags", "position"] or [
    f.name for f in M["SETPOINT_FF"].SPEC.fields
] != ["tick", "flags", "position", "feedforward"]:
    raise ImportError("the emulator's SETPOINT handlers no longer match the protocol")

#: the attributes the C tick and setpoint handler (fw_tick, fw_setpoints) read and write in
#: the emulator's __dict__
_C_STATE = (
    "mode", "applied_mv", "_applied_of", "_applied_v", "tick", "last_host_tick", "tick_us",
    "watchdog_ms", "_read_plant", "buffer", "setpoint", "setpoint_hold", "feedforward_mv",
    "_no_feedforward", "pids", "_drives", "watchdog_tripped", "estop", "streaming",
    "decimation", "encoder", "_telemetry_cfg", "_out", "counts", "status", "_last_frame",
    "_last_reply",
)  # fmt: skip
_PID_STATE = ("limit_mv", "kp", "ki", "kd", "integral", "prev_error", "saturated")
SETPOINT_DEPTH = 8  #: setpoints buffered ahead of their tick
DEFAULT_WATCHDOG_MS = 250
FIRMWARE_ID = 0x47554131  #: "GUA1", the emulators (Python and the C core in the loop)
TICK_MASK = 0xFFFFFFFF  #: the tick is a u32 counter
IDLE, POSITION, VOLTAGE = MODE["idle"], MODE["position"], MODE["voltage"]


def pwm_mv(mv: int, levels: int, supply_mv: int) -> int:
    """``mv`` [mV] quantised to a sign-magnitude PWM duty of ``levels`` steps of the
    ``supply_mv`` [mV] (rounded), returned as the duty's voltage [mV]; integer math, as the
    C core's ``gf_sil_pwm``."""
    duty = (abs(mv) * levels + supply_mv // 2) // supply_mv
    duty_mv = (duty * supply_mv + levels // 2) // levels
    return duty_mv if mv >= 0 else -duty_mv


@cache
def pwm_table(levels: int, supply_mv: int) -> tuple[int, ...]:
    """:func:`pwm_mv` of every ``mv`` in ``-supply_mv .. supply_mv`` (index ``mv +
    supply_mv``), made once per process and drive: the per-tick lookup."""
    return tuple(pwm_mv(mv, levels, supply_mv) for mv in range(-supply_mv, supply_mv + 1))


def tick_diff(a: int, b: int) -> int:
    """Serial tick arithmetic (README timing rules): ``(int32_t)(a - b)``."""
    return ((a - b + 0x80000000) & TICK_MASK) - 0x80000000


def require_simulable(description) -> None:
    """Raise a one-line :class:`ConfigError` unless the firmware can run ``description``: a
    serial chain whose every joint has a drive and an encoder (the guard robot's build)."""
    where = getattr(description, "source", "") or description.name
    joints = getattr(description, "joints", None)
    if joints is None:
        raise ConfigError(
            f"{where}: robot {description.name} ({description.model}) cannot be simulated "
            "behind the firmware: it needs a serial chain with a drive and an encoder per joint"
        )
    for k, j in enumerate(joints):
        missing = [what for what, x in (("drive", j.drive), ("encoder", j.encoder)) if x is None]
        if missing:
            raise ConfigError(
                f"{where}: joints[{k}] ({j.name}): no {' or '.join(missing)}; the firmware "
                f"emulator needs a drive and an encoder on every joint to simulate robot "
                f"{description.name}"
            )


def bind_robot(fw, description, plant) -> None:
    """Set the robot facts both firmware implementations need on ``fw``: description,
    plant, joint count ``n``, ``tick_us`` [us], ``tick_period_s`` [s] and ``cpr`` (encoder
    counts per joint revolution). Every joint needs a drive and an encoder."""
    require_simulable(description)
    joints = description.joints
    fw.description = description
    fw.plant = plant
    fw.n = len(joints)
    fw.tick_us = int(round(description.sample_period * 1e6))
    fw.tick_period_s = fw.tick_us * 1e-6
    fw.cpr = [counts_per_joint_rev(j.encoder.counts_per_rev, j.drive.gear_ratio) for j in joints]


class FirmwareEmulator:
    """The guard firmware's behaviour over a plant with ``step(voltages_V) -> sample``.

    ``description`` is a :class:`guardid.robot.ChainDescription` whose joints all have a
    drive and an encoder; ``plant`` advances one sample period per ``step`` and returns an
    object with ``counts`` (encoder counts per joint, ints), ``voltage`` [V] and
    ``current`` [A] (period means as the ADC reports them).
    """

    runs_ahead = True  #: host frames handled between ticks (guardid.fakeport.device)
    #: INFO protocol_version and capability bits; a subclass may play older firmware
    protocol_version = PROTOCOL_VERSION
    capabilities = (
        "current_sense",
        "voltage_sense",
        "setpoint_buffer",
        "watchdog",
        "voltage_mode",
        "feedforward",
    )

    def __init__(self, description, plant) -> None:
        joints = description.joints
        bind_robot(self, description, plant)
        self.supply_mv = [mv_from_volts(j.drive.supply_voltage) for j in joints]
        self.pwm_levels = [(1 << j.drive.pwm_bits) - 1 for j in joints]
        self.limits = [self._count_limits(j, c) for j, c in zip(joints, self.cpr, strict=True)]
        self.pids = [FixedPid(s) for s in self.supply_mv]
        # per joint, for the tick: (count limits or None, PWM levels, supply [mV], the PWM
        # voltage [mV] of every mV in +-supply: pwm_table)
        drives = zip(self.limits, self.pwm_levels, self.supply_mv, strict=True)
        self._per_joint = [(lim, lv, s, pwm_table(lv, s)) for lim, lv, s in drives]
        for pid, joint, cpr in zip(self.pids, joints, self.cpr, strict=True):
            if joint.pid is not None:
                gains = [int(round(g * 1e6)) for g in (joint.pid.kp, joint.pid.ki, joint.pid.kd)]
                pid.set_gains(pid_gains_q16(*gains, cpr, self.tick_us))

        self.parser = FrameParser()
        self.encoder = Encoder()
        self._telemetry_frame = self.encoder.packer(TELEMETRY, self.n)  # per-tick fast path
        self._read_plant = getattr(plant, "step_sensors", None) or self._sample_fields
        # the position-mode tick in C (fastcodec's extension; None: the Python path), its
        # drive facts per joint as int64s: has limits, limits [counts], levels, supply [mV],
        # saturated and limit status bits
        fast = fastcodec.module()
        bounds = [lim or (0, 0) for lim, *_ in self._per_joint]
        fits = self.n <= MAX_JOINTS and all(abs(b) < 2**62 for pair in bounds for b in pair)
        self._pid_pwm = fast.pid_pwm if fast is not None and fits else None
        self._telemetry_c = fast.telemetry if fast is not None and fits else None
        # the whole position-mode tick and the queueing of setpoints in C (fw_tick,
        # fw_setpoints: tests/test_firmware_fast_tick.py), with the constants they compare
        # with; they read and write the attributes in the instances' __dict__: only while no
        # class attribute has one of their names (and SETPOINT, SETPOINT_FF go to these
        # handlers)
        owners = [(self, _C_STATE), (self.encoder, ("seq",)), *((p, _PID_STATE) for p in self.pids)]
        own = not any(hasattr(type(x), a) for x, names in owners for a in names)
        handlers = [self._HANDLERS.get(k) for k in ("Setpoint", "SetpointFf")]
        plain = handlers == [FirmwareEmulator._on_setpoint, FirmwareEmulator._on_setpoint_ff]
        self._tick_c = fast.fw_tick if fast is not None and fits and own else None
        # (several ticks a call: only while advance is this class's, which they stand for)
        plain_advance = type(self).advance is FirmwareEmulator.advance
        self._ticks_c = fast.fw_ticks if self._tick_c is not None and plain_advance else None
        self._setpoints_c = fast.fw_setpoints if self._tick_c is not None and plain else None
        self._tick_consts = struct.pack("=4q", POSITION, UNDERRUN_BIT, WATCHDOG_BIT, ESTOP_BIT)
        self._setpoint_consts = struct.pack(
            f"={6 + self.n}q", M["SETPOINT"].MSG_ID, M["SETPOINT_FF"].MSG_ID, POSITION,
            SETPOINT_DEPTH, HOLD_BIT, self.n, *self.supply_mv
        )  # fmt: skip
        self._telemetry_cfg = fast_config(TELEMETRY.SPEC, self.n) if fits else b""
        self._drives = b"".join(
            struct.pack("=7q", lim is not None, *b, levels, supply, sat, stop)
            for (lim, levels, supply, _), b, sat, stop in zip(
                self._per_joint, bounds, SATURATED_BITS, LIMIT_BITS, strict=False
            )
        )  # (fits: n <= MAX_JOINTS, the number of status bits of each kind)
        self._last_frame = None  # (msg_id, seq, message) of the previous host frame
        self._last_reply = None  # its ACK/NAK, resent if the same frame comes again
        # _HANDLERS (a subclass may replace some) by message id, a parsed frame's first field
        self._by_id = {
            c.MSG_ID: self._HANDLERS[c.__name__] for c in M.values() if c.__name__ in self._HANDLERS
        }
        self._out = bytearray()
        self._applied_of = self._applied_v = None  # the C tick's applied_mv and it in V
        self.tick = 0
        self.mode = MODE["idle"]
        self.streaming = False
        self.decimation = 1
        self.estop = False
        self.watchdog_tripped = False
        self.watchdog_ms = DEFAULT_WATCHDOG_MS
        self.last_host_tick = 0
        self.buffer: deque = deque()
        self.setpoint = [0] * self.n
        self._no_feedforward = [0] * self.n  # shared, never changed
        self.feedforward_mv = self._no_feedforward  # added to the PID output (SETPOINT_FF)
        self.setpoint_hold = True  # no underrun before the first streamed setpoint
        self.voltage_cmd_mv = [0] * self.n
        # after limits and PWM, held over the next period (replaced, not changed in place,
        # once the C tick ran: _applied_v holds it in V)
        self.applied_mv = [0] * self.n
        self.counts = [0] * self.n
        self.status = 0

    @staticmethod
    def _count_limits(joint, cpr: int):
        if joint.limits.position is None:
            return None
        lo, hi = joint.limits.position
        return (math.ceil(lo * cpr / (2 * math.pi)), math.floor(hi * cpr / (2 * math.pi)))

    # ------------------------------------------------------------------ host side
    def receive(self, data: bytes) -> None:
        """Handle every whole valid frame in ``data`` (partial frames wait for more)."""
        handlers, fast = self._by_id, self._setpoints_c
        frames = self.parser.feed(data)
        if frames:  # no handler changes the tick
            self.last_host_tick = self.tick
        k, n = 0, len(frames)
        while k < n:
            if fast is not None:  # the setpoints from frame k on that it queues, in C
                k = fast(self.__dict__, frames, k, self._setpoint_consts)
                if k == n:
                    break
            frame = frames[k]  # a Frame is the (msg_id, seq, message) key
            k += 1
            if self._last_reply is not None and frame == self._last_frame:
                self._send(self._last_reply)  # a retry: answer again, change nothing
                continue
            self._last_frame, self._last_reply = frame, None
            handler = handlers.get(frame.msg_id)
            if handler is not None:
                handler(self, frame)

    def _send(self, msg) -> None:
        self._out += self.encoder.encode(msg)

    def _ack(self, frame) -> None:
        self._last_reply = M["ACK"](frame.seq, frame.msg_id)
        self._send(self._last_reply)

    def _nak(self, frame, error: str) -> None:
        self._last_reply = M["NAK"](frame.seq, frame.msg_id, ERR[error])
        self._send(self._last_reply)

    def _on_hello(self, frame) -> None:
        caps = sum(1 << CAP[c] for c in self.capabilities)
        self._send(
            M["INFO"](
                self.protocol_version,
                self.n,
                caps,
                FIRMWARE_ID,
                self.tick_us,
                self.watchdog_ms,
                SETPOINT_DEPTH,
                tuple(self.cpr),
            )
        )

    def _on_ping(self, frame) -> None:
        self._send(M["PONG"](frame.msg.nonce, self.tick))

    def _on_set_mode(self, frame) -> None:
        mode = frame.msg.mode
        if mode not in MODE.values():
            return self._nak(frame, "bad_value")
        if mode != MODE["idle"] and self.estop:
            return self._nak(frame, "estop_active")
        if mode != self.mode:  # README: SET_MODE to the current mode changes nothing
            self._enter_mode(mode)
        if mode != MODE["idle"]:
            self.watchdog_tripped = False
        self._ack(frame)

    def _enter_mode(self, mode: int) -> None:
        self.mode = mode
        self.buffer.clear()
        self.setpoint = list(self.counts)
        self.feedforward_mv = self._no_feedforward
        self.setpoint_hold = True  # no underrun before the first streamed setpoint
        self.voltage_cmd_mv = [0] * self.n
        for pid in self.pids:
            pid.reset()
        if mode == MODE["idle"]:
            self.applied_mv = [0] * self.n

    def _on_set_pid(self, frame) -> None:
        msg = frame.msg
        if not 0 <= msg.joint < self.n:
            return self._nak(frame, "bad_joint")
        gains = pid_gains_q16(msg.kp, msg.ki, msg.kd, self.cpr[msg.joint], self.tick_us)
        self.pids[msg.joint].set_gains(gains)
        self._ack(frame)

    def _on_setpoint_ff(self, frame) -> None:
        self._on_setpoint(frame, list(frame.msg[3]))

    def _on_setpoint(self, frame, feedforward_mv=None) -> None:
        """Queue (tick, position, hold) for SETPOINT, (tick, position, hold, feedforward [mV])
        for SETPOINT_FF (a 3-tuple entry means no feedforward), or NAK."""
        msg, buffer = frame.msg, self.buffer
        tick, flags, position = msg[0], msg[1], msg[2]
        if len(position) != self.n:
            return self._nak(frame, "bad_joint")
        if self.estop:
            return self._nak(frame, "estop_active")
        if self.mode != POSITION:
            return self._nak(frame, "wrong_mode")
        # tick_diff(tick, x) <= 0, inlined (serial u32 arithmetic)
        if ((tick - self.tick + 0x80000000) & TICK_MASK) <= 0x80000000:
            return self._nak(frame, "setpoint_late")
        if buffer and ((tick - buffer[-1][0] + 0x80000000) & TICK_MASK) <= 0x80000000:
            return self._nak(frame, "bad_value")
        if len(buffer) >= SETPOINT_DEPTH:
            return self._nak(frame, "buffer_full")
        if feedforward_mv is None:
            return buffer.append((tick, list(position), bool(flags & HOLD_BIT)))
        if any(abs(v) > s for v, s in zip(feedforward_mv, self.supply_mv, strict=True)):
            return self._nak(frame, "bad_value")
        buffer.append((tick, list(position), bool(flags & HOLD_BIT), feedforward_mv))

    def _on_set_voltage(self, frame) -> None:
        msg = frame.msg
        if len(msg.voltage) != self.n:
            return self._nak(frame, "bad_joint")
        if self.estop:
            return self._nak(frame, "estop_active")
        if self.mode != MODE["voltage"]:
            return self._nak(frame, "wrong_mode")
        if any(abs(v) > s for v, s in zip(msg.voltage, self.supply_mv, strict=True)):
            return self._nak(frame, "bad_value")
        self.voltage_cmd_mv = list(msg.voltage)

    def _on_start_stream(self, frame) -> None:
        if frame.msg.decimation < 1:
            return self._nak(frame, "bad_value")
        self.streaming = True
        self.decimation = frame.msg.decimation
        self._ack(frame)

    def _on_stop_stream(self, frame) -> None:
        self.streaming = False
        self._ack(frame)

    def _on_estop(self, frame) -> None:
        self.estop = True
        self._enter_mode(MODE["idle"])
        self._ack(frame)
        self._send(M["FAULT"](self.tick, FAULT["estop"], 0xFF, 0))

    def _on_clear_estop(self, frame) -> None:
        self.estop = False
        self.watchdog_tripped = False
        self._ack(frame)

    def _on_set_watchdog(self, frame) -> None:
        if frame.msg.timeout == 0:
            return self._nak(frame, "bad_value")
        self.watchdog_ms = frame.msg.timeout
        self._ack(frame)

    _HANDLERS = {
        "Hello": _on_hello,
        "Ping": _on_ping,
        "SetMode": _on_set_mode,
        "SetPid": _on_set_pid,
        "Setpoint": _on_setpoint,
        "SetpointFf": _on_setpoint_ff,
        "SetVoltage": _on_set_voltage,
        "StartStream": _on_start_stream,
        "StopStream": _on_stop_stream,
        "Estop": _on_estop,
        "ClearEstop": _on_clear_estop,
        "SetWatchdog": _on_set_watchdog,
    }

    # ------------------------------------------------------------------ the 15 ms tick
    def advance(self) -> None:
        """One sample period of the plant, then the firmware's tick (module docstring)."""
        sensed = None  # the C extension's whole position-mode tick when it takes it
        if self._tick_c is not None:
            sensed = self._tick_c(self.__dict__, self._tick_consts)
            if sensed is True:  # done
                return
        if sensed is None:  # else the plant was read: the Python path goes on from there
            applied = self.applied_mv  # [V] from the C tick when it made that list
            u = self._applied_v if applied is self._applied_of else [mv * 1e-3 for mv in applied]
            sensed = self._read_plant(u)
        self._tick_from(sensed)

    def advance_ticks(self, count: int) -> int:
        """Up to ``count`` ticks, as many calls of :meth:`advance`, in one call of the C
        extension (``fw_ticks``); returns the ticks run: fewer than ``count`` (maybe 0)
        when a tick is not one the C tick does whole (the caller advances from there)."""
        if self._ticks_c is None:
            return 0
        done, sensed = self._ticks_c(self.__dict__, self._tick_consts, count)
        if sensed is not None:  # that tick's plant was read: the Python path finishes it
            self._tick_from(sensed)
            done += 1
        return done

    def _tick_from(self, sensed) -> None:
        """The tick after the plant's read ``sensed``: (counts, voltage [V], current [A])."""
        counts, volts, amps = sensed
        self.tick = tick = (self.tick + 1) & TICK_MASK
        self.counts = counts
        status = 0
        mode = self.mode
        if mode != IDLE:
            silent_ms = ((tick - self.last_host_tick) & TICK_MASK) * self.tick_us // 1000
            if silent_ms >= self.watchdog_ms:
                self.watchdog_tripped = True
                self._enter_mode(IDLE)
                self._send(M["FAULT"](tick, FAULT["watchdog"], 0xFF, silent_ms))
                mode = IDLE
        done = None  # the C tick's (applied [mV], status bits, applied [V])
        if mode == POSITION:
            due = False
            buffer = self.buffer
            # tick_diff(buffer[0][0], tick) <= 0, inlined (serial u32 arithmetic)
            while buffer and ((buffer[0][0] - tick + 0x80000000) & TICK_MASK) <= 0x80000000:
                entry = buffer.popleft()
                self.setpoint, self.setpoint_hold = entry[1], entry[2]
                self.feedforward_mv = entry[3] if len(entry) > 3 else self._no_feedforward
                due = True
            if not due and not self.setpoint_hold:
                status |= UNDERRUN_BIT
            setpoint, feedforward = self.setpoint, self.feedforward_mv
            if self._pid_pwm is not None:  # the C extension: PID, limit stop and PWM
                done = self._pid_pwm(self.pids, setpoint, counts, feedforward, self._drives)
            if done is None:
                out = []
                for j, pid in enumerate(self.pids):
                    out.append(pid.step(setpoint[j], counts[j], feedforward[j]))
                    if pid.saturated:
                        status |= SATURATED_BITS[j]
        elif mode == VOLTAGE:
            out = [
                max(-s, min(s, v)) for v, s in zip(self.voltage_cmd_mv, self.supply_mv, strict=True)
            ]
        else:
            out = [0] * self.n
        if done is None:
            applied = []
            for j, (lim, levels, supply, table) in enumerate(self._per_joint):
                mv = out[j]
                if lim is not None and (
                    (mv > 0 and counts[j] >= lim[1]) or (mv < 0 and counts[j] <= lim[0])
                ):
                    mv = 0
                    status |= LIMIT_BITS[j]
                if -supply <= mv <= supply:
                    applied.append(table[mv + supply])
                else:
                    applied.append(pwm_mv(mv, levels, supply))
            self.applied_mv = applied
        else:
            self.applied_mv, bits, self._applied_v = done
            self._applied_of = self.applied_mv
            status |= bits
        if self.watchdog_tripped:
            status |= WATCHDOG_BIT
        if self.estop:
            status |= ESTOP_BIT
        self.status = status
        if self.streaming and tick % self.decimation == 0:
            # TELEMETRY(tick, status, mode, counts, voltage [mV], current [mA], setpoint),
            # packed from its flattened values (the bytes encode() gives for the message);
            # voltage [V] and current [A] to milli-units (rounded half up), clamped to int16
            # (the packer refuses a value out of range without numbering a frame); by the C
            # extension (rounding, clamping, packing in one call) when it takes the values
            frame, setpoint = None, self.setpoint
            if self._telemetry_c is not None:
                encoder = self.encoder
                frame = self._telemetry_c(self._telemetry_cfg, encoder.seq, tick, status, mode,
                                          counts, volts, amps, setpoint)  # fmt: skip
                if frame is not None:
                    encoder.seq = (encoder.seq + 1) & 0xFFFF
            if frame is None:
                pack = self._telemetry_frame
                milli = [floor(x * 1000.0 + 0.5) for x in (*volts, *amps)]
                try:
                    frame = pack(tick, status, mode, *counts, *milli, *setpoint)
                except ValueError:
                    milli = [-32768 if m < -32768 else 32767 if m > 32767 else m for m in milli]
                    frame = pack(tick, status, mode, *counts, *milli, *setpoint)
            self._out += frame

    def _sample_fields(self, volts) -> tuple:
        """(counts, voltage [V], current [A]) of ``plant.step(volts)``, for a plant without
        the lean ``step_sensors``."""
        sample = self.plant.step(volts)
        return [int(c) for c in sample.counts], sample.voltage, sample.current

    def take_output(self) -> bytes:
        """Bytes emitted since the previous call."""
        if not self._out:
            return b""
        out = bytes(self._out)
        self._out.clear()
        return out

    def wants_time(self) -> bool:
        """Time matters while streaming or moving (the watchdog runs)."""
        return self.streaming or self.mode != MODE["idle"]

    def close(self) -> None:
        """Nothing to release."""


def make_sim_device(robot: str, options) -> FirmwareEmulator:
    """Device factory for ``sim://``: the robot's YAML, a seeded plant, this emulator."""
    from guardid.plant import make_plant
    from guardid.robot import load_robot

    description = load_robot(robot)
    require_simulable(description)
    plant = make_plant(description, options)
    return FirmwareEmulator(description, plant)
