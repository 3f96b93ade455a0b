"""The firmware emulator's per-tick C fast path (gp_pyext ``pid_pwm`` and ``telemetry``)
gives what its Python path gives.

Truth: :class:`guardid.firmware.pid.FixedPid` ``step``, :func:`pwm_mv`, the limit stop as
the emulator's Python path writes it, and the Python codec's ``encode`` of the TELEMETRY
message with the values rounded and clamped by hand.
"""

from __future__ import annotations

import copy
import math
import os
import random
import struct

import pytest

from guardid import protocol as P
from guardid.firmware.emulator import LIMIT_BITS, SATURATED_BITS, pwm_mv
from guardid.firmware.pid import FixedPid
from guardid.native import find_compiler
from guardid.protocol import fastcodec
from guardid.protocol.codec import _fast_config

pytestmark = pytest.mark.skipif(
    find_compiler() is None or os.environ.get("GUARDID_NATIVE") == "0", reason="needs a C compiler"
)
TELEMETRY = P.MESSAGES["TELEMETRY"]


def _python_tick(pids, setpoint, counts, feedforward, drives):
    """(applied [mV], status) by FixedPid.step, the limit stop and pwm_mv."""
    applied, status = [], 0
    for j, pid in enumerate(pids):
        lim, levels, supply = drives[j]
        mv = pid.step(setpoint[j], counts[j], feedforward[j])
        status |= SATURATED_BITS[j] if pid.saturated else 0
        q = counts[j]
        if lim is not None and ((mv > 0 and q >= lim[1]) or (mv < 0 and q <= lim[0])):
            mv = 0
            status |= LIMIT_BITS[j]
        applied.append(pwm_mv(mv, levels, supply))
    return applied, status


def _pack(drives):
    return b"".join(
        struct.pack("=7q", lim is not None, *(lim or (0, 0)), lv, s, sat, stop)
        for (lim, lv, s), sat, stop in zip(drives, SATURATED_BITS, LIMIT_BITS, strict=False)
    )


def _random_pids(rng, n):
    pids = []
    for _ in range(n):
        pid = FixedPid(rng.choice([12000, 24000, 5000]))
        pid.set_gains(tuple(rng.randrange(0, 3 * 2**16) for _ in range(3)))
        pid.integral = rng.randrange(-(pid.limit_mv << 16), (pid.limit_mv << 16) + 1)
        pid.prev_error = rng.randrange(-5000, 5000)
        pids.append(pid)
    return pids


def test_pid_pwm_is_the_python_tick_on_random_states():
    """Saturation both ways, anti-windup, feedforward, the limit stop and the PWM duty:
    the same output (in mV and in V), status bits and PID state as the Python path, tick
    after tick."""
    fast, rng, seen = fastcodec.module().pid_pwm, random.Random(7), set()
    for _ in range(400):
        n = rng.randint(1, 4)
        pids = _random_pids(rng, n)
        twins = copy.deepcopy(pids)
        drives = [(rng.choice([None, (-3000, 2500)]), rng.choice([255, 1023]), p.limit_mv)
                  for p in pids]  # fmt: skip
        for _ in range(5):
            setpoint = [rng.randrange(-6000, 6000) for _ in range(n)]
            counts = [rng.choice([rng.randrange(-6000, 6000), -3000, 2500]) for _ in range(n)]
            feedforward = [rng.choice([0, rng.randrange(-5000, 5000)]) for _ in range(n)]
            want = _python_tick(twins, setpoint, counts, feedforward, drives)
            got = fast(pids, setpoint, counts, feedforward, _pack(drives))
            assert list(got) == [*want, [mv * 1e-3 for mv in want[0]]]
            for a, b in zip(pids, twins, strict=True):
                state = (a.integral, a.prev_error, a.saturated)
                assert state == (b.integral, b.prev_error, b.saturated)
            seen.add(want[1] & 0xFF)
    assert any(s & 0x0F for s in seen) and any(s & 0xF0 for s in seen)  # both kinds happened


@pytest.mark.parametrize(
    "change",
    [("kp", 2**31), ("integral", 2**45), ("prev_error", 2**40), ("counts", 2**30), ("ff", 0.5)],
)
def test_pid_pwm_leaves_values_out_of_its_exact_range_to_python(change):
    """A gain, state or input its int64 arithmetic is not exact for: None, nothing changed."""
    fast = fastcodec.module().pid_pwm
    pids = _random_pids(random.Random(1), 2)
    setpoint, counts, ff = [10, 20], [0, 0], [0, 0]
    what, value = change
    if what == "counts":
        counts[1] = value
    elif what == "ff":
        ff[0] = value
    else:
        setattr(pids[1], what, value)
    before = [(p.integral, p.prev_error, p.saturated) for p in pids]
    assert fast(pids, setpoint, counts, ff, _pack([(None, 255, 12000)] * 2)) is None
    assert [(p.integral, p.prev_error, p.saturated) for p in pids] == before


def test_telemetry_is_the_encoded_message_with_rounded_clamped_milli_units():
    """Rounding half up (x.xxx5 both signs), the int16 clamp both ends, numbering."""
    fast = fastcodec.module().telemetry
    cfg = _fast_config(TELEMETRY.SPEC, 2)
    volts, amps = [1.2345, -0.0005], [40.0, -33.5]
    got = fast(cfg, 65535, 2**32 - 1, 5, 1, [7, -8], volts, amps, [9, -10])
    milli = [math.floor(x * 1000.0 + 0.5) for x in volts + amps]
    assert milli[2] > 32767 and milli[3] < -32768
    want = TELEMETRY(2**32 - 1, 5, 1, (7, -8), tuple(milli[:2]), (32767, -32768), (9, -10))
    assert got == P.encode(want, 65535)
    bad = [([7, 2**31], volts), ([7, 8], [math.inf, 0.0]), ([7, 8], [1, 0.0])]
    for counts, v in bad:  # out of range, not finite, not a float: the Python path's call
        assert fast(cfg, 0, 1, 0, 1, counts, v, amps, [0, 0]) is None
