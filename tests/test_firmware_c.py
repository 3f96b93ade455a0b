"""The portable C firmware core (firmware_proto/core) against the Python emulator.

The core is built with the host C compiler (guardid.firmware.c_core) and driven in the
loop on the simulated plant; the module is skipped when no compiler exists. Every case
feeds the same host bytes to both firmwares and requires the same bytes back, the same
motor voltages and the same state, and checks the behaviour against the protocol README.
"""

from __future__ import annotations

import math
import os
import random
import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import serial
from test_firmware_emulator import SpeedPlant
from test_hil import N_TICKS, Recorder, run

from guardid.firmware import FirmwareEmulator, FixedPid, pid_gains_q16
from guardid.firmware.c_core import find_compiler
from guardid.firmware.emulator import pwm_mv
from guardid.link import Session, open_port
from guardid.plant import Plant
from guardid.protocol import ENUMS, MESSAGES, Encoder, FrameParser
from guardid.protocol.vectors import random_message
from guardid.robot import load_robot

if find_compiler() is None:
    pytest.skip("no C compiler (gcc/cc/clang) on PATH: C core not tested", allow_module_level=True)

from guardid.firmware.c_core import CFirmware, CPid, c_pid_gains_q16, c_pwm  # noqa: E402

FW = Path(__file__).resolve().parents[1] / "firmware_proto"
CFLAGS = ["-std=c99", "-Wall", "-Wextra", "-Werror", "-pedantic", "-O2"]
GUARD = load_robot("guard")
M = MESSAGES
ERR = ENUMS["error"]
STATUS = ENUMS["status"]
MODE = ENUMS["mode"]
FAULT = ENUMS["fault"]
HOLD = 1 << ENUMS["setpoint_flags"]["hold"]


# ---------------------------------------------------------------------- building
def test_core_builds_standalone_without_warnings_and_without_fpu(tmp_path):
    """The core + codec with a main and a stub HAL, as a firmware project builds them."""
    main = tmp_path / "main.c"
    main.write_text(
        '#include "guard_fw.h"\n'
        "static int32_t rc(void *c, uint8_t j) { (void)c; return (int32_t)j; }\n"
        "static void ra(void *c, uint8_t j, int32_t *v, int32_t *i) "
        "{ (void)c; *v = j; *i = -(int32_t)j; }\n"
        "static void so(void *c, uint8_t j, int32_t mv, uint16_t d) "
        "{ (void)c; (void)j; (void)mv; (void)d; }\n"
        "static void uw(void *c, const uint8_t *d, size_t n) { (void)c; (void)d; (void)n; }\n"
        "int main(void) {\n"
        "  static gf_fw_t fw; gf_config_t cfg = {0}; gf_hal_t hal = {0, rc, ra, so, uw};\n"
        "  cfg.n_joints = 1; cfg.tick_us = 15000; cfg.joint[0].counts_per_rev = 24000;\n"
        "  cfg.joint[0].supply_mv = 12000; cfg.joint[0].pwm_bits = 8;\n"
        "  if (gf_init(&fw, &cfg, &hal) != GF_OK) return 1;\n"
        "  gf_receive_byte(&fw, 0); gf_tick(&fw); gf_estop(&fw); return gf_wants_time(&fw);\n"
        "}\n"
    )
    cc = find_compiler()
    srcs = [str(FW / "guard_proto.c"), str(FW / "core" / "guard_fw.c"), str(main)]
    extra = []
    # -mgeneral-regs-only: any floating point in the core is a compile error (no FPU)
    probe = subprocess.run([cc, "-mgeneral-regs-only", "-x", "c", "-c", "-o", os.devnull, "-"],
                           input="int x;\n", capture_output=True, text=True)  # fmt: skip
    if probe.returncode == 0:
        extra = ["-mgeneral-regs-only"]
    cmd = [cc, *CFLAGS, *extra, f"-I{FW}", f"-I{FW / 'core'}", *srcs, "-o", str(tmp_path / "a")]
    res = subprocess.run(cmd, capture_output=True, text=True)
    assert res.returncode == 0 and res.stderr == "", res.stderr
    assert subprocess.run([str(tmp_path / "a")]).returncode == 0
    for name in ("guard_fw.c", "guard_fw.h"):
        text = (FW / "core" / name).read_text()
        assert not re.search(r"\b(float|double)\b|\b(malloc|calloc|realloc)\s*\(", text), name


# ---------------------------------------------------------------------- arithmetic
def _extreme(rng: random.Random, lo: int, hi: int) -> int:
    r = rng.random()
    if r < 0.1:
        return lo
    if r < 0.2:
        return hi
    if r < 0.5:  # small magnitudes, as in service
        return rng.randint(max(lo, -1000), min(hi, 1000))
    return rng.randint(lo, hi)


def test_q16_gains_equal_the_python_ones():
    rng = random.Random(7)
    cases = [(40_000_000, 10_000_000, 1_000_000, 24000, 15000)]
    cases += [(-(2**31), 2**31 - 1, -(2**31), 1, 1), (2**31 - 1, -(2**31), 2**31 - 1, 1, 2**32 - 1)]
    cases += [(2**31 - 1, 2**31 - 1, 2**31 - 1, 2**32 - 1, 1)]
    for _ in range(3000):
        g = [_extreme(rng, -(2**31), 2**31 - 1) for _ in range(3)]
        cpr = rng.choice([1, 48, 24000, 48000, rng.randint(1, 2**32 - 1), 2**32 - 1])
        tick = rng.choice([1, 1000, 15000, rng.randint(1, 2**32 - 1), 2**32 - 1])
        cases.append((*g, cpr, tick))
    for case in cases:
        assert c_pid_gains_q16(*case) == pid_gains_q16(*case), case


def test_pid_step_equals_fixed_pid_bit_for_bit():
    rng = random.Random(11)
    for trial in range(300):
        limit = rng.choice([12000, 1, 32767, rng.randint(1, 32767)])
        big = trial % 3 == 0  # huge gains / errors: the 128-bit path
        if big:
            gains = [_extreme(rng, -(2**60), 2**60) for _ in range(3)]
        else:
            gains = list(pid_gains_q16(*(_extreme(rng, -(2**31), 2**31 - 1) for _ in range(3)),
                                       rng.choice([24000, 48000, 48]), 15000))  # fmt: skip
        py, c = FixedPid(limit), CPid(limit)
        py.set_gains(gains)
        c.set_gains(gains)
        for _ in range(60):
            if rng.random() < 0.2:
                sp, pos = _extreme(rng, -(2**31), 2**31 - 1), _extreme(rng, -(2**31), 2**31 - 1)
            else:
                sp, pos = rng.randint(-3000, 3000), rng.randint(-3000, 3000)
            ff = rng.choice([0, rng.randint(-limit, limit), _extreme(rng, -32767, 32767)])
            assert c.step(sp, pos, ff) == py.step(sp, pos, ff), (gains, limit, sp, pos, ff)
            assert (c.integral, c.saturated) == (py.integral, py.saturated)


def test_pwm_quantisation_equals_the_emulator():
    for bits, supply in ((8, 12000), (10, 12000), (1, 5000), (16, 32767), (8, 1)):
        step = max(1, supply // 3000)
        for mv in range(-supply, supply + 1, step):
            assert c_pwm(mv, supply, bits) == pwm_mv(mv, (1 << bits) - 1, supply), (bits, mv)


# ---------------------------------------------------------------------- closed loop
def _run_bytes(url: str, n: int = N_TICKS) -> tuple[bytes, dict]:
    port = Recorder(open_port(url))
    try:
        rows, session = run(port, n)
    finally:
        port.close()
    assert session.stats.errors == 0 and session.stats.seq_gaps == 0
    return bytes(port.received), rows


def test_60s_closed_loop_is_byte_identical_to_the_emulator():
    py, rows = _run_bytes("sim://guard?seed=1")
    c, _ = _run_bytes("sim://guard?seed=1&firmware=c")
    assert sorted(rows) == list(range(N_TICKS))
    assert len(c) == len(py) and c == py


# ---------------------------------------------------------------------- state machine
class Twin:
    """The emulator and the C core side by side, each on its own copy of the plant."""

    def __init__(self, make_plant) -> None:
        self.py = FirmwareEmulator(GUARD, make_plant())
        self.c = CFirmware(GUARD, make_plant())
        self.encoder = Encoder()
        self.parser = FrameParser()
        self.frames: list = []

    def send(self, msg, seq: int | None = None) -> list:
        """Send a message (or raw bytes) to both; return the decoded replies."""
        if isinstance(msg, bytes | bytearray):
            data = bytes(msg)
        else:
            data = self.encoder.encode(msg)
        self.py.receive(data)
        self.c.receive(data)
        return self._compare()

    def step(self, n: int = 1) -> list:
        """Advance both n ticks; return the decoded output."""
        out = []
        for _ in range(n):
            assert self.c.applied_mv == self.py.applied_mv
            self.py.advance()
            self.c.advance()
            out += self._compare()
        return out

    def set_tick(self, tick: int) -> None:
        self.py.tick = self.py.last_host_tick = tick
        self.c.set_tick(tick)

    def _compare(self) -> list:
        a, b = self.py.take_output(), self.c.take_output()
        assert b == a
        st = self.c.state()
        py = self.py
        assert (st["tick"], st["mode"], st["status"], st["streaming"]) == (
            py.tick, py.mode, py.status, int(py.streaming))  # fmt: skip
        assert (st["estop"], st["watchdog_tripped"], st["queued"], st["watchdog_ms"]) == (
            int(py.estop), int(py.watchdog_tripped), len(py.buffer), py.watchdog_ms)  # fmt: skip
        assert bool(st["wants_time"]) == py.wants_time()
        assert self.c.applied_mv == py.applied_mv
        frames = [f.msg for f in self.parser.feed(a)]
        self.frames += frames
        return frames


def real_plant(seed: int = 3):
    return lambda: Plant(GUARD, seed=seed)


def speed_plant():
    return SpeedPlant(GUARD.n_dof)


def _naks(frames):
    return [f.error for f in frames if type(f) is M["NAK"]]


def _acks(frames):
    return [f.ack_id for f in frames if type(f) is M["ACK"]]


def _telemetry(frames):
    return [f for f in frames if type(f) is M["TELEMETRY"]]


def test_watchdog_trip_keepalive_and_clear_are_equal():
    t = Twin(real_plant())
    assert type(t.send(M["HELLO"]())[0]) is M["INFO"]
    t.send(M["SET_MODE"](MODE["voltage"]))
    t.send(M["START_STREAM"](1))
    t.send(M["SET_VOLTAGE"]((6000, -3000)))
    out = t.step(20)
    faults = [f for f in out if type(f) is M["FAULT"]]
    assert [f.code for f in faults] == [FAULT["watchdog"]]
    assert faults[0].tick == 17 and faults[0].detail == 255  # 17 ticks x 15 ms >= 250 ms
    assert t.py.applied_mv == [0, 0] and t.py.mode == MODE["idle"]
    assert all(x.status & (1 << STATUS["watchdog_tripped"]) for x in _telemetry(out)[16:])
    assert _naks(t.send(M["SET_WATCHDOG"](0))) == [ERR["bad_value"]]
    assert _acks(t.send(M["SET_WATCHDOG"](45))) == [M["SET_WATCHDOG"].MSG_ID]
    t.send(M["SET_MODE"](MODE["voltage"]))  # clears the latched bit
    assert not t.py.watchdog_tripped
    out = t.step(4)
    assert [f.code for f in out if type(f) is M["FAULT"]] == [FAULT["watchdog"]]
    # position mode kept alive by PING only
    t.send(M["SET_WATCHDOG"](250))
    t.send(M["SET_MODE"](MODE["position"]))
    for _ in range(8):
        t.step(10)
        t.send(M["PING"](99))
    assert t.py.mode == MODE["position"]
    t.step(17)
    assert t.py.mode == MODE["idle"] and t.py.watchdog_tripped
    t.send(M["CLEAR_ESTOP"]())
    assert not t.py.watchdog_tripped
    t.step(3)


def test_estop_is_equal_and_refuses_every_moving_command():
    t = Twin(real_plant())
    t.send(M["SET_MODE"](MODE["position"]))
    t.send(M["START_STREAM"](1))
    now = t.py.tick
    for k in range(1, 6):
        t.send(M["SETPOINT"](now + k, 0, (2000 * k, 500 * k)))
    t.step(4)
    assert t.py.applied_mv != [0, 0]
    out = t.send(M["ESTOP"]())
    assert [type(f) for f in out] == [M["ACK"], M["FAULT"]] and out[1].code == FAULT["estop"]
    assert t.py.applied_mv == [0, 0]  # at once, not at the next tick
    moving = [
        M["SET_MODE"](MODE["position"]),
        M["SET_MODE"](MODE["voltage"]),
        M["SETPOINT"](t.py.tick + 2, 0, (0, 0)),
        M["SET_VOLTAGE"]((1000, 1000)),
    ]
    for msg in moving:
        assert _naks(t.send(msg)) == [ERR["estop_active"]]
    for msg in (M["SET_MODE"](MODE["idle"]), M["SET_PID"](1, 1, 2, 3), M["STOP_STREAM"](),
                M["START_STREAM"](2), M["ESTOP"]()):  # fmt: skip
        assert _acks(t.send(msg)) == [msg.MSG_ID]
    assert type(t.send(M["PING"](5))[0]) is M["PONG"]
    out = t.step(4)
    assert all(x.status & (1 << STATUS["estop"]) for x in _telemetry(out))
    t.send(M["CLEAR_ESTOP"]())
    assert t.py.mode == MODE["idle"] and not t.py.estop
    assert _acks(t.send(M["SET_MODE"](MODE["position"]))) == [M["SET_MODE"].MSG_ID]
    t.step(3)


def test_hardware_estop_input_latches_like_the_frame():
    c = CFirmware(GUARD, Plant(GUARD, seed=2))
    enc = Encoder()
    c.receive(enc.encode(M["SET_MODE"](MODE["voltage"])))
    c.receive(enc.encode(M["SET_VOLTAGE"]((5000, 5000))))
    c.advance()
    assert c.applied_mv != [0, 0]
    c.take_output()
    c.estop_input()
    frames = [f.msg for f in FrameParser().feed(c.take_output())]
    assert [type(f) for f in frames] == [M["FAULT"]] and frames[0].code == FAULT["estop"]
    assert c.applied_mv == [0, 0] and c.state()["estop"] == 1 and c.state()["mode"] == 0


def test_setpoint_buffer_late_full_order_hold_and_underrun_are_equal():
    t = Twin(real_plant(4))
    assert _naks(t.send(M["SETPOINT"](5, 0, (0, 0)))) == [ERR["wrong_mode"]]
    t.send(M["SET_MODE"](MODE["voltage"]))
    assert _naks(t.send(M["SETPOINT"](5, 0, (0, 0)))) == [ERR["wrong_mode"]]
    t.send(M["SET_MODE"](MODE["position"]))
    t.send(M["START_STREAM"](1))
    t.step(3)
    now = t.py.tick
    assert _naks(t.send(M["SETPOINT"](now, 0, (0, 0)))) == [ERR["setpoint_late"]]
    assert _naks(t.send(M["SETPOINT"](now - 3, 0, (0, 0)))) == [ERR["setpoint_late"]]
    assert _naks(t.send(M["SETPOINT"](now + 2, 0, (10, 10)))) == []
    assert _naks(t.send(M["SETPOINT"](now + 2, 0, (10, 10)))) == [ERR["bad_value"]]
    assert _naks(t.send(M["SETPOINT"](now + 1, 0, (10, 10)))) == [ERR["bad_value"]]
    assert _naks(t.send(M["SETPOINT"](now + 3, 0, (10,)))) == [ERR["bad_joint"]]
    for k in range(3, 10):
        assert _naks(t.send(M["SETPOINT"](now + k, 0, (100 * k, -40 * k)))) == []
    assert _naks(t.send(M["SETPOINT"](now + 10, 0, (0, 0)))) == [ERR["buffer_full"]]
    out = _telemetry(t.step(14))
    under = [bool(x.status & (1 << STATUS["setpoint_underrun"])) for x in out]
    # now+1: nothing due, but no stream has started yet (entering position mode holds);
    # now+2 .. now+9 applied; then the stream ran dry
    assert under == [False] * 9 + [True] * 5
    assert out[8].setpoint == (900, -360) and out[-1].setpoint == (900, -360)
    now = t.py.tick
    t.send(M["SETPOINT"](now + 1, 0, (50, 50)))
    t.send(M["SETPOINT"](now + 2, HOLD, (60, 60)))  # parking: no underrun after it
    out = _telemetry(t.step(8))
    assert not any(x.status & (1 << STATUS["setpoint_underrun"]) for x in out)
    assert out[-1].setpoint == (60, 60)
    # re-entering position mode changes nothing; idle -> position: setpoint = position
    t.send(M["SET_MODE"](MODE["position"]))
    assert _telemetry(t.step(1))[-1].setpoint == (60, 60)
    t.send(M["SET_MODE"](MODE["idle"]))
    last = _telemetry(t.step(1))[-1]
    t.send(M["SET_MODE"](MODE["position"]))
    assert _telemetry(t.step(1))[-1].setpoint == last.position


def test_setpoint_ff_is_added_before_the_limits_alike_and_reset_by_setpoint():
    """SETPOINT_FF: with zero gains the output is the feedforward alone, PWM-quantised
    (8 bits of 12 V: 1500 mV -> duty round(1500 * 255 / 12000) = 32 -> 1506 mV), clamped
    by nothing but the supply; the NAKs of SETPOINT plus bad_value beyond the supply; a
    plain SETPOINT puts it back to 0; with gains it adds to the PID alike in C and Python."""
    t = Twin(real_plant(8))
    for j in range(2):
        t.send(M["SET_PID"](j, 0, 0, 0))
    assert _naks(t.send(M["SETPOINT_FF"](5, 0, (0, 0), (0, 0)))) == [ERR["wrong_mode"]]
    t.send(M["SET_MODE"](MODE["position"]))
    t.send(M["START_STREAM"](1))
    t.step(2)
    now = t.py.tick
    assert _naks(t.send(M["SETPOINT_FF"](now + 1, 0, (0, 0), (1500, -700)))) == []
    assert _naks(t.send(M["SETPOINT_FF"](now + 2, 0, (0, 0), (12001, 0)))) == [ERR["bad_value"]]
    assert _naks(t.send(M["SETPOINT_FF"](now + 2, 0, (0, 0), (0, -12001)))) == [ERR["bad_value"]]
    assert _naks(t.send(M["SETPOINT_FF"](now + 2, 0, (0,), (0,)))) == [ERR["bad_joint"]]
    assert _naks(t.send(M["SETPOINT_FF"](now, 0, (0, 0), (0, 0)))) == [ERR["setpoint_late"]]
    assert _naks(t.send(M["SETPOINT_FF"](now + 2, 0, (0, 0), (-12000, 12000)))) == []
    assert _naks(t.send(M["SETPOINT"](now + 3, HOLD, (0, 0)))) == []
    t.step(1)
    assert t.py.applied_mv == [1506, -706]  # duty 32 and 15 of 255 (worked above)
    t.step(1)
    assert t.py.applied_mv == [-12000, 12000]  # the supply itself, not past it
    t.step(1)
    assert t.py.applied_mv == [0, 0]  # SETPOINT: feedforward back to 0
    # with the guard's gains: PID + feedforward, equal in both, across many ticks
    for j, joint in enumerate(GUARD.joints):
        t.send(M["SET_PID"](j, *(round(g * 1e6) for g in (joint.pid.kp, joint.pid.ki,
                                                           joint.pid.kd))))  # fmt: skip
    now = t.py.tick
    for k in range(1, 8):
        t.send(M["SETPOINT_FF"](now + k, 0, (40 * k, -20 * k), (300 * k, -150 * k)))
    seen = {tuple(t.py.applied_mv) for _ in range(10) if t.step(1)}
    assert len(seen) > 5


def test_voltage_mode_and_mode_changes_are_equal():
    t = Twin(real_plant(5))
    t.send(M["START_STREAM"](2))
    assert _naks(t.send(M["SET_VOLTAGE"]((1000, 1000)))) == [ERR["wrong_mode"]]
    t.send(M["SET_MODE"](MODE["position"]))
    assert _naks(t.send(M["SET_VOLTAGE"]((1000, 1000)))) == [ERR["wrong_mode"]]
    t.send(M["SET_MODE"](MODE["voltage"]))
    assert _naks(t.send(M["SET_VOLTAGE"]((12001, 0)))) == [ERR["bad_value"]]
    assert _naks(t.send(M["SET_VOLTAGE"]((0, -12001)))) == [ERR["bad_value"]]
    assert _naks(t.send(M["SET_VOLTAGE"]((1, 2, 3)))) == [ERR["bad_joint"]]
    assert t.send(M["SET_VOLTAGE"]((-12000, 7777))) == []  # not acknowledged
    assert t.py.applied_mv == [0, 0]  # applies at the next tick
    t.step(1)
    assert t.py.applied_mv == [-12000, 7765]  # PWM-quantised (8-bit duty of 12 V)
    # README: SET_MODE voltage in voltage mode is "ACK (no change)"
    assert _acks(t.send(M["SET_MODE"](MODE["voltage"]))) == [M["SET_MODE"].MSG_ID]
    t.step(1)
    assert t.py.applied_mv == [-12000, 7765]
    t.send(M["SET_MODE"](MODE["position"]))  # position from voltage: as from idle
    t.step(3)
    t.send(M["SET_MODE"](MODE["voltage"]))  # voltage from position: at 0 V
    t.step(1)
    assert t.py.applied_mv == [0, 0]
    t.send(M["SET_VOLTAGE"]((3000, 3000)))
    t.step(2)
    t.send(M["SET_MODE"](MODE["idle"]))
    assert t.py.applied_mv == [0, 0]  # idle: 0 V at once
    t.step(5)


def test_joint_limits_are_equal():
    t = Twin(speed_plant)
    lo, hi = t.py.limits[1]
    for dev in (t.py, t.c):
        dev.plant.pos[1] = hi + 5.0
    t.send(M["SET_MODE"](MODE["voltage"]))
    t.send(M["START_STREAM"](1))
    t.send(M["SET_VOLTAGE"]((2000, 5000)))
    out = _telemetry(t.step(2))
    assert out[-1].status & (1 << STATUS["limit_j1"]) and t.py.applied_mv[1] == 0
    assert t.py.applied_mv[0] != 0  # joint 0 has no limits
    t.send(M["SET_VOLTAGE"]((0, -1000)))  # away from the limit is allowed
    out = _telemetry(t.step(4))
    assert t.py.applied_mv[1] < 0
    for dev in (t.py, t.c):
        dev.plant.pos[1] = lo - 5.0
    t.send(M["SET_MODE"](MODE["position"]))
    now = t.py.tick
    t.send(M["SETPOINT"](now + 1, HOLD, (0, lo - 500)))  # PID pulls further down: blocked
    out = _telemetry(t.step(3))
    assert out[-1].status & (1 << STATUS["limit_j1"]) and t.py.applied_mv[1] == 0


def test_nak_codes_and_replies_are_equal():
    t = Twin(real_plant(6))
    assert _naks(t.send(M["SET_MODE"](3))) == [ERR["bad_value"]]
    assert _naks(t.send(M["SET_PID"](2, 1, 1, 1))) == [ERR["bad_joint"]]
    assert _naks(t.send(M["START_STREAM"](0))) == [ERR["bad_value"]]
    assert _naks(t.send(M["SET_WATCHDOG"](0))) == [ERR["bad_value"]]
    t.send(M["SET_WATCHDOG"](100))
    info = t.send(M["HELLO"]())[0]
    assert info.watchdog_timeout == 100 and info.setpoint_depth == 8
    assert (
        info.counts_per_rev == (24000, 48000) and info.capabilities == 0x3F
    )  # bits 0..5, feedforward included
    t.send(M["SET_PID"](0, 80_000_000, 0, 2_000_000))
    t.send(M["START_STREAM"](3))
    assert [x.tick for x in _telemetry(t.step(10))] == [3, 6, 9]
    t.send(M["STOP_STREAM"]())
    assert _telemetry(t.step(4)) == []
    pong = t.send(M["PING"](0xDEADBEEF))[0]
    assert (pong.nonce, pong.tick) == (0xDEADBEEF, 14)


def test_damaged_and_split_frames_are_handled_alike():
    t = Twin(real_plant(8))
    good = Encoder(5).encode(M["SET_MODE"](MODE["voltage"]))
    bad = bytearray(good)
    bad[3] ^= 0x10  # CRC mismatch: dropped, no reply
    assert t.send(bytes(bad)) == []
    assert t.send(b"\x01\x02garbage\x00\x00" + bytes(range(1, 120)) + b"\x00") == []
    frame = Encoder(6).encode(M["SET_MODE"](MODE["voltage"]))
    for i in range(len(frame) - 1):  # one byte at a time
        assert t.send(frame[i : i + 1]) == []
    assert _acks(t.send(frame[-1:])) == [M["SET_MODE"].MSG_ID]
    t.send(Encoder(7).encode(M["TELEMETRY"](1, 0, 0, (0,), (0,), (0,), (0,))))  # MCU id: no reply
    assert t.c.state()["rx_errors"] >= 3 and t.c.state()["rx_frames"] == 2
    t.step(3)


def test_repeated_frames_are_answered_again_and_not_applied_alike():
    """A retry (the same frame again) gets the same ACK/NAK and changes nothing; the same
    seq with other content is a new command (tests/test_link_retry.py: the rule itself)."""
    t = Twin(real_plant(10))
    enc = Encoder(40)
    go = enc.encode(M["SET_MODE"](MODE["position"]))
    assert _acks(t.send(go)) == _acks(t.send(go)) == [M["SET_MODE"].MSG_ID]
    t.step(17)  # silent: the watchdog trips
    assert _acks(t.send(go)) == [M["SET_MODE"].MSG_ID]
    assert t.py.mode == MODE["idle"] and t.py.watchdog_tripped  # the repeat changed nothing
    bad = enc.encode(M["SET_PID"](5, 1, 1, 1))
    assert _naks(t.send(bad)) == _naks(t.send(bad)) == [ERR["bad_joint"]]
    stop = enc.encode(M["ESTOP"]())
    assert [type(f) for f in t.send(stop)] == [M["ACK"], M["FAULT"]]
    assert [type(f) for f in t.send(stop)] == [M["ACK"]]
    t.send(Encoder(50).encode(M["CLEAR_ESTOP"]()))
    assert not t.py.estop
    t.send(Encoder(50).encode(M["SET_MODE"](MODE["voltage"])))  # same seq, other content
    assert t.py.mode == MODE["voltage"]
    t.send(Encoder(50).encode(M["SET_MODE"](MODE["idle"])))  # same seq and id, other mode
    assert t.py.mode == MODE["idle"]
    ping = enc.encode(M["PING"](3))
    assert [f.tick for f in t.send(ping) + t.step(1) + t.send(ping) if type(f) is M["PONG"]] == [
        17,
        18,
    ]


def test_serial_tick_arithmetic_across_the_u32_wrap():
    t = Twin(real_plant(9))
    t.set_tick(2**32 - 6)
    t.send(M["SET_MODE"](MODE["position"]))
    t.send(M["START_STREAM"](1))
    for k in range(1, 9):
        t.send(M["SETPOINT"]((2**32 - 6 + k) & 0xFFFFFFFF, 0, (10 * k, 10 * k)))
    assert _naks(t.send(M["SETPOINT"](2**32 - 7, 0, (0, 0)))) == [ERR["setpoint_late"]]
    out = _telemetry(t.step(8))
    assert [x.tick for x in out] == [2**32 - 5, 2**32 - 4, 2**32 - 3, 2**32 - 2, 2**32 - 1, 0, 1, 2]
    assert not any(x.status & (1 << STATUS["setpoint_underrun"]) for x in out)
    assert [x.setpoint[0] for x in out] == [10 * k for k in range(1, 9)]
    assert _naks(t.send(M["SETPOINT"](2**32 - 1, 0, (0, 0)))) == [ERR["setpoint_late"]]
    t.step(20)  # watchdog across the wrap
    assert t.py.watchdog_tripped


def test_random_command_streams_are_equal():
    """Seeded random host traffic (all message kinds, extremes included) on the real plant."""
    rng = random.Random(2026)
    for trial in range(8):
        t = Twin(real_plant(20 + trial))
        t.send(M["START_STREAM"](1))
        for _ in range(800):
            r = rng.random()
            now = t.py.tick
            if r < 0.3:
                t.step(rng.randint(1, 3))
            elif r < 0.55:
                flags = HOLD if rng.random() < 0.2 else 0
                target = tuple(rng.randint(-3000, 3000) for _ in range(2))
                t.send(M["SETPOINT"]((now + rng.randint(-2, 10)) & 0xFFFFFFFF, flags, target))
            elif r < 0.65:
                t.send(M["SET_MODE"](rng.choice([0, 1, 1, 2, 2, 3])))
            elif r < 0.72:
                t.send(M["SET_VOLTAGE"](tuple(rng.randint(-13000, 13000) for _ in range(2))))
            elif r < 0.75:
                t.send(M["CLEAR_ESTOP"]())
            else:
                name = rng.choice(["SET_PID", "SET_WATCHDOG", "PING", "HELLO", "START_STREAM",
                                   "ESTOP", "SETPOINT", "SET_VOLTAGE", "STOP_STREAM"])  # fmt: skip
                n = 2 if rng.random() < 0.8 else rng.randint(1, 4)
                msg = random_message(rng, name, n)
                if name == "SET_PID" and rng.random() < 0.7:
                    msg = msg._replace(joint=rng.randint(0, 2))
                if name == "SET_WATCHDOG":
                    msg = msg._replace(timeout=rng.choice([0, 15, 30, 250, msg.timeout]))
                t.send(msg)
        assert len(t.frames) > 100


# ---------------------------------------------------------------------- capture/identify
class Sines:
    """q_j(t) = c_j + sums of sines with a ramp: enough excitation for a fit."""

    period = 20.0

    def positions(self, t):
        t = np.asarray(t, dtype=float)
        ramp = np.minimum(t / 2.0, 1.0)
        w = 2 * np.pi * np.array([0.1, 0.25, 0.4])
        q1 = ramp * (0.6 * np.sin(w[0] * t) + 0.25 * np.sin(w[1] * t) + 0.1 * np.sin(w[2] * t))
        q2 = 0.2 + ramp * (0.15 * np.sin(w[1] * t + 1) + 0.06 * np.sin(w[2] * t + 2))
        return np.column_stack([q1, q2])

    def to_dict(self):
        return {"kind": "test-sines"}


def _capture_and_identify(tmp_path, firmware: str):
    from guardid.capture import capture
    from guardid.identify import IdentifyOptions, identify
    from guardid.identify.runs import load_run

    port = open_port(f"sim://guard?seed=12&firmware={firmware}")
    try:
        session = Session(port)
        session.handshake()
        log = tmp_path / f"run_{firmware}.csv"
        result = capture(session, GUARD, Sines(), 40.0, log, {"robot": "guard"})
    finally:
        port.close()
    assert result.ended == "complete"
    r = load_run(log)
    ident = identify([r], GUARD, IdentifyOptions(methods=("ls", "wls", "rls")))
    return r, ident


def test_capture_and_identification_through_the_c_core_equal_the_emulator(tmp_path):
    run_py, id_py = _capture_and_identify(tmp_path, "py")
    run_c, id_c = _capture_and_identify(tmp_path, "c")
    for name in ("ticks", "t", "q", "current", "voltage"):
        assert np.array_equal(getattr(run_py, name), getattr(run_c, name)), name
    assert id_py.names == id_c.names and set(id_py.results) == set(id_c.results)
    for method, res in id_py.results.items():
        assert np.array_equal(res.theta, id_c.results[method].theta), method
    assert np.all(np.isfinite(id_py.results["ls"].theta))
    for a, b in zip(id_py.motors, id_c.motors, strict=True):
        assert a == b


# ---------------------------------------------------------------------- fake-port CLI
def test_fake_port_cli_serves_the_c_core():
    env = dict(os.environ)
    env.pop("GUARDID_FAKEPORT_DEVICE", None)
    # generous lock-step windows: a host descheduled (load beside the test) for under 50 ms
    # between its start-up commands cannot make the server step (and the watchdog trip)
    cmd = [sys.executable, "-m", "guardid", "fake-port", "--seed", "1", "--firmware", "c",
           "--settle-ms", "50", "--idle-ms", "100"]  # fmt: skip
    proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            env=env)  # fmt: skip
    try:
        path = proc.stdout.readline().strip()
        assert path.startswith("/dev/"), proc.stderr.read()
        port = serial.Serial(path, 115200, timeout=2.0)
        try:
            session = Session(port, timeout_s=60.0)  # a bound, ended by the answer
            info = session.handshake()
            session.set_mode("voltage")
            session.start_stream()
            session.send_voltage([3.0, 0.0])
            rows = [session.next_telemetry() for _ in range(5)]
            session.finish()
        finally:
            port.close()
    finally:
        proc.terminate()
        proc.wait(timeout=60)
    assert info["counts_per_rev"] == (24000, 48000)
    assert all(r.mode == MODE["voltage"] for r in rows)
    assert math.isclose(rows[-1].voltage_mv[0], 3000, abs_tol=300)
