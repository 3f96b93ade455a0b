"""Rows lost without a gap in the tick column: a step between two rows that no drive makes.

A guardid log shows every lost row as a gap in its tick column (:mod:`.segments`). A log
cut by hand (rows deleted, the ticks renumbered) or two logs pasted together with
contiguous ticks show none: the step between the rows either side of the cut is taken for
one tick's motion, a velocity no motor gave, which the motor fit (R, Ke) and the momentum
form's rows then lean on. On a 300 s capture of the variant robot with 2337 rows cut out
of its middle and its ticks made contiguous, the tilt motor's Ke came out 0.02196 +- 5e-5
V s/rad against the YAML's 0.025 (60 std), with exit 0 and ordinary-looking rigid-body
estimates. Such a step is a **jump**: the run is split there as at a long gap.

**The reach** (:func:`drive_reach`). A DC motor behind a gear of ratio N, at V volts,
turns its joint no faster than its no-load speed V / (Ke N) unless an outside torque drives
it on; a torque tau_ext at the joint then raises the speed by at most the back-EMF of the
current it drives against the motor, R tau_ext / (eta Kt N) volts' worth. The outside
torque bounded here is gravity: the largest |g_j(q)| of the description's nominal model
over :data:`POSES` poses drawn within the joints' limits. So joint j moves at most

    w_j = (V_j + R_j max|g_j| / (eta_j Kt_j N_j)) / (Ke_j N_j)   [rad/s | m/s]

with V_j the larger of the drive's supply and the run's largest |voltage| on that joint.
A step of more than ``JUMP_MARGIN w_j dt + 1 count`` between two rows dt seconds apart is
a jump (the count: the encoder's rounding can add up to one to a step).

:data:`JUMP_MARGIN` = 2 covers what the bound leaves out: a Ke up to 25 % below the
description's (identify refuses a fitted Ke further off), the Coriolis and centrifugal
torques, a gravity peak between the sampled poses, the supply's ripple. Honest logs step
inside it: over 714 captures of five robots (guard, coarse, modified, third, variant;
Fourier, Schroeder and sines excitations, a start with the PID saturated; 8 s to 1 h) the
largest step was 0.37 of the threshold, the median log's 0.17; an outside review's 88 fresh
captures (starts up to 2^20 counts away, the supply up to 50 % over, a payload added) reached
0.47, and 0.57 with the voltage sensor clipping at its range
(``bench/results/jumps_2026-11-29.txt``). A joint that does outrun its drive (coasting
under gravity with the bridge off) is split there too: a warning line, and the rows at the
two new ends.

A joint without a drive (its effort a measured torque), a description without joints (the
flexible link), a torque log or a run off the tick grid (a foreign log, whose host times
may come in bursts) has no reach: nothing is checked there.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

JUMP_MARGIN = 2.0
"""A step beyond this many times the drive's reach in the rows' time is a jump [-]."""
POSES = 256
"""Poses [-] drawn (seeded) within the joints' limits for the largest gravity torque."""
UNLIMITED_TRAVEL = {"revolute": math.pi, "prismatic": 1.0}
"""Half-range [rad | m] of the poses drawn for a joint without position limits."""


@dataclass(frozen=True)
class Reach:
    """Per joint of a description: ``ke_n`` [V s/rad | V s/m] (Ke N of the drive; inf
    without one), ``back_drive_v`` [V] (R max|g_j| / (eta Kt N): gravity's most), ``supply_v``
    [V], ``count`` [rad | m] (one encoder count at the joint, 0 without an encoder) and
    ``sensor_range_v`` [V] (the voltage sensor's full scale; inf without one)."""

    names: tuple[str, ...]
    ke_n: np.ndarray
    back_drive_v: np.ndarray
    supply_v: np.ndarray
    count: np.ndarray
    sensor_range_v: np.ndarray

    def speeds(self, voltage=None) -> np.ndarray:
        """Per joint the fastest speed [rad/s | m/s] its drive gives (module docstring), inf
        for a joint without a drive; the volts are the supply or, when larger, the largest
        finite |voltage| of ``voltage`` (N, n) [V] (a run's column), taken at most up to
        the voltage sensor's range (a reading beyond it is no voltage the drive gave)."""
        volts = self.supply_v
        if voltage is not None:
            v = np.abs(np.asarray(voltage, dtype=float))
            if v.ndim == 2 and v.shape[1] == len(volts) and len(v):
                v = np.where(np.isfinite(v) & (v <= self.sensor_range_v), v, 0.0)
                volts = np.maximum(volts, v.max(axis=0))
        with np.errstate(invalid="ignore", divide="ignore"):
            speed = (volts + self.back_drive_v) / self.ke_n
        return np.where(np.isfinite(self.ke_n), speed, np.inf)


def drive_reach(description) -> Reach | None:
    """The :class:`Reach` of ``description``'s joints; None when none has a drive (or the
    description has no joints: the flexible link)."""
    joints = getattr(description, "joints", None)
    if not joints or not any(j.drive is not None for j in joints):
        return None
    gravity = _largest_gravity(description)
    n = len(joints)
    ke_n, back, supply, count = (np.full(n, np.inf), np.zeros(n), np.zeros(n), np.zeros(n))
    sensor_range = np.full(n, np.inf)
    for k, joint in enumerate(joints):
        d = joint.drive
        if d is not None:
            ke_n[k] = d.ke * d.gear_ratio
            back[k] = d.resistance * gravity[k] / (d.efficiency * d.kt * d.gear_ratio)
            supply[k] = d.supply_voltage
        if joint.voltage_sensor is not None:
            sensor_range[k] = joint.voltage_sensor.range
        per_rad = joint.counts_per_rad
        count[k] = 1.0 / per_rad if per_rad else 0.0
    return Reach(tuple(j.name for j in joints), ke_n, back, supply, count, sensor_range)


def _largest_gravity(description) -> np.ndarray:
    """Per joint the largest |g_j(q)| [N m | N] of the nominal model over :data:`POSES`
    seeded poses within the joints' limits (:data:`UNLIMITED_TRAVEL` without limits)."""
    from guardid.dynamics import build_model

    rng = np.random.default_rng(0)
    lo, hi = [], []
    for joint in description.joints:
        limits = joint.limits.position if joint.limits is not None else None
        if limits is None:
            half = UNLIMITED_TRAVEL.get(joint.type, math.pi)
            limits = (-half, half)
        lo.append(limits[0])
        hi.append(limits[1])
    q = rng.uniform(lo, hi, size=(POSES, len(lo)))
    g = build_model(description).bias(q, np.zeros_like(q))
    return np.max(np.abs(g), axis=0)


@dataclass(frozen=True)
class Jump:
    """A step of ``step`` [rad | m] of ``joint`` between the row at ``at_s`` [s] (run time)
    and the next, ``limit`` [rad | m] being the most its drive gives in that time; the run
    is split after the row (``index``: the first row after the jump); ``period_s`` [s] the
    run's tick (:meth:`guardid.identify.segments.Split.lines` says what the split cost)."""

    path: str
    at_s: float
    index: int
    joint: str
    step: float
    limit: float
    period_s: float


def find_jumps(run, reach: Reach | None, period_s: float) -> list[Jump]:
    """The jumps of ``run`` (a Run: t [s], q (N, n), voltage [V]) against ``reach``, in
    order: per row pair the joint whose step is furthest beyond its limit. None of a run
    whose effort is a measured torque, of a run off the tick grid (a foreign log), or
    without a reach."""
    if reach is None or run.torque or run.ticks is None or len(run.t) < 2:
        return []  # a foreign log's host times may come in bursts: no rows' time to trust
    q = np.asarray(run.q, dtype=float)
    if q.ndim != 2 or q.shape[1] != len(reach.names):
        return []
    speed = reach.speeds(run.voltage)
    dt = np.diff(np.asarray(run.t, dtype=float))
    limit = JUMP_MARGIN * dt[:, None] * speed[None, :] + reach.count[None, :]
    ratio = np.abs(np.diff(q, axis=0)) / limit
    rows = np.flatnonzero(np.any(ratio > 1.0, axis=1))
    out = []
    for k in rows:
        j = int(np.argmax(ratio[k]))
        step = float(abs(q[k + 1, j] - q[k, j]))
        out.append(Jump(run.path, float(run.t[k]), int(k + 1), reach.names[j], step,
                        float(limit[k, j]), period_s))  # fmt: skip
    return out
