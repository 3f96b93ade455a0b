"""The bring-up checks' verdicts, worked out from what the bench moves recorded (pure
functions on arrays; no link). Every verdict says what was measured and, when it is not
``ok``, the fix in words.

The motor equation of a joint's pulses is the reference of three checks: a period's mean
motor voltage is ``V = R i + Ke w`` (the inductance's share, L di/dt, averages to about
nothing over a 15 ms period against a 0.25 ms time constant), ``w`` [rad/s] being the
joint speed from the encoder's counts over the period. A least-squares fit of R and Ke
over a joint's pulses (voltage on, off, reversed, off: the current and the speed vary
independently) against the YAML's values says:

* the sign of Ke: the encoder counts the way the motor turns, or against it (encoder A/B
  or the motor's leads swapped; the two give the same signals to a board, only the
  joint's real motion tells them apart);
* |Ke| / Ke(YAML): the YAML's counts per revolution times the real one's reciprocal (a
  known move: the back-EMF integrates to the angle turned, whatever the encoder says);
* R / R(YAML): the current sensor's gain reciprocal (and its sign).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

OK, WARN, FAIL, UNKNOWN = "ok", "warn", "FAIL", "unknown"

KE_TOLERANCE = 0.2
"""|Ke fit / Ke YAML - 1| above this: the counts per revolution disagree [-] (a x2 decoder
error is 100 %, the fit's scatter on the simulated guard robot about 2 %)."""
GAIN_TOLERANCE = 0.3
"""|R YAML / R fit - 1| above this: the current sensor's gain is off [-] (a motor's
winding resistance varies by ~20 % with temperature)."""
OFFSET_RANGE_FRACTION = 0.02
"""A current reading at rest above this share of the sensor's range is an offset [-]."""
SUPPLY_WARN, SUPPLY_FAIL = 0.1, 0.25
"""Supply voltage off the YAML's by more than these fractions: warn, fail [-]."""
STALL_FRACTION = 0.6
"""A pulse whose mean current is above this share of V/R turned nothing (stall) [-]."""


@dataclass(frozen=True)
class Check:
    """One row of the doctor's table: ``name``, ``joint`` ('' for the robot), ``verdict``
    (ok, warn, FAIL, unknown), ``measured`` (what was seen, with units), ``fix`` (words)."""

    name: str
    joint: str
    verdict: str
    measured: str
    fix: str = ""

    @property
    def failed(self) -> bool:
        return self.verdict == FAIL


@dataclass(frozen=True)
class JointPulses:
    """What one joint's pulses recorded, one entry per telemetry row: the commanded
    voltage [V], measured voltage [V] and current [A], encoder counts, the limit bit."""

    name: str
    commanded_v: np.ndarray
    voltage_v: np.ndarray
    current_a: np.ndarray
    counts: np.ndarray
    at_limit: np.ndarray


@dataclass(frozen=True)
class JointYaml:
    """The YAML's facts the checks need: counts per joint radian, joint-side Ke [V s/rad],
    R [ohm], supply [V], current sensor range [A], motor counts per rev."""

    name: str
    counts_per_rad: float
    ke: float
    r: float
    supply_v: float
    current_range_a: float
    counts_per_rev: int


def current_offset(joint: JointYaml, rest_current_a: np.ndarray) -> Check:
    """The current sensor's reading at rest (motors at 0 V, joints still)."""
    offset = float(np.mean(rest_current_a))
    limit = OFFSET_RANGE_FRACTION * joint.current_range_a
    measured = f"{offset * 1e3:+.0f} mA at rest (limit +-{limit * 1e3:.0f} mA)"
    if abs(offset) <= limit:
        return Check("current offset at rest", joint.name, OK, measured)
    return Check(
        "current offset at rest", joint.name, FAIL, measured,
        "the current sensor's zero is off: check its reference voltage and supply, "
        "or calibrate its zero in the firmware",
    )  # fmt: skip


def _verdict(name: str, joint: str, measured: str, fix: str) -> Check:
    """FAIL with ``fix`` when there is one, else ok."""
    return Check(name, joint, FAIL if fix else OK, measured, fix)


def moved(p: JointPulses) -> int:
    """The farthest the counts went from the first row's [counts]."""
    return int(np.max(np.abs(p.counts - p.counts[0]))) if len(p.counts) else 0


def _stalled(joint: JointYaml, p: JointPulses, offset_a: float) -> tuple[bool, float, float]:
    """(stalled, pulse voltage [V], current over stall current [-]) of the pulse direction
    whose current is lowest (gravity helps one way; a direction the firmware's limit
    blocked has no voltage and does not count)."""
    shares, v_on = [], 0.0
    for sign in (1.0, -1.0):
        on = (np.sign(p.commanded_v) == sign) & (np.abs(p.voltage_v) > 0.25 * joint.supply_v)
        if np.count_nonzero(on) >= 3:
            v = float(np.mean(np.abs(p.voltage_v[on])))
            i = float(np.mean(np.abs(p.current_a[on] - offset_a)))
            shares.append(i * joint.r / v)
            v_on = max(v_on, v)
    share = min(shares) if shares else 0.0
    return bool(shares) and share > STALL_FRACTION, v_on, share


def fit_motor(p: JointPulses, period_s: float, offset_a: float) -> tuple[float, float]:
    """(R [ohm], Ke [V s/rad]) of V = R (i - offset) + Ke w over the pulses, w from the
    counts at the YAML's counts per radian (caller's scale: counts per rad 1)."""
    w = np.diff(p.counts.astype(float)) / period_s
    v = p.voltage_v[1:]
    i = p.current_a[1:] - offset_a
    a = np.column_stack([i, w])
    (r, ke), *_ = np.linalg.lstsq(a, v, rcond=None)
    return float(r), float(ke)


def motion_checks(
    joint: JointYaml, p: JointPulses, period_s: float, offset_a: float, stuck_counts: int
) -> list[Check]:
    """Encoder direction, counts per revolution and the current sensor's gain and sign,
    from one joint's pulses; a joint whose counts did not move gets one verdict saying
    whether the motor turned (the current fell below the stall current) or not."""
    name = joint.name
    if moved(p) < stuck_counts:
        stalled, v_on, share = _stalled(joint, p, offset_a)
        measured = (
            f"{moved(p)} counts under +-{v_on:.1f} V; current {share:.0%} of the stall "
            "current in the freer direction"
        )
        fix = (
            "the motor draws near its stall current: the joint is jammed or held against "
            "a stop (free it; swapped motor leads drive it into the stop), or it turned "
            "against a load and the encoder counts nothing (check its A/B and supply wires)"
            if stalled
            else "the motor turns (its current falls below stall) but the encoder counts "
            "nothing: check the encoder's A/B and supply wires and its pins in board.h"
        )
        return [Check("encoder counts under voltage", name, FAIL, measured, fix)]
    r, ke_counts = fit_motor(p, period_s, offset_a)
    ke = ke_counts * joint.counts_per_rad  # V s/rad at the YAML's counts per radian
    direction = "fall" if ke < 0 else "rise"
    out = [_verdict(
        "encoder direction vs motor voltage", name,
        f"counts {direction} under positive voltage (Ke {ke:.3g} V s/rad)",
        "if the joint turned its positive way (the YAML's), swap the encoder's A and B "
        "wires (or set its BOARD_ENC<joint index>_SIGN to -1 in board.h), else swap the "
        "motor's leads" if ke < 0 else "",
    )]  # fmt: skip
    cpr = joint.ke / abs(ke) * joint.counts_per_rev  # the real counts per motor revolution
    out.append(_verdict(
        "counts per revolution", name,
        f"~{cpr:.0f} counts per motor rev from the back-EMF, YAML {joint.counts_per_rev} "
        f"(Ke {abs(ke):.3g}, YAML {joint.ke:.3g} V s/rad)",
        "set the encoder's counts_per_rev (and gear_ratio) in the robot YAML to the "
        "real ones, or the decoder's x1/x2/x4 mode in the firmware"
        if abs(abs(ke) / joint.ke - 1.0) > KE_TOLERANCE else "",
    ))  # fmt: skip
    gain = joint.r / r if r else float("inf")
    fix = ""
    if gain < 0:
        fix = "the current sensor reads against the motor voltage: turn it round"
    elif abs(gain - 1.0) > GAIN_TOLERANCE:
        fix = (
            "the current sensor's sensitivity differs from the YAML's current_sensor "
            "range: set the range to the sensor's, or check its gain resistor"
        )
    out.append(_verdict(
        "current sign under load", name,
        f"gain {gain:.2f} (R fit {r:.3g}, YAML {joint.r:.3g} ohm)", fix,
    ))  # fmt: skip
    return out


def supply_check(joints: list[JointYaml], pulses: list[JointPulses]) -> Check:
    """The supply voltage from the measured over the commanded motor voltage."""
    ratios, nominal = [], []
    for joint, p in zip(joints, pulses, strict=True):
        use = (p.commanded_v != 0) & ~p.at_limit
        use[:1] = False  # the first row's voltage is the period before the command
        if np.any(use):
            ratios.append(np.median(p.voltage_v[use] / p.commanded_v[use]))
            nominal.append(joint.supply_v)
    if not ratios:
        return Check("supply voltage", "", UNKNOWN, "no pulse measured")
    supply = float(np.median(np.array(ratios) * np.array(nominal)))
    yaml_v = float(np.median(nominal))
    off = supply / yaml_v - 1.0
    measured = f"{supply:.1f} V (YAML {yaml_v:g} V, {off:+.0%})"
    if abs(off) > SUPPLY_FAIL:
        verdict = FAIL
    elif abs(off) > SUPPLY_WARN:
        verdict = WARN
    else:
        return Check("supply voltage", "", OK, measured)
    return Check(
        "supply voltage", "", verdict, measured,
        "set the bench supply to the YAML's supply_voltage, or the YAML to the supply "
        "(the PID gains and the PWM scale assume it)",
    )  # fmt: skip


RTT_OK_TICKS, RTT_FAIL_TICKS = 4, 8
"""A PING's worst round trip within this many ticks: ok; beyond the second (the setpoint
buffer's depth): fail [ticks]."""


def link_check(rtts_s: np.ndarray, period_s: float) -> Check:
    """Round trip and jitter of PING -> PONG [s]."""
    rtts_s = np.asarray(rtts_s, dtype=float)
    med, worst = float(np.median(rtts_s)), float(np.max(rtts_s))
    jitter = float(np.std(rtts_s))
    measured = (
        f"round trip median {med * 1e3:.1f} ms, worst {worst * 1e3:.1f} ms, jitter "
        f"(std) {jitter * 1e3:.1f} ms over {len(rtts_s)} pings"
    )
    if worst <= RTT_OK_TICKS * period_s:
        return Check("link round trip", "", OK, measured)
    verdict = FAIL if worst > RTT_FAIL_TICKS * period_s else WARN
    return Check(
        "link round trip", "", verdict, measured,
        "setpoints may come late: lower the USB adapter's latency timer, use a shorter "
        "cable or another USB port, close programs loading the host",
    )  # fmt: skip
