"""The bench moves of ``guardid doctor``, over a handshaken :class:`guardid.link.Session`.

In order: the joints at rest (motors idle: the current sensors' zero), PINGs (the link),
the e-stop (latched, refusing moves, released), the watchdog (voltage mode at 0 V, then
host silence), then per joint a voltage pulse each way (voltage mode, the other joint at
0 V): ``PULSE_FRACTION`` of the supply for ``PULSE_TICKS`` ticks, 0 V for as long, the
same reversed, 0 V. Before a joint moves its pulse is checked against its position limits:
the farthest it can go is the motor's no-load speed at that voltage (V / Ke) over the
pulse, and that must fit between where it rests and its limit; while it moves, counts
outside that window, or a FAULT from the robot, put the motors idle at once and end the
moves. Whatever ends the run, the robot is left idle with its stream stopped.
"""

from __future__ import annotations

import math

import numpy as np

from guardid.doctor.checks import (
    FAIL,
    OK,
    UNKNOWN,
    Check,
    JointPulses,
    JointYaml,
    current_offset,
    link_check,
    motion_checks,
    supply_check,
)
from guardid.errors import LinkError
from guardid.protocol import ENUMS

STATUS = ENUMS["status"]
WATCHDOG_BIT = 1 << STATUS["watchdog_tripped"]
ESTOP_BIT = 1 << STATUS["estop"]
LIMIT_BITS = [1 << v for k, v in sorted(STATUS.items()) if k.startswith("limit_j")]

PULSE_FRACTION = 0.5  #: pulse voltage as a share of the supply [-] (lifts the guard's tilt)
PULSE_TICKS = 20  #: ticks of each pulse and each pause after it
STILL_TICKS = 10  #: counts unchanged this many ticks: the joints are at rest
FIRST_REST_TICKS = 100
"""Ticks in idle before the current sensors' zero is read (1.5 s on the guard): an arm
sinks onto its stop, which an encoder that counts nothing would not show."""
SETTLE_LIMIT_TICKS = 300  #: give up waiting for rest after this many ticks
REST_TICKS = 30  #: rows averaged for the current sensors' zero
PINGS = 20
WATCHDOG_TEST_S = 0.1  #: the watchdog timeout set for its test [s]
WATCHDOG_RUN_S = 0.25  #: the watchdog timeout while the pulses run [s]
STUCK_RAD = 0.005  #: a joint whose counts moved less than this [rad] did not move
LIMIT_MARGIN_RAD = 0.02  #: room kept from a position limit [rad]
WINDOW_FACTOR = 4.0  #: a joint going beyond this many times its bound is stopped


class MovesStopped(Exception):
    """The moves were ended early (the robot is idle); ``check`` says why."""

    def __init__(self, check: Check) -> None:
        super().__init__(check.measured)
        self.check = check


def joint_facts(description) -> list[JointYaml]:
    """The YAML's facts per joint (joint-side Ke = motor Ke x gear ratio)."""
    out = []
    for j in description.joints:
        d = j.drive
        out.append(JointYaml(
            name=j.name,
            counts_per_rad=j.counts_per_rad,
            ke=d.ke * d.gear_ratio, r=d.resistance, supply_v=d.supply_voltage,
            current_range_a=j.current_sensor.range, counts_per_rev=j.encoder.counts_per_rev,
        ))  # fmt: skip
    return out


def _clock(session) -> float:
    """Simulated time on a lock-step sim:// port, else the wall clock [s]."""
    return session._clock()


def _rows(session, n: int) -> list:
    return [session.next_telemetry() for _ in range(n)]


def settle(session, min_ticks: int = 1, keepalive=None) -> list:
    """Telemetry until every joint's counts stood still for STILL_TICKS ticks, at least
    ``min_ticks`` rows and at most SETTLE_LIMIT_TICKS; returns the rows read.
    ``keepalive`` (if given) is called before every read (0 V in voltage mode: the
    watchdog must not trip while the joints come to rest)."""
    rows, still = [session.next_telemetry()], 0
    while (still < STILL_TICKS or len(rows) < min_ticks) and len(rows) < SETTLE_LIMIT_TICKS:
        if keepalive is not None:
            keepalive()
        rows.append(session.next_telemetry())
        still = still + 1 if rows[-1].counts == rows[-2].counts else 0
    return rows


def estop_check(session) -> Check:
    """ESTOP latches (status bit, moves refused) and CLEAR_ESTOP releases it."""
    name = "e-stop"
    session.estop()
    latched = any(t.status & ESTOP_BIT and t.mode == 0 for t in _rows(session, 3))
    refused = False
    try:
        session.set_mode("voltage")
    except LinkError as exc:
        refused = "estop_active" in str(exc)
    if not refused:
        session.set_mode("idle")
    session.clear_estop()
    released = False
    for _ in range(5):  # frames sent before CLEAR_ESTOP was handled may still carry the bit
        if not session.next_telemetry().status & ESTOP_BIT:
            released = True
            break
    if latched and refused and released:
        return Check(name, "", OK, "ESTOP latched (motors idle, moves refused); cleared")
    seen = f"latched {latched}, moves refused {refused}, released {released}"
    return Check(
        name, "", FAIL, seen,
        "the firmware must idle the motors, refuse moves until CLEAR_ESTOP and report the "
        "e-stop bit: check the e-stop input (board.h, active low) and the firmware",
    )  # fmt: skip


def watchdog_check(session, period_s: float) -> Check:
    """Voltage mode at 0 V, then host silence: the robot must idle itself and say so."""
    name = "watchdog"
    session.set_watchdog(WATCHDOG_TEST_S)
    session.set_mode("voltage")
    session.send_voltage([0.0] * len(session.info["counts_per_rev"]))
    session.telemetry.clear()
    start = None
    tripped = None
    limit = round((WATCHDOG_TEST_S * 4) / period_s) + 4
    for _ in range(limit):
        t = session.next_telemetry()
        start = t.tick if start is None else start
        if t.status & WATCHDOG_BIT and t.mode == 0:
            tripped = (t.tick - start + 1) * period_s
            break
    session.clear_estop()  # also clears a tripped watchdog
    session.set_mode("idle")
    session.set_watchdog(WATCHDOG_RUN_S)
    if tripped is not None and tripped <= WATCHDOG_TEST_S + 4 * period_s:
        return Check(name, "", OK, f"idled after {tripped * 1e3:.0f} ms of host silence "
                     f"(set {WATCHDOG_TEST_S * 1e3:.0f} ms)")  # fmt: skip
    seen = "not" if tripped is None else f"only after {tripped * 1e3:.0f} ms"
    return Check(
        name, "", FAIL, f"{seen} idled within {limit * period_s * 1e3:.0f} ms of host silence "
        f"(set {WATCHDOG_TEST_S * 1e3:.0f} ms)",
        "the motors keep their last command when the cable comes out: the firmware's "
        "watchdog must idle them after SET_WATCHDOG's timeout",
    )  # fmt: skip


def ping_times(session, n: int = PINGS) -> np.ndarray:
    """Round trips [s] of ``n`` PINGs (simulated time on a lock-step sim:// port)."""
    out = []
    for _ in range(n):
        t0 = _clock(session)
        session.ping()
        out.append(_clock(session) - t0)
    session.telemetry.clear()
    return np.array(out)


def pulse_plan(joint, yaml: JointYaml, counts0: int, period_s: float):
    """(sign of the first pulse, pulse voltage [V], window (lo, hi) [counts]) for a joint
    resting at ``counts0``; :class:`MovesStopped` when its limits leave too little room."""
    volts = PULSE_FRACTION * yaml.supply_v
    bound = volts / yaml.ke * PULSE_TICKS * period_s  # [rad] at no-load speed
    q0 = counts0 / yaml.counts_per_rad
    lo, hi = joint.limits.position if joint.limits.position is not None else (-math.inf, math.inf)
    sign = 1 if hi - q0 >= q0 - lo else -1
    room = (hi - q0) if sign > 0 else (q0 - lo)
    if room < bound + LIMIT_MARGIN_RAD:
        raise MovesStopped(Check(
            "room to move", yaml.name, FAIL,
            f"at {q0:.3f} rad, {room:.3f} rad from its limit, a pulse may go {bound:.3f} rad",
            "move the joint by hand towards the middle of its range (or check the limits "
            "in the YAML) and run doctor again",
        ))  # fmt: skip
    w_lo = max(lo, q0 - WINDOW_FACTOR * bound)
    w_hi = min(hi, q0 + WINDOW_FACTOR * bound)
    tol = LIMIT_MARGIN_RAD
    window = (math.floor((min(w_lo, q0) - tol) * yaml.counts_per_rad),
              math.ceil((max(w_hi, q0) + tol) * yaml.counts_per_rad))  # fmt: skip
    return sign, volts, window


def pulse_joint(session, description, k: int, yaml: JointYaml, period_s: float) -> JointPulses:
    """Run joint ``k``'s pulses (voltage mode already on) and return what they recorded."""
    n = len(description.joints)
    rest = settle(session, keepalive=lambda: session.send_voltage([0.0] * n))
    sign, volts, (w_lo, w_hi) = pulse_plan(description.joints[k], yaml, rest[-1].counts[k],
                                           period_s)  # fmt: skip
    schedule = []
    for level in (sign * volts, 0.0, -sign * volts, 0.0):
        schedule += [level] * PULSE_TICKS
    cmd, rows, faults = [], [], len(session.faults)
    prev = 0.0
    for level in schedule:
        vector = [0.0] * n
        vector[k] = level
        session.send_voltage(vector)
        t = session.next_telemetry()
        rows.append(t)
        cmd.append(prev)  # the command in force over the period this row measures
        prev = level
        c = t.counts[k]
        if not w_lo <= c <= w_hi or len(session.faults) > faults:
            session.set_mode("idle")
            why = (
                f"counts {c} left the window {w_lo}..{w_hi}"
                if not w_lo <= c <= w_hi
                else f"the robot sent FAULT {session.faults[-1]}"
            )
            raise MovesStopped(Check(
                "moves stopped", yaml.name, FAIL, f"{why}: motors idled",
                "the joint ran further than its pulse allows: check the encoder and motor "
                "wiring before any capture",
            ))  # fmt: skip
    session.send_voltage([0.0] * n)
    return JointPulses(
        name=yaml.name,
        commanded_v=np.array(cmd),
        voltage_v=np.array([t.voltage_mv[k] for t in rows]) * 1e-3,
        current_a=np.array([t.current_ma[k] for t in rows]) * 1e-3,
        counts=np.array([t.counts[k] for t in rows], dtype=np.int64),
        at_limit=np.array([bool(t.status & LIMIT_BITS[k]) for t in rows]),
    )


def run_checks(session, description, latency: Check | None = None) -> list[Check]:
    """Every check, in the order of the module docstring; the robot idle at the end.

    The session's handshake must be done. Link errors propagate (the robot idled first)."""
    period_s = description.sample_period
    facts = joint_facts(description)
    checks: list[Check] = []
    try:
        session.set_mode("idle")
        session.start_stream()
        rows = settle(session, FIRST_REST_TICKS)
        if rows[-1].status & ESTOP_BIT:
            session.clear_estop()
            if session.next_telemetry().status & ESTOP_BIT:
                checks.append(Check(
                    "e-stop", "", FAIL, "the e-stop input is active",
                    "release the e-stop button (its input, board.h, reads low: pressed or "
                    "shorted to ground)",
                ))  # fmt: skip
                return checks + _not_run(facts)
        rest = _rows(session, REST_TICKS)
        offsets = []
        for k, yaml in enumerate(facts):
            current = np.array([t.current_ma[k] for t in rest]) * 1e-3
            checks.append(current_offset(yaml, current))
            offsets.append(float(np.mean(current)))
        checks.append(link_check(ping_times(session), period_s))
        if latency is not None:
            checks.append(latency)
        checks.append(estop_check(session))
        checks.append(watchdog_check(session, period_s))
        session.set_mode("voltage")
        pulses = []
        try:
            for k, yaml in enumerate(facts):
                p = pulse_joint(session, description, k, yaml, period_s)
                pulses.append(p)
                stuck = max(8, round(STUCK_RAD * yaml.counts_per_rad))
                checks += motion_checks(yaml, p, period_s, offsets[k], stuck)
        except MovesStopped as stop:
            checks.append(stop.check)
            return checks
        finally:
            session.finish()
        checks.append(supply_check(facts, pulses))
    finally:
        session.finish()
    return checks


def _not_run(facts) -> list[Check]:
    return [Check("moves", y.name, UNKNOWN, "not run") for y in facts]
