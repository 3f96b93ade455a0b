"""Where a capture goes on after its port came back (``capture --reconnect``).

While the port was gone the robot's watchdog idled it, and it rests wherever that left it
(an arm on its stop). The trajectory is taken up again at a rest point: the first start of
a period after the rows reached (an excitation trajectory is at rest there: q, q' and q''
as at its start), reached by an approach from where the robot rests: a quintic in time
from rest to rest, slow enough to stay within half the joints' velocity and acceleration
limits, then a hold of :data:`HOLD_S` for the PID to settle. The approach's rows are not
logged: the log goes on with the trajectory's, after a gap in the tick column.
"""

from __future__ import annotations

import math

import numpy as np

from guardid.capture.checks import counts_per_rad
from guardid.errors import LinkError
from guardid.link.session import LazyRows

LIMIT_SHARE = 0.5  #: the approach uses at most this share of the velocity/accel limits [-]
MIN_APPROACH_S = 0.3  #: shortest approach [s]
HOLD_S = 0.5  #: the approach holds the rest point this long before the trajectory [s]
REST_SPEED_SHARE = 0.02
"""A point of the trajectory whose speed is at most this share of the joint's velocity
limit is a rest point [-]."""
_QUINTIC_V, _QUINTIC_A = 1.875, 5.7735  # peak speed x T / d, peak accel x T^2 / d


def link_lost(exc: LinkError) -> bool:
    """True when ``exc`` says the link failed (the port vanished, no answer or no
    telemetry), not that the robot refused a command."""
    return "refused by the robot" not in str(exc)


def next_rest_index(trajectory, description, reached: int, after: int | None = None):
    """The first trajectory row [index] at or after ``reached`` on a period's start (and
    after ``after``, a previous resume, so that every resume makes progress), or None when
    the trajectory is not at rest there."""
    period_ticks = trajectory.period / description.sample_period
    k = max(0, math.floor(reached / period_ticks))
    while (index := math.ceil(k * period_ticks - 1e-9)) < reached or (
        after is not None and index <= after
    ):
        k += 1
    t = np.array([index * description.sample_period])
    speed = np.abs(trajectory.velocities(t)).reshape(-1)
    vmax = np.array([_limit(j, "velocity") for j in description.joints])
    if np.any(speed > REST_SPEED_SHARE * vmax):
        return None
    return index


def _limit(joint, kind: str) -> float:
    value = getattr(joint.limits, kind, None) if joint.limits is not None else None
    return float(value) if value else math.inf


def approach_ticks(description, q_from, q_to) -> int:
    """Ticks of the quintic from ``q_from`` to ``q_to`` [rad] within LIMIT_SHARE of the
    limits (at least MIN_APPROACH_S)."""
    seconds = MIN_APPROACH_S
    for joint, a, b in zip(description.joints, q_from, q_to, strict=True):
        d = abs(float(b) - float(a))
        v, acc = _limit(joint, "velocity"), _limit(joint, "acceleration")
        seconds = max(seconds, _QUINTIC_V * d / (LIMIT_SHARE * v))
        seconds = max(seconds, math.sqrt(_QUINTIC_A * d / (LIMIT_SHARE * acc)))
    return math.ceil(seconds / description.sample_period)


def resume_rows(trajectory, description, counts_now, resume_at: int, n_ticks: int):
    """(rows, approach length): setpoints [counts] from the robot's ``counts_now`` to the
    trajectory's row ``resume_at`` (approach and hold), then the trajectory's rows
    ``resume_at`` .. ``n_ticks`` - 1."""
    from guardid.capture.run import setpoint_counts

    target = setpoint_counts(trajectory, description, 1, resume_at)[0]
    approach = approach_counts(description, counts_now, target)

    def tail(start: int, stop: int) -> np.ndarray:
        return setpoint_counts(trajectory, description, stop - start, resume_at + start)

    return _behind(approach, tail, n_ticks - resume_at), len(approach)


def approach_counts(description, counts_from, counts_to) -> np.ndarray:
    """(ticks, n) setpoints [counts] of the approach from ``counts_from`` to ``counts_to``:
    the quintic of :func:`approach_ticks`, then the hold of HOLD_S."""
    per_rad = counts_per_rad(description)
    q_from = np.asarray(counts_from, dtype=float) / per_rad
    q_to = np.asarray(counts_to, dtype=float) / per_rad
    ramp = approach_ticks(description, q_from, q_to)
    hold = math.ceil(HOLD_S / description.sample_period)
    tau = np.clip(np.arange(ramp + hold) / ramp, 0.0, 1.0)[:, None]
    s = tau**3 * (10 - 15 * tau + 6 * tau**2)
    approach = np.rint((q_from + s * (q_to - q_from)) * per_rad).astype(np.int64)
    approach[ramp:] = np.asarray(counts_to, dtype=np.int64)
    return approach


def start_rows(rows: LazyRows, description, counts_now, target, extra=()):
    """(rows, approach length): the run's setpoint ``rows`` behind an approach from where the
    robot rests (``counts_now``) to their first setpoint ``target`` [counts] (:func:`
    approach_counts`; ``extra``: values after each approach row, the first row's
    feedforward [mV]), or ``rows`` as they are when the robot rests there. For a run that
    starts after the motors were held at 0 V (the current sensors' zero read before the
    trajectory, :mod:`guardid.capture.zero`): an arm that sank onto its stop is led back
    within the limits' shares, not by a step at the PID's full voltage (a PID slow to
    hold it against gravity may still lag at the first row)."""
    if np.array_equal(np.asarray(counts_now), np.asarray(target)):
        return rows, 0
    approach = approach_counts(description, counts_now, target)
    if len(extra):
        tail = np.tile(np.asarray(extra, dtype=np.int64), (len(approach), 1))
        approach = np.hstack([approach, tail])
    return _behind(approach, rows.make, len(rows)), len(approach)


def _behind(approach: np.ndarray, tail, n_tail: int) -> LazyRows:
    """The ``approach`` rows, then the ``n_tail`` rows ``tail(start, stop)`` makes (their
    own indices from 0), made as a run reaches them."""
    lead = len(approach)

    def make(start: int, stop: int) -> np.ndarray:
        parts = []
        if start < lead:
            parts.append(approach[start : min(stop, lead)])
        if stop > lead:
            parts.append(tail(max(start, lead) - lead, stop - lead))
        return np.concatenate(parts)

    return LazyRows(lead + n_tail, make)
