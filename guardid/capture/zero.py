"""The current sensors' zero, read after a capture (and before it) with the motors at 0 V.

A current sensor's zero offset is a constant torque to identification: over the tilt's
short travel its gravity is nearly a constant torque too, and a pan's Coulomb and viscous
friction take up the rest, so an offset of a fraction of an ADC step moves estimates by
more than their std (docs/IDENTIFY.md 'The current sensors' zero'). After the trajectory
(and before it, ``capture --zero-before``) the motors are held at 0 V (voltage mode, 0 V
sent every tick as ``guardid doctor`` does: the watchdog stays fed, and a lock-step port
steps at the host's pace); once every joint's counts stood still for STILL_TICKS ticks no
current flows, and the mean reading over the next ``rest_s`` seconds is the sensors' zero.
It goes to the log's footer (``current_zero``, ``current_zero_before``: each joint's with
``t_s``, the readings' mean time on the log's clock), which identify reads: two zeros give
the sensor's drift over the run, taken off as a straight line between them. The rows read
at rest are not logged: they are not part of the trajectory.
"""

from __future__ import annotations

import math
from collections import Counter

STILL_TICKS = 10  #: counts unchanged this many ticks: the joints are at rest
SETTLE_LIMIT_S = 15.0  #: give up when the joints are not at rest within this long [s]
REST_SHARE = 0.1
"""The default rest: this share of the run's length [-] (the zero's error then stays the
same share of the estimates' std at any length: both shrink as 1 / sqrt(time)), within
REST_MIN_S and REST_MAX_S."""
REST_MIN_S = 2.0  #: the default rest's shortest [s]
REST_MAX_S = 120.0  #: the default rest's longest [s]


def default_rest_s(run_s: float) -> float:
    """The rest [s] after a run of ``run_s`` seconds: REST_SHARE of it, within REST_MIN_S
    and REST_MAX_S."""
    return min(max(REST_SHARE * run_s, REST_MIN_S), REST_MAX_S)


def measure_current_zero(session, description, rest_s: float, readings=None,
                         ticks=None) -> dict:  # fmt: skip
    """Hold the motors at 0 V, wait until every joint stood still, then read the current
    sensors for ``rest_s`` seconds (the telemetry must be streaming; the caller puts the
    robot idle after).

    Returns the footer's ``current_zero`` (:func:`zero_of` the readings), or
    ``{not_measured: reason}`` when the joints did not come to rest within SETTLE_LIMIT_S.
    ``readings`` (a list, optional) receives each reading as it comes (a caller stopped
    part-way keeps them), ``ticks`` (a list, optional) each reading's tick. Link errors
    propagate (the caller puts the robot idle)."""
    period = description.sample_period
    need = max(2, math.ceil(rest_s / period))
    limit = need + math.ceil(SETTLE_LIMIT_S / period)
    zero_v = [0.0] * len(description.joints)
    session.set_mode("voltage")
    readings = [] if readings is None else readings
    still, last = 0, None
    for _ in range(limit):
        session.send_voltage(zero_v)
        t = session.next_telemetry()
        still = still + 1 if t.counts == last else 0
        last = t.counts
        if still >= STILL_TICKS:  # a joint that moves again ends the run of still ticks
            readings.append(t.current_ma)
            if ticks is not None:
                ticks.append(t.tick)
            if len(readings) >= need:
                break
    if len(readings) < need:
        return {
            "not_measured": f"the joints were not at rest for {rest_s:g} s within "
            f"{SETTLE_LIMIT_S:g} s of the motors held at 0 V"
        }
    return zero_of(description, readings)


def zero_of(description, readings) -> dict:
    """Per driven joint ``{mean_a, std_a, rows, readings_ma}`` of ``readings`` (each the
    telemetry's currents [mA], at least 2): their mean and sample std [A], how many, and
    [mA, count] pairs (how many read each whole mA, for identify to put them on the ADC's
    levels as it does the log's currents)."""
    zero = {}
    for j, joint in enumerate(description.joints):
        if joint.drive is None:
            continue
        values = [r[j] * 1e-3 for r in readings]
        mean = sum(values) / len(values)
        var = sum((v - mean) ** 2 for v in values) / (len(values) - 1)
        counts = Counter(int(r[j]) for r in readings)  # the telemetry's whole mA
        zero[joint.name] = {"mean_a": mean, "std_a": math.sqrt(var), "rows": len(values),
                            "readings_ma": [[v, c] for v, c in sorted(counts.items())]}  # fmt: skip
    return zero
