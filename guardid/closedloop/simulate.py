"""The guard robot's closed loop simulated with estimated base parameters.

The firmware is :class:`guardid.firmware.emulator.FirmwareEmulator` itself (its 15 ms tick:
encoder counts, the same fixed-point PID with the robot YAML's ``pid:`` gains, the position
limit check, the PWM duty), driving :class:`guardid.plant.Plant` (DC motors R, L, Ke, Kt,
gear; Karnopp stick/slip friction; classical RK4, ``substeps`` per tick, each step cut at
stick and limit events) whose rigid body is the estimate: M(q) and the bias torque come
from the base regressor (M's columns from unit accelerations), friction from the
estimate's Fv, Fc, Fo. The setpoints are the log's (its ``sp_*`` columns), stamped with
the log's ticks; noise off.
"""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np

from guardid.errors import GuardidError
from guardid.firmware.emulator import FirmwareEmulator
from guardid.plant import Plant
from guardid.protocol import ENUMS, Encoder
from guardid.protocol import MESSAGES as M

SUBSTEPS = 1
"""Plant RK4 steps per 15 ms tick at least (the fake port's default; see guardid.plant.plant);
more when the estimate's inertia makes the motor's damping stiff (:func:`stiffness_substeps`)."""
MAX_SUBSTEPS = 4
"""Above this many RK4 steps per tick the estimate's inertia is refused as too small to be a
robot's: one 15 ms step is stable down to an effective inertia of 0.072 kg m^2 on the guard's
pan and 0.27 on its tilt, four steps down to a quarter of that (0.018 and 0.068, 2-3 % of the
real ones); each step costs a simulation's time."""
RK4_STABLE = 2.0
"""h lambda kept below this on the negative real axis [-]: classical RK4 is stable up to
2.785 there (|1 + z + z^2/2 + z^3/6 + z^4/24| <= 1); 2.0 leaves a margin for the coupling."""
RUNAWAY_FACTOR = 10.0
"""A joint faster than this many times its motor's no-load speed at full supply (supply / Ke
of the joint) is a runaway: no motor of the description drives it there [-]."""
FRICTION_PREFIXES = ("Fv", "Fc", "Fo", "Fs")


class SimulationDiverged(GuardidError):
    """The closed-loop simulation left the physical: a non-finite state or a runaway speed.
    ``time_s`` [s] from the run's first row, ``reason`` one phrase."""

    def __init__(self, reason: str, time_s: float) -> None:
        super().__init__(f"diverged at t = {time_s:.3f} s ({reason})")
        self.reason, self.time_s = reason, float(time_s)


class NotSimulable(GuardidError):
    """A parameter set the closed loop cannot be simulated with (one phrase: why)."""


class BaseDynamics:
    """Rigid body of base parameters ``theta`` (b,) in the shape the plant evaluates:
    ``mass_matrix(q)`` (N, n, n) [kg m^2] and ``bias(q, qd)`` (N, n) [N m] (Coriolis,
    centrifugal, gravity), both from ``model.base_regressor`` with friction left out."""

    def __init__(self, model, theta) -> None:
        names = tuple(model.base.names)
        p = np.array(theta, dtype=float)
        p[[i for i, n in enumerate(names) if n.startswith(FRICTION_PREFIXES)]] = 0.0
        self._model, self.n_dof = model, model.n_dof
        self.params, self.param_names = p, names

    def mass_matrix(self, q, params=None) -> np.ndarray:
        p = self.params if params is None else np.asarray(params, dtype=float)
        q = np.atleast_2d(np.asarray(q, dtype=float))
        zero = np.zeros_like(q)
        rest = self._model.base_regressor(q, zero, zero) @ p
        cols = []
        for i in range(self.n_dof):
            e = zero.copy()
            e[:, i] = 1.0
            cols.append(self._model.base_regressor(q, zero, e) @ p - rest)
        return np.stack(cols, axis=2)

    def bias(self, q, qd, params=None) -> np.ndarray:
        p = self.params if params is None else np.asarray(params, dtype=float)
        q = np.atleast_2d(np.asarray(q, dtype=float))
        qd = np.atleast_2d(np.asarray(qd, dtype=float))
        return self._model.base_regressor(q, qd, np.zeros_like(q)) @ p

    def mass_matrix_1(self, q, params=None) -> np.ndarray:
        return self.mass_matrix([q], params)[0]

    def bias_1(self, q, qd, params=None) -> np.ndarray:
        return self.bias([q], [qd], params)[0]


def estimated_description(description, names, theta):
    """``description`` with each joint's friction replaced by the estimate's Fv<j>, Fc<j>
    (clipped at 0: the plant's static level) and Fo<j> when identified."""
    value = dict(zip(names, (float(x) for x in theta), strict=True))
    joints = []
    for j, joint in enumerate(description.joints):
        f = joint.friction
        if f is not None:
            k = str(j + 1)
            f = replace(
                f,
                viscous=value.get("Fv" + k, f.viscous),
                coulomb=max(value.get("Fc" + k, f.coulomb), 0.0),
                offset=value.get("Fo" + k, f.offset),
            )
        joints.append(replace(joint, friction=f))
    return replace(description, joints=tuple(joints))


def effective_inertia_terms(description, names, theta):
    """(a [kg m^2] (n,), c [N m s/rad] (n,)) per joint: the plant's inertia correction
    kt tau_e ke / R, subtracted from M's diagonal, and its velocity damping kt ke / R + Fv
    with the estimate's Fv (see guardid.plant.plant)."""
    from guardid.plant.joints import joint_constants

    value = dict(zip(names, (float(x) for x in theta), strict=True))
    consts = joint_constants(estimated_description(description, names, theta), True, True)
    a = np.array([jc.kt * jc.tau_e * jc.ke / jc.r if jc.driven else 0.0 for jc in consts])
    c = np.array([(jc.kt * jc.ke / jc.r if jc.driven else 0.0) + value.get(f"Fv{k + 1}", jc.fv)
                  for k, jc in enumerate(consts)])  # fmt: skip
    return a, c


class MassBasis:
    """M(q) of every base parameter at fixed positions ``q_rad`` (N, n) [rad]: M(q) for any
    ``theta`` is ``at(theta)`` (N, n, n) [kg m^2] (M is linear in the base parameters;
    friction columns left out as in :class:`BaseDynamics`)."""

    def __init__(self, model, q_rad) -> None:
        self.q = np.atleast_2d(np.asarray(q_rad, dtype=float))
        zero = np.zeros_like(self.q)
        rest = model.base_regressor(self.q, zero, zero)
        cols = []
        for i in range(model.n_dof):
            e = zero.copy()
            e[:, i] = 1.0
            cols.append(model.base_regressor(self.q, zero, e) - rest)
        self.basis = np.stack(cols, axis=2)  # (N, n, n, b)
        names = tuple(model.base.names)
        self.keep = np.array([not n.startswith(FRICTION_PREFIXES) for n in names])

    def at(self, theta) -> np.ndarray:
        return self.basis @ np.where(self.keep, np.asarray(theta, dtype=float), 0.0)


def stiffness_substeps(description, model, theta, visited) -> int:
    """RK4 steps per tick that keep the simulation stable with ``theta`` at the joint
    positions the motion visits, ``visited`` (N, n) [rad] or their :class:`MassBasis`;
    NotSimulable when the effective mass
    matrix M(q) - diag(a) is not positive definite at one of them (a negative or zero inertia:
    no physical robot, the simulation would run away), when a joint's damping is negative
    (friction that gives energy), or when more than :data:`MAX_SUBSTEPS` would be needed.

    Stiffness: the largest eigenvalue of (M - diag(a))^-1 diag(c) (the motors' back-EMF and
    viscous damping over the inertia) times the tick must stay below :data:`RK4_STABLE`."""
    names = tuple(model.base.names)
    a, c = effective_inertia_terms(description, names, theta)
    basis = visited if isinstance(visited, MassBasis) else MassBasis(model, visited)
    q = basis.q
    m = basis.at(theta) - np.diag(a)[None]
    m = 0.5 * (m + np.swapaxes(m, 1, 2))
    low = np.linalg.eigvalsh(m)[:, 0]
    if not np.all(np.isfinite(low)):
        raise NotSimulable("mass matrix not finite")
    k = int(np.argmin(low))
    if low[k] <= 0.0:
        where = ", ".join(f"{np.degrees(x):.1f}" for x in q[k])
        raise NotSimulable(
            f"mass matrix not positive definite at q = ({where}) deg, smallest eigenvalue "
            f"{low[k]:.3g} kg m^2: a negative inertia"
        )
    if np.any(c < 0.0):
        j = int(np.argmin(c))
        raise NotSimulable(f"joint {j + 1}'s damping {c[j]:.3g} N m s/rad is negative")
    root = np.sqrt(c)  # M^-1 C has the eigenvalues of the symmetric C^1/2 M^-1 C^1/2
    sym = root[None, :, None] * np.linalg.inv(m) * root[None, None, :]
    lam = float(np.linalg.eigvalsh(sym)[:, -1].max())
    n = max(SUBSTEPS, math.ceil(float(description.sample_period) * lam / RK4_STABLE))
    if n > MAX_SUBSTEPS:
        raise NotSimulable(
            f"an inertia too small to simulate ({n} RK4 steps per tick needed, damping over "
            f"inertia {lam:.3g} 1/s)"
        )
    return n


class GuardedPlant(Plant):
    """The plant, stopped before its sensors read a non-finite or runaway state
    (:class:`SimulationDiverged`); ``max_speed`` (n,) [rad/s]."""

    def __init__(self, *args, max_speed, **kwargs) -> None:
        super().__init__(*args, **kwargs)
        self._max_speed = [float(x) for x in max_speed]

    def step_sensors(self, u):
        """As :meth:`Plant.step_sensors`, checking the state between integration and ADC."""
        parts = self._integrate(u)
        for j, (x, v) in enumerate(zip(self._q, self._qd, strict=True)):
            if not (math.isfinite(x) and math.isfinite(v)):
                raise SimulationDiverged(f"joint {j + 1} state not finite", self._tick * self.dt)
            if abs(v) > self._max_speed[j]:
                raise SimulationDiverged(
                    f"joint {j + 1} at {v:.3g} rad/s, beyond {RUNAWAY_FACTOR:g} x its motor's "
                    "no-load speed",
                    self._tick * self.dt,
                )
        self.reading = self._measure(*parts)[:3]
        return self.reading


def runaway_speeds(description) -> np.ndarray:
    """Per joint [rad/s]: :data:`RUNAWAY_FACTOR` x supply / (Ke N) (no-load joint speed)."""
    return np.array([RUNAWAY_FACTOR * j.drive.supply_voltage / (j.drive.ke * j.drive.gear_ratio)
                     for j in description.joints])  # fmt: skip


def check_simulable(description) -> None:
    """One-line GuardidError unless every joint has a drive, an encoder and ``pid:``."""
    where = getattr(description, "source", "") or description.name
    joints = getattr(description, "joints", None)
    if joints is None or len(joints) != 2:
        raise GuardidError(
            f"--method iv/didim: {where}: robot {description.name} cannot be simulated in "
            "closed loop (a two-joint serial chain with motors, encoders and pid: is needed)"
        )
    for k, j in enumerate(joints):
        missing = [w for w, x in (("drive", j.drive), ("encoder", j.encoder), ("pid", j.pid))
                   if x is None]  # fmt: skip
        if missing:
            raise GuardidError(
                f"--method iv/didim: {where}: joints[{k}] ({j.name}) has no "
                f"{' or '.join(missing)}: the closed-loop simulation needs the motors, "
                "encoders and PID gains of every joint"
            )


def start_integral(pid, sp_counts, counts, next_mv) -> int:
    """The integral [Q16 mV] a :class:`~guardid.firmware.pid.FixedPid` holds after its step
    at a log's first row, from the outputs the log reports for the rows after it.

    ``sp_counts``, ``counts`` (K,) [counts]: setpoint and position at K rows of consecutive
    ticks; ``next_mv`` (K,) [mV]: the voltage of the period after each row (the PID's
    output at it). Row k >= 1 holds out_k = kp e_k + I_0 + ki (e_1 + ... + e_k) +
    kd (e_k - e_{k-1}) (Q16, e = setpoint - position), so each unsaturated row gives I_0;
    their mean averages out the PWM's and the voltage sensor's quantisation. None when no
    row is usable (fewer than two rows, or every output at the supply limit or zero)."""
    e = np.asarray(sp_counts, dtype=np.int64) - np.asarray(counts, dtype=np.int64)
    mv = np.asarray(next_mv, dtype=float)
    if len(e) < 2:
        return None
    ki_sum = pid.ki * np.cumsum(e[1:])
    rest = pid.kp * e[1:] + ki_sum + pid.kd * np.diff(e)
    usable = (np.abs(mv[1:]) < 0.95 * pid.limit_mv) & (mv[1:] != 0.0)
    if not np.any(usable):
        return None
    i0 = float(np.mean(mv[1:][usable] * 65536.0 - rest[usable]))
    lim = pid.limit_mv << 16
    return int(max(-lim, min(lim, round(i0))))


def started_firmware(description, plant, setpoint_rad, u0_v=None, following=None):
    """(firmware, setpoints [counts] (N, n), first counts, u0 [V] (n,)): the firmware
    emulator over ``plant`` in position mode at a log's first row, its PID's integral set
    from ``u0_v`` or ``following`` (see :func:`simulate`)."""
    fw = FirmwareEmulator(description, plant)
    counts0 = list(plant.counts())
    fw.counts = list(counts0)  # the firmware has read the encoders at the first row
    fw.receive(Encoder().encode(M["SET_MODE"](ENUMS["mode"]["position"])))
    fw.take_output()
    fw.watchdog_ms = 1 << 62  # no host in the loop
    cpr = np.array(fw.cpr, dtype=float)
    sp = np.rint(np.asarray(setpoint_rad, dtype=float) * cpr / (2 * math.pi)).astype(np.int64)
    fw.setpoint = sp[0].tolist()  # held until the next logged setpoint (lost rows between)
    u0 = np.zeros(len(cpr)) if u0_v is None else np.asarray(u0_v, dtype=float)
    for j, pid in enumerate(fw.pids):
        e0 = int(sp[0, j]) - int(counts0[j])
        mv = max(-pid.limit_mv, min(pid.limit_mv, int(round(1000.0 * u0[j]))))
        lim = pid.limit_mv << 16
        pid.integral = max(-lim, min(lim, (mv << 16) - pid.kp * e0))
        if following is not None:
            k = len(following[0])
            fitted = start_integral(pid, sp[:k, j], following[0][:, j], 1000.0 * following[1][:, j])
            pid.integral = pid.integral if fitted is None else fitted
        pid.prev_error = e0
        fw.applied_mv[j] = mv
    return fw, sp, counts0, u0


def simulate(description, model, theta, ticks, setpoint_rad, q0_rad, qd0, u0_v=None,
             following=None, sensors=False, supply=None, seed=0):  # fmt: skip
    """Joint positions [rad] (N, n) of the closed loop at the log's ``ticks`` (N,); with
    ``sensors``: (positions, encoder counts (N, n), period-mean voltage [V] and current [A]
    (N, n) as the firmware reads them, each row the period ending at its tick; the first
    row's voltage and current NaN: its period is before the simulation). ``supply``: a
    :class:`~guardid.plant.SupplyVariation` drawn from ``seed`` (None: the nominal supply).

    ``theta`` (b,): every base parameter of ``model``; ``setpoint_rad`` (N, n): the log's
    setpoints (held over unlogged ticks); the simulation starts at the first row from
    ``q0_rad`` (n,) [rad] and ``qd0`` (n,) [rad/s] with the PID's last output ``u0_v`` (n,)
    [V] (the voltage the log reports for the next period; its integral is set to give it,
    neglecting the derivative term, unless ``following`` is given).
    ``following``: (counts (K, n), next_v (K, n) [V]) of the log's first K rows (consecutive
    ticks): the integral is then :func:`start_integral`'s, which keeps the derivative term.

    NotSimulable before any step when ``theta`` is not a physical robot's where the motion
    goes (:func:`stiffness_substeps` at the setpoints and the start); SimulationDiverged
    (with its time) when the state turns non-finite or runs away, before the simulated
    sensors read it.
    """
    check_simulable(description)
    names = tuple(model.base.names)
    visited = np.vstack([np.asarray(setpoint_rad, dtype=float), np.asarray(q0_rad, dtype=float)])
    substeps = stiffness_substeps(description, model, theta, visited)
    plant_desc = estimated_description(description, names, theta)
    plant = GuardedPlant(plant_desc, model=BaseDynamics(model, theta), noise=False,
                         substeps=substeps, q0=list(q0_rad), qd0=list(qd0),
                         max_speed=runaway_speeds(description), supply=supply,
                         seed=seed)  # fmt: skip
    fw, sp, counts0, u0 = started_firmware(description, plant, setpoint_rad, u0_v, following)
    cpr = np.array(fw.cpr, dtype=float)
    rel = np.asarray(ticks, dtype=np.int64) - int(ticks[0])
    out = np.empty((len(rel), len(cpr)))
    out[0] = plant.state.q
    read = np.full((len(rel), 3, len(cpr)), np.nan) if sensors else None
    if sensors:
        read[0, 0] = counts0
    buffer = fw.buffer
    row = 1
    for k in range(1, int(rel[-1]) + 1):
        if rel[row] == k:
            buffer.append((k, sp[row].tolist(), False))
        fw.advance()
        if rel[row] == k:
            out[row] = plant.state.q
            if sensors:
                read[row] = plant.reading
            row += 1
    if sensors:
        return out, read[:, 0].astype(np.int64), read[:, 1], read[:, 2]
    return out
