"""The firmware emulator's whole position-mode tick and its queueing of setpoint frames in C
(gp_pyext ``fw_tick``, ``fw_setpoints``) do what its Python path does.

Truth: the same emulator with both C paths off (its Python tick and SETPOINT handlers, as
with ``GUARDID_NATIVE=0``), fed the same bytes, over a plant that gives both the same
readings; and the NAK error codes each refused frame must get, worked out by hand from the
README's rules.
"""

from __future__ import annotations

import math
import os

import pytest

from guardid.fakeport.engine import LinkEngine
from guardid.fakeport.faults import FaultConfig
from guardid.firmware import FirmwareEmulator
from guardid.native import find_compiler
from guardid.protocol import ENUMS, Encoder, FrameParser, encode
from guardid.protocol import MESSAGES as M
from guardid.robot import load_robot

pytestmark = pytest.mark.skipif(
    find_compiler() is None or os.environ.get("GUARDID_NATIVE") == "0", reason="needs a C compiler"
)
ERR = ENUMS["error"]
MODE = ENUMS["mode"]


class WavyPlant:
    """Counts that follow the applied voltage [V] (40 counts per V per tick) plus a ripple,
    voltages and currents with sub-milli digits; at ``huge_at`` ticks a count beyond the C
    tick's exact range (the Python path's), at ``amps_at`` a current beyond int16 mA."""

    def __init__(self, huge_at=(), amps_at=()) -> None:
        self.k, self.pos = 0, [0.0, 0.0]
        self.huge_at, self.amps_at = set(huge_at), set(amps_at)

    def step_sensors(self, u):
        self.k += 1
        self.pos = [p + 40.0 * v + 3.0 * math.sin(0.3 * self.k + j) for j, (p, v) in
                    enumerate(zip(self.pos, u, strict=True))]  # fmt: skip
        counts = [math.floor(p) for p in self.pos]
        if self.k in self.huge_at:
            counts[1] = 2**29 + 17
        amps = [v / 8.0 + 0.00049 * self.k for v in u]
        if self.k in self.amps_at:
            amps[0] = 40.0
        return counts, [v + 0.0005 for v in u], amps


def _pair(**plant):
    """(emulator with the C paths, the same with them off), on equal plants."""
    guard = load_robot("guard")
    fast, slow = (FirmwareEmulator(guard, WavyPlant(**plant)) for _ in range(2))
    assert fast._tick_c is not None and fast._setpoints_c is not None
    slow._tick_c = slow._setpoints_c = None
    return fast, slow


def _state(fw) -> tuple:
    pids = [(p.integral, p.prev_error, p.saturated) for p in fw.pids]
    return (fw.tick, fw.counts, fw.setpoint, fw.setpoint_hold, fw.feedforward_mv,
            list(fw.buffer), pids, fw.applied_mv, fw.status, fw.mode, fw.encoder.seq,
            fw._last_frame, fw._last_reply, fw.watchdog_tripped, fw.estop)  # fmt: skip


def _same(fast, slow, data=None, ticks=0, seen=None, runs=False) -> bytes:
    """Both get ``data`` then run ``ticks``; the same bytes out and state, tick by tick
    (their status bits added to ``seen``); ``runs``: ``fast`` runs them by advance_ticks
    (then advance for the rest), compared after them."""
    out = b""
    if data is not None:
        fast.receive(data)
        slow.receive(data)
        out = fast.take_output()
        assert out == slow.take_output()
        assert _state(fast) == _state(slow)
    if runs and ticks:
        done = fast.advance_ticks(ticks)
        for _ in range(ticks - done):
            fast.advance()
        for _ in range(ticks):
            slow.advance()
        got = fast.take_output()
        assert got == slow.take_output()
        assert _state(fast) == _state(slow)
        if seen is not None:
            seen.add(fast.status)
        return out + got
    for _ in range(ticks):
        fast.advance()
        slow.advance()
        got = fast.take_output()
        assert got == slow.take_output()
        assert _state(fast) == _state(slow)
        out += got
        if seen is not None:
            seen.add(fast.status)
    return out


def _naks(data: bytes) -> list[tuple[int, int]]:
    """(refused frame's seq, error code) of every NAK in ``data``."""
    return [(f.msg.ack_seq, f.msg.error) for f in FrameParser().feed(data)
            if type(f.msg) is M["NAK"]]  # fmt: skip


def test_setpoint_runs_are_queued_and_every_refusal_is_the_python_handlers():
    """Runs of SETPOINT / SETPOINT_FF in one chunk: queued as the handlers queue them (hold
    flag, feedforward), and each refusal in the README's order: late, not after the last
    buffered (bad_value), buffer full, feedforward beyond the supply (bad_value), wrong
    joint count, e-stop, wrong mode; a retried frame answered again, not applied again."""
    fast, slow = _pair()
    host = Encoder()
    sp = M["SETPOINT"]
    _same(fast, slow, host.encode(M["SET_MODE"](MODE["position"])), ticks=3)
    now = fast.tick  # 3
    late = host.encode(sp(now, 0, (9, 9)))  # for the tick that just ran: late, empty buffer
    assert _naks(_same(fast, slow, late)) == [(host.seq - 1, ERR["setpoint_late"])]
    s0 = host.seq
    chunk = b"".join([
        host.encode(sp(now + 1, 0, (10, 20))),
        host.encode(sp(now + 2, 1, (11, 21))),  # hold
        host.encode(sp(now + 2, 0, (12, 22))),  # s0 + 2: not after the last: bad_value
        host.encode(sp(now + 3, 0, (13, 23))),
        host.encode(sp(now, 0, (14, 24))),  # s0 + 4: late
        host.encode(M["SETPOINT_FF"](now + 4, 0, (15, 25), (100, -200))),
        host.encode(M["SETPOINT_FF"](now + 5, 0, (16, 26), (12001, 0))),  # s0 + 6: > supply
        host.encode(sp(now + 5, 0, (17, 27, 37))),  # s0 + 7: three joints
    ] + [host.encode(sp(now + 5 + k, 0, (k, -k))) for k in range(6)])  # fmt: skip
    out = _same(fast, slow, chunk)
    # the buffer holds 8: the last two of the six find it full
    want = [(s0 + 2, ERR["bad_value"]), (s0 + 4, ERR["setpoint_late"]),
            (s0 + 6, ERR["bad_value"]), (s0 + 7, ERR["bad_joint"]),
            (s0 + 12, ERR["buffer_full"]), (s0 + 13, ERR["buffer_full"])]  # fmt: skip
    assert _naks(out) == want
    assert [e[0] for e in fast.buffer] == list(range(now + 1, now + 9))
    assert [e[2] for e in fast.buffer][:2] == [False, True]
    assert fast.buffer[3][3] == [100, -200]
    # a retry of the last frame, refused as the buffer was full: after four ticks (room
    # again, its tick still ahead) the same NAK again, nothing queued; of an accepted frame
    # (no answer to resend): handled again, so refused as not after the last
    _same(fast, slow, ticks=4)  # ticks 4..7 take four entries
    last = encode(sp(now + 10, 0, (5, -5)), s0 + 13)
    assert _naks(_same(fast, slow, last)) == [(s0 + 13, ERR["buffer_full"])]
    assert len(fast.buffer) == 4
    again = host.encode(sp(now + 30, 0, (2, 2)))
    assert _naks(_same(fast, slow, again)) == []
    assert _naks(_same(fast, slow, again)) == [(host.seq - 1, ERR["bad_value"])]
    _same(fast, slow, ticks=10)
    for fw in (fast, slow):  # an e-stop comes before the mode (a state ESTOP never leaves)
        fw.estop = True
    refused = host.encode(sp(fast.tick + 50, 0, (3, 3)))  # (after the buffered ones)
    assert _naks(_same(fast, slow, refused)) == [(host.seq - 1, ERR["estop_active"])]
    for fw in (fast, slow):
        fw.estop = False
    _same(fast, slow, host.encode(M["ESTOP"]()))
    refused = host.encode(sp(fast.tick + 50, 0, (3, 3)))  # (after the buffered ones)
    assert _naks(_same(fast, slow, refused)) == [(host.seq - 1, ERR["estop_active"])]
    _same(fast, slow, host.encode(M["CLEAR_ESTOP"]()), ticks=2)
    refused = host.encode(sp(fast.tick + 2, 0, (3, 3)))  # idle since the e-stop
    assert _naks(_same(fast, slow, refused)) == [(host.seq - 1, ERR["wrong_mode"])]


def _stream(host, rows, first, every=1, ff=False, hold_at=-1) -> bytes:
    """SETPOINT (SETPOINT_FF with ``ff``) frames for ticks first, first + every, ..."""
    frames = []
    for k, row in enumerate(rows):
        tick, flags = first + k * every, int(k == hold_at)
        if ff:
            frames.append(host.encode(M["SETPOINT_FF"](tick, flags, row, (400, -300))))
        else:
            frames.append(host.encode(M["SETPOINT"](tick, flags, row)))
    return b"".join(frames)


@pytest.mark.parametrize("runs", [False, True], ids=["advance", "advance_ticks"])
def test_the_c_tick_is_the_python_tick_through_every_mode_and_fault(runs):
    """Tick by tick (or run by run of advance_ticks) the same bytes and state: streamed
    setpoints with feedforward, a hold, underruns, saturation and the tilt's limit stop,
    decimated telemetry, a current beyond int16 mA, a count beyond the C tick's range (its
    Python path from the plant's read on), the watchdog's trip, voltage mode, an e-stop;
    the C tick took most ticks."""
    fast, slow = _pair(huge_at=(40,), amps_at=(30, 31))
    taken, tick_c, ticks_c = [], fast._tick_c, fast._ticks_c

    def counted(state, consts):
        got = tick_c(state, consts)
        taken.append("done" if got is True else "no" if got is None else "from the read")
        return got

    def counted_runs(state, consts, count):
        done, got = ticks_c(state, consts, count)
        taken.extend(["done"] * done)
        if done < count:
            taken.append("no" if got is None else "from the read")
        return done, got

    fast._tick_c, fast._ticks_c = counted, counted_runs
    host, seen = Encoder(), set()

    def same(data=None, ticks=0):
        return _same(fast, slow, data, ticks, seen, runs)

    same(host.encode(M["SET_MODE"](MODE["position"])), ticks=2)
    same(host.encode(M["START_STREAM"](2)))
    for block in range(12):  # 8 setpoints ahead, then 8 ticks; big steps saturate
        rows = [(3000 * ((block + k) % 3) - 2000, 6000 * (block % 2) - 2500) for k in range(8)]
        same(_stream(host, rows, fast.tick + 1, ff=block % 3 == 1, hold_at=5), ticks=8)
        if block == 4:  # gaps: every other tick has no setpoint (underrun flags)
            same(_stream(host, rows[:4], fast.tick + 1, every=2), ticks=9)
    for flag in ("watchdog_tripped", "estop"):  # their status bits in position mode
        for fw in (fast, slow):  # (states the protocol never leaves the emulator in)
            setattr(fw, flag, True)
        same(ticks=2)
        for fw in (fast, slow):
            setattr(fw, flag, False)
    same(ticks=30)  # host silence: the watchdog trips (250 ms: 17 ticks)
    assert fast.watchdog_tripped and fast.mode == MODE["idle"]
    same(host.encode(M["SET_MODE"](MODE["voltage"])), ticks=2)
    same(host.encode(M["SET_VOLTAGE"]((3000, -2000))), ticks=3)
    same(host.encode(M["SET_MODE"](MODE["position"])), ticks=1)
    same(_stream(host, [(500, 500)] * 6, fast.tick + 1), ticks=3)
    same(host.encode(M["ESTOP"]()), ticks=3)
    same(host.encode(M["CLEAR_ESTOP"]()), ticks=2)
    assert taken.count("done") > 0.7 * len(taken) and taken.count("from the read") == 1
    bits = 0
    for status in seen:
        bits |= status
    status_bits = ENUMS["status"]
    for name in ("saturated_j0", "saturated_j1", "limit_j1", "setpoint_underrun",
                 "watchdog_tripped", "estop"):  # fmt: skip
        assert bits & 1 << status_bits[name], name


class _OneAtATime:
    """The emulator without advance_ticks: the engine's tick by tick path."""

    def __init__(self, fw) -> None:
        self.fw, self.tick_period_s = fw, fw.tick_period_s
        self.receive, self.advance, self.take_output = fw.receive, fw.advance, fw.take_output


@pytest.mark.parametrize("deadline_ticks", [3.5, 4.0, 0.5, 40.0])
def test_run_ticks_runs_the_ticks_due_by_the_deadline_as_one_at_a_time(deadline_ticks):
    """LinkEngine.run_ticks through advance_ticks: the ticks due by the deadline (a tick
    at the deadline is due), the clock at the last one, the same bytes and state as tick by
    tick."""
    fast, slow = _pair()
    calls, ticks_c = [], fast._ticks_c
    fast._ticks_c = lambda *args: calls.append(args[2]) or ticks_c(*args)
    engines = [LinkEngine(d, FaultConfig(), 1) for d in (fast, _OneAtATime(slow))]
    host = Encoder()
    frames = host.encode(M["SET_MODE"](MODE["position"])) + host.encode(M["START_STREAM"](1))
    frames += _stream(host, [(100 * k, -80 * k) for k in range(8)], 1)
    ran = 1 + min(6, int(deadline_ticks))
    for engine in engines:
        engine.host_write(frames)
        engine.run_ticks(1, engine.tick_ns)  # (the first tick in position mode: Python's)
        engine.run_ticks(6, round(engine.now_ns + deadline_ticks * engine.tick_ns))
    assert [e.ticks for e in engines] == [ran, ran]
    assert [e.now_ns for e in engines] == [ran * engines[0].tick_ns] * 2
    assert engines[0].take() == engines[1].take()
    assert _state(fast) == _state(slow) and fast.tick == ran
    assert calls == [1] + ([ran - 1] if ran > 1 else [])  # (the first: 0 done, in Python)


def test_a_subclass_that_changes_what_the_c_paths_stand_for_keeps_its_python_paths():
    """A class attribute named as one the C tick writes (a property would not see it), an
    own advance (advance_ticks would skip it), an own SETPOINT handler: those C paths off."""
    guard = load_robot("guard")

    class Shadowing(FirmwareEmulator):
        status = property(lambda self: 0, lambda self, value: None)

    class OwnAdvance(FirmwareEmulator):
        def advance(self) -> None:
            super().advance()

    class OwnHandler(FirmwareEmulator):
        _HANDLERS = {**FirmwareEmulator._HANDLERS, "Setpoint": lambda self, frame: None}

    kinds = {}
    for cls in (FirmwareEmulator, Shadowing, OwnAdvance, OwnHandler):
        fw = cls(guard, WavyPlant())
        kinds[cls.__name__] = [x is not None for x in (fw._tick_c, fw._ticks_c, fw._setpoints_c)]
    assert kinds == {
        "FirmwareEmulator": [True, True, True],
        "Shadowing": [False, False, False],
        "OwnAdvance": [True, False, True],
        "OwnHandler": [True, True, False],
    }
