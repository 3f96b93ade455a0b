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

    per_rad = counts_per_rad(description)
    q_from = np.asarray(counts_now, dtype=float) / per_rad
    target = setpoint_counts(trajectory, description, 1, resume_at)[0]
    q_to = target / per_rad
    ramp = approach_ticks(description, q_from, q_to)
    hold = math.ceil(HOLD_S / description.sample_period)
    tau = np.clip(np.arange(ramp + hold) / ramp, 0.0, 1.0)[:, None]
    s = tau**3 * (10 - 15 * tau + 6 * tau**2)
    approach = np.rint((q_from + s * (q_to - q_from)) * per_rad).astype(np.int64)
    approach[ramp:] = target
    lead = len(approach)

    def make(start: int, stop: int) -> np.ndarray:
        parts = []
        if start < lead:
            parts.append(approach[start : min(stop, lead)])
        if stop > lead:
            a = max(start, lead) - lead + resume_at
            parts.append(setpoint_counts(trajectory, description, stop - max(start, lead), a))
        return np.concatenate(parts)

    return LazyRows(lead + n_ticks - resume_at, make), lead
