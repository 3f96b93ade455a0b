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
"""Plant RK4 steps per 15 ms tick (the fake port's default; see guardid.plant.plant)."""
FRICTION_PREFIXES = ("Fv", "Fc", "Fo", "Fs")


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


def simulate(description, model, theta, ticks, setpoint_rad, q0_rad, qd0, u0_v=None):
    """Joint positions [rad] (N, n) of the closed loop at the log's ``ticks`` (N,).

    ``theta`` (b,): every base parameter of ``model``; ``setpoint_rad`` (N, n): the log's
    setpoints (held over unlogged ticks); the simulation starts at the first row from
    ``q0_rad`` (n,) [rad] and ``qd0`` (n,) [rad/s] with the PID's last output ``u0_v`` (n,)
    [V] (the voltage the log reports for the next period; its integral is set to give it).
    """
    check_simulable(description)
    names = tuple(model.base.names)
    plant_desc = estimated_description(description, names, theta)
    plant = Plant(plant_desc, model=BaseDynamics(model, theta), noise=False,
                  substeps=SUBSTEPS, q0=list(q0_rad), qd0=list(qd0))  # fmt: skip
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
        pid.prev_error = e0
        fw.applied_mv[j] = mv
    rel = np.asarray(ticks, dtype=np.int64) - int(ticks[0])
    out = np.empty((len(rel), len(cpr)))
    out[0] = plant.state.q
    buffer = fw.buffer
    row = 1
    for k in range(1, int(rel[-1]) + 1):
        if rel[row] == k:
            buffer.append((k, sp[row].tolist(), False))
        fw.advance()
        if rel[row] == k:
            out[row] = plant.state.q
            row += 1
    if not np.all(np.isfinite(out)):
        raise GuardidError(
            "--method iv/didim: the closed-loop simulation with the current estimate "
            "diverged (non-finite motion): the estimate is far from a physical robot"
        )
    return out
