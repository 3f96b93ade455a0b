"""The simulated two-joint plant: gear motors, rigid body, friction with stiction, sensors.

Model (SI units, per joint j; see docs in guardid/plant/__init__.py):

* Motor: L di/dt = V - R i - ke qd with ke = Ke N; joint torque kt i with kt = N eta Kt.
  tau_e = L/R (0.25 ms on the guard) is far below a tick, so the current is split into its
  slow manifold plus the exact boundary layer after each voltage step (singular
  perturbation, first order in tau_e):  i(t) = (V - ke qd)/R + tau_e ke qdd / R
  + delta e^{-t/tau_e}.  The qdd term is moved to the left-hand side as an inertia
  correction -kt tau_e ke / R; the boundary layer's torque kt delta e^{-t/tau_e} is applied as
  its exact impulse kt delta tau_e (1 - e^{-T/tau_e}) at the start of the period. The period
  mean current is integrated exactly from the end states:
  T i_mean = (V T - ke dq)/R + tau_e ke dqd / R + delta tau_e (1 - e^{-T/tau_e}).
  A locked rotor gives exactly i = V/R + (i0 - V/R) e^{-t/tau_e}.
* Rigid body: M(q) qdd + b(q, qd) = tau (M includes N^2 J_rotor), from the dynamics model.
* Friction (Karnopp-style stick/slip): a moving joint feels fv qd + fc s + fo with s its
  direction of motion. When its velocity reaches zero inside a step the step is cut at the
  crossing (linear interpolation, re-integrated) and the joint is held (qd = qdd = 0); it
  stays held while the friction needed to hold it, f = tau_drive - b - (M qdd)_coupling,
  lies in [fo - fc, fo + fc] (static level = Coulomb level), else it slides in the
  direction of f. The check runs at every sub-step boundary and event (with the voltage
  held over the tick it is exact for a single joint; coupling-driven breakaway is found
  within one sub-step). Position limits are inelastic stops handled the same way (the
  stop adds an unbounded one-sided holding torque).
* Integrator: classical RK4, ``substeps`` per tick, on (q, qd) of the non-held joints.
"""

from __future__ import annotations

import math
import random
from typing import NamedTuple

import numpy as np

from guardid.plant.fast2r import fit_two_revolute, generic_two
from guardid.plant.joints import PlantError, joint_constants
from guardid.plant.payload import payload_params
from guardid.plant.sensors import adc_quantise, pwm_quantise
from guardid.plant.variation import SupplyVariation, start_pose_q0
from guardid.plant.wiring import wire

DEFAULT_SUBSTEPS = 1
"""RK4 sub-steps per tick. One step per 15 ms tick keeps q within ~1e-7 rad of a tight
reference on the guard and energy drift ~2e-9 over 10 s (tests); stick events inside the
step are still located exactly (the step is cut there). What a larger value buys: a held
joint's breakaway caused by the *other* joint's motion is checked at every sub-step
instead of every tick (at most one tick late with 1). 1 keeps the whole simulated robot
above 200x real time through the protocol stack (bench/bench_hil.py)."""

_MAX_EVENTS = 8


class SensorSample(NamedTuple):
    """What the robot measures at the end of one period (tick k covers (k-1)T .. kT).

    counts: encoder counts at t = kT (ints); q_sensed [rad] = counts / counts_per_rad;
    voltage [V], current [A]: period means as the ADC reports them (noise + quantisation);
    voltage_true, current_true: exact period means; q [rad], qd [rad/s], i [A]: true
    state at t = kT.
    """

    tick: int
    time: float
    counts: tuple
    q_sensed: tuple
    voltage: tuple
    current: tuple
    voltage_true: tuple
    current_true: tuple
    q: tuple
    qd: tuple
    i: tuple


class PlantState(NamedTuple):
    """True state: time [s], q [rad], qd [rad/s], i [A], held (stuck / at a stop) flags."""

    time: float
    q: tuple
    qd: tuple
    i: tuple
    held: tuple


class Plant:
    """Simulated guard-type plant (two revolute joints), stepped one sample period at a time.

    ``step(u)`` holds ``u`` over one period: motor voltages [V] for driven joints (PWM
    quantised), joint torques [N m] for drive-less joints. Options: ``seed`` (sensor noise),
    ``noise`` (False: quantisation only), ``payload`` (PayloadChange list), ``substeps``,
    ``q0``/``qd0``, ``friction``/``limits`` (False drops them), ``open_circuit`` (motors
    disconnected: no current, rotor inertia still reflected), ``fast`` ('auto': fitted 2R
    evaluator if it verifies, else the model's mass_matrix_1/bias_1; False: always generic).
    ``supply`` (:class:`~guardid.plant.variation.SupplyVariation`; None: nominal): the motors
    see the PWM voltage times the supply's factor of the tick; the voltage sensor measures that.
    """

    def __init__(self, robot, *, model=None, seed: int = 0, noise: bool = True, payload=(),
                 substeps: int = DEFAULT_SUBSTEPS, q0=None, qd0=None, friction: bool = True,
                 limits: bool = True, open_circuit: bool = False, fast="auto",
                 supply=None):  # fmt: skip
        if isinstance(robot, str) or hasattr(robot, "__fspath__"):
            from guardid.robot import load_robot

            robot = load_robot(str(robot))
        if not hasattr(robot, "joints"):
            raise PlantError(f"{robot.name}: only serial-chain robots can be simulated")
        if model is None:
            from guardid.dynamics import build_model

            model = build_model(robot)
        if len(robot.joints) != 2:
            raise PlantError(f"{robot.name}: the plant simulates two-joint chains only")
        if substeps < 1:
            raise PlantError(f"substeps must be >= 1, got {substeps}")
        self.description, self.model = robot, model
        self.dt = float(robot.sample_period)
        self.substeps = int(substeps)
        self.joints = joint_constants(robot, friction, limits)
        self.open_circuit = bool(open_circuit)
        self.noise = bool(noise)
        self._rng = random.Random(seed)
        names, n_links = list(model.param_names), len(robot.links)
        base = np.asarray(model.params, dtype=float)
        changes = sorted(payload or (), key=lambda c: c.time)
        self.params = [base] + [payload_params(base, names, n_links, c) for c in changes]
        self._change_times = [float(c.time) for c in changes]
        self._dyns = [self._evaluator(p, fast) for p in self.params]
        self._phase = 0
        self._dyn = self._dyns[0]
        self.fast_path = fast is not False and all(getattr(d, "fitted", False) for d in self._dyns)
        q = [0.0, 0.0] if q0 is None else [float(x) for x in q0]
        qd = [0.0, 0.0] if qd0 is None else [float(x) for x in qd0]
        self._q, self._qd, self._i = q, qd, [0.0, 0.0]
        self._acc = [0.0, 0.0]
        self._m = self._dyn(q[0], q[1], qd[0], qd[1])[:3]
        self._sign = [1.0 if v >= 0 else -1.0 for v in qd]
        self._held = [jc.fc > 0.0 and v == 0.0 for jc, v in zip(self.joints, qd, strict=True)]
        self._stop = [0, 0]
        self._tick = 0
        self.current_drift_a_per_s = [0.0, 0.0]
        """Per joint how fast its current sensor's zero moves [A/s of the robot's time],
        before the sensor's ADC (``sim://...&wiring=current_drift:J=R``)."""
        self._edges = self._quad_counts(q)
        self._counts = list(self._edges)
        self._last_sign = [1.0, 1.0]
        self._single = any(jc.counts_per_rad and not jc.quadrature for jc in self.joints)
        self._u = [0.0, 0.0]
        self._per_rad = [jc.counts_per_rad for jc in self.joints]
        self._stops = [(jc.fc, jc.lo, jc.hi) for jc in self.joints]  # friction, limits
        # per joint: (driven, r, tau_e, ke, voltage and current sensors (range, bits, sigma)
        # or None)
        self._sensing = [(jc.driven, jc.r, jc.tau_e, jc.ke, jc.voltage_sensor,
                          jc.current_sensor) for jc in self.joints]  # fmt: skip
        # per joint: (driven, kt, r, open circuit, supply [V], PWM bits)
        self._drive = [(jc.driven, jc.kt, jc.r, self.open_circuit, jc.supply, jc.pwm_bits)
                       for jc in self.joints]  # fmt: skip
        self._supply = supply.factors(seed) if supply is not None and supply.active else None
        self._c1 = None
        self._configure([0.0, 0.0])

    # ------------------------------------------------------------------ set-up helpers
    def _evaluator(self, params, fast):
        dyn = fit_two_revolute(self.model, params) if fast is not False else None
        if dyn is not None:
            dyn.fitted = True
            return dyn
        return generic_two(self.model, params)

    def _configure(self, u) -> None:
        """Per-tick constants: drive torque c0 - c1 qd and inertia correction a per joint
        (c1 and a depend on the joint only: worked out once, see :meth:`_joint_terms`)."""
        if self._c1 is None:
            self._c1, self._a, self._decay = self._joint_terms()
        (dr1, kt1, r1, off, _, _), (dr2, kt2, r2, _, _, _) = self._drive  # two joints
        u1, u2 = u
        self._c0 = [
            (kt1 * u1 / r1 if not off else 0.0) if dr1 else u1,
            (kt2 * u2 / r2 if not off else 0.0) if dr2 else u2,
        ]
        self._make_accel()

    def _joint_terms(self):
        """Per joint: velocity coefficient c1 [N m s/rad], inertia correction a [kg m^2]
        and the current's boundary-layer decay over one period e^{-T/tau_e} (constants)."""
        c1, a, decay = [], [], []
        for jc in self.joints:
            if not jc.driven or self.open_circuit:
                c1.append(jc.fv)
                a.append(0.0)
            else:
                c1.append(jc.kt * jc.ke / jc.r + jc.fv)
                a.append(jc.kt * jc.tau_e * jc.ke / jc.r)
            decay.append(math.exp(-self.dt / jc.tau_e) if jc.driven and jc.tau_e > 0 else 0.0)
        return c1, a, decay

    def _make_accel(self) -> None:
        """Build the acceleration closure for the current held set and slip directions."""
        j1, j2 = self.joints
        e1 = self._c0[0] - j1.fc * self._sign[0] - j1.fo
        e2 = self._c0[1] - j2.fc * self._sign[1] - j2.fo
        c11, c12 = self._c1
        a1, a2 = self._a
        h1, h2 = self._held
        dyn = self._dyn

        if not h1 and not h2 and hasattr(dyn, "free_accel"):
            acc = dyn.free_accel(e1, e2, c11, c12, a1, a2)  # the closure below, fused with dyn

        elif not h1 and not h2:

            def acc(q1, q2, v1, v2):
                m11, m12, m22, b1, b2 = dyn(q1, q2, v1, v2)
                r1 = e1 - c11 * v1 - b1
                r2 = e2 - c12 * v2 - b2
                m11 -= a1
                m22 -= a2
                det = m11 * m22 - m12 * m12
                return (r1 * m22 - r2 * m12) / det, (r2 * m11 - r1 * m12) / det

        elif h1 and not h2:

            def acc(q1, q2, v1, v2):
                m11, m12, m22, b1, b2 = dyn(q1, q2, 0.0, v2)
                return 0.0, (e2 - c12 * v2 - b2) / (m22 - a2)

        elif h2 and not h1:

            def acc(q1, q2, v1, v2):
                m11, m12, m22, b1, b2 = dyn(q1, q2, v1, 0.0)
                return (e1 - c11 * v1 - b1) / (m11 - a1), 0.0

        else:

            def acc(q1, q2, v1, v2):
                return 0.0, 0.0

        self._accel = acc

    # ------------------------------------------------------------------ stick / slip
    def _holding(self):
        """Friction each held joint needs to stay held [N m] (None for moving joints)."""
        q1, q2 = self._q
        v1, v2 = self._qd
        m11, m12, m22, b1, b2 = self._dyn(q1, q2, v1, v2)
        d1, d2 = self._accel(q1, q2, v1, v2)
        f1 = self._c0[0] - b1 - m12 * d2 if self._held[0] else None
        f2 = self._c0[1] - b2 - m12 * d1 if self._held[1] else None
        return f1, f2

    def _update_contacts(self) -> None:
        """Release held joints whose holding friction leaves the static band (worst first)."""
        while any(self._held):
            need = self._holding()
            worst, excess, sign = -1, 0.0, 0.0
            for j, f in enumerate(need):
                if f is None:
                    continue
                jc, stop = self.joints[j], self._stop[j]
                lo = -math.inf if stop < 0 else jc.fo - jc.fc
                hi = math.inf if stop > 0 else jc.fo + jc.fc
                over = f - hi if f > hi else (lo - f if f < lo else 0.0)
                if over > excess:
                    worst, excess, sign = j, over, (1.0 if f > hi else -1.0)
            if worst < 0:
                return
            self._held[worst] = False
            self._stop[worst] = 0
            self._sign[worst] = sign
            self._make_accel()

    def _hold(self, j: int, stop: int) -> None:
        self._qd[j] = 0.0
        self._held[j] = True
        self._stop[j] = stop
        if stop:
            self._q[j] = self.joints[j].hi if stop > 0 else self.joints[j].lo
        self._make_accel()
        self._update_contacts()

    # ------------------------------------------------------------------ integration
    def _rk4(self, h):
        acc = self._accel
        q1, q2 = self._q
        v1, v2 = self._qd
        hh = 0.5 * h
        a1, a2 = acc(q1, q2, v1, v2)
        p1, p2, w1, w2 = q1 + hh * v1, q2 + hh * v2, v1 + hh * a1, v2 + hh * a2
        b1, b2 = acc(p1, p2, w1, w2)
        p1, p2, x1, x2 = q1 + hh * w1, q2 + hh * w2, v1 + hh * b1, v2 + hh * b2
        c1, c2 = acc(p1, p2, x1, x2)
        p1, p2, y1, y2 = q1 + h * x1, q2 + h * x2, v1 + h * c1, v2 + h * c2
        d1, d2 = acc(p1, p2, y1, y2)
        h6 = h / 6.0
        self._acc = [d1, d2]
        return (
            q1 + h6 * (v1 + 2.0 * (w1 + x1) + y1),
            q2 + h6 * (v2 + 2.0 * (w2 + x2) + y2),
            v1 + h6 * (a1 + 2.0 * (b1 + c1) + d1),
            v2 + h6 * (a2 + 2.0 * (b2 + c2) + d2),
        )

    def _event(self, new):
        """(fraction, joint, stop) of the earliest zero-speed or limit crossing, or None."""
        best = None
        held, q, qd, sign = self._held, self._q, self._qd, self._sign
        for j, (fc, lo, hi) in enumerate(self._stops):
            if held[j]:
                continue
            vn = new[2 + j]
            if fc > 0.0 and sign[j] * vn <= 0.0:
                v0 = qd[j]
                th = v0 / (v0 - vn) if v0 != vn else 0.0
                if best is None or th < best[0]:
                    best = (th, j, 0)
            qn = new[j]
            if qn > hi or qn < lo:
                q0 = q[j]
                lim, stop = (hi, 1) if qn > hi else (lo, -1)
                th = (lim - q0) / (qn - q0) if qn != q0 else 0.0
                if best is None or th < best[0]:
                    best = (th, j, stop)
        return best

    def _advance(self, h: float) -> None:
        """Integrate ``h`` seconds, cutting the step at stick and limit events."""
        events = 0
        while h > 0.0:
            new = self._rk4(h)
            ev = self._event(new) if events < _MAX_EVENTS else None
            if ev is None:
                self._accept(new)
                return
            th, j, stop = ev
            th = min(max(th, 0.0), 1.0)
            if th > 0.0:
                self._accept(self._rk4(th * h))
            self._hold(j, stop)
            h -= th * h
            events += 1

    def _accept(self, new) -> None:
        q1, q2, v1, v2 = new
        if self._single:
            self._count_edges(q1, q2)
        self._q = [q1, q2]
        self._qd = [v1, v2]
        flipped = False
        held, sign = self._held, self._sign
        for j in (0, 1):
            v = new[2 + j]
            if not held[j] and v != 0.0 and (v > 0.0) != (sign[j] > 0.0):
                sign[j] = -sign[j]
                flipped = flipped or self.joints[j].fc != 0.0
        if flipped:  # only after an event budget ran out; keep the friction direction right
            self._make_accel()

    def _quad_counts(self, q) -> list[int]:
        """floor(q N counts_per_rev / 2 pi) per joint."""
        return [math.floor(x * jc.counts_per_rad) for x, jc in zip(q, self.joints, strict=True)]

    def _count_edges(self, q1, q2) -> None:
        for j, x in enumerate((q1, q2)):
            jc = self.joints[j]
            e = math.floor(x * jc.counts_per_rad)
            if jc.quadrature:
                self._counts[j] = e
            else:
                self._counts[j] += int(self._last_sign[j]) * abs(e - self._edges[j])
            self._edges[j] = e

    # ------------------------------------------------------------------ public API
    @property
    def state(self) -> PlantState:
        """True state now."""
        return PlantState(self._tick * self.dt, tuple(self._q), tuple(self._qd),
                          tuple(self._i), tuple(self._held))  # fmt: skip

    @property
    def tick(self) -> int:
        """Number of periods simulated so far."""
        return self._tick

    def counts(self) -> tuple:
        """Encoder counts now (ints)."""
        if self._single:
            return tuple(self._counts)
        return tuple(self._quad_counts(self._q))

    def step(self, u) -> SensorSample:
        """Hold ``u`` (V per driven joint, N m per drive-less one) for one period."""
        counts, v_meas, i_meas, v_true, i_true = self._measure(*self._integrate(u))
        q_meas = [
            c / jc.counts_per_rad if jc.counts_per_rad else x
            for c, x, jc in zip(counts, self._q, self.joints, strict=True)
        ]
        return SensorSample(self._tick, self._tick * self.dt, tuple(counts), tuple(q_meas),
                            tuple(v_meas), tuple(i_meas), tuple(v_true), tuple(i_true),
                            tuple(self._q), tuple(self._qd), tuple(self._i))  # fmt: skip

    def step_sensors(self, u) -> tuple[list, list, list]:
        """:meth:`step` returning only what the firmware reads: encoder counts (ints),
        period-mean voltage [V] and current [A] as the ADC reports them (lists; the same
        simulation and noise draws as :meth:`step`, without building a SensorSample)."""
        return self._measure(*self._integrate(u))[:3]

    def _integrate(self, u):
        """Advance one period holding ``u``; return what the measurement needs."""
        T = self.dt
        t0 = self._tick * T
        applied = []
        last_sign = self._last_sign
        factor = next(self._supply) if self._supply is not None else 1.0
        for j, ((driven, _, _, _, supply, bits), x) in enumerate(zip(self._drive, u, strict=True)):
            x = pwm_quantise(float(x), supply, bits) * factor if driven else float(x)
            applied.append(x)
            if x != 0.0:
                last_sign[j] = 1.0 if x > 0 else -1.0
        self._configure(applied)
        q_start = list(self._q)
        decay, layer = self._boundary_layer(applied)
        qd_start = list(self._qd)
        if any(self._held):
            self._update_contacts()
        if self.substeps == 1 and self._phase == len(self._change_times):
            # the loop below for one sub-step and no payload change to come
            self._advance((t0 + T) - t0)
            if any(self._held):
                self._update_contacts()
            self._tick += 1
            return applied, q_start, qd_start, decay, layer
        h = T / self.substeps
        for m in range(self.substeps):
            ts, te = t0 + m * h, t0 + (m + 1) * h
            if m == self.substeps - 1:
                te = t0 + T
            while self._phase < len(self._change_times) and self._change_times[self._phase] < te:
                tc = max(self._change_times[self._phase], ts)
                if tc > ts:
                    self._advance(tc - ts)
                    ts = tc
                self._phase += 1
                self._dyn = self._dyns[self._phase]
                self._make_accel()
                if any(self._held):
                    self._update_contacts()
            self._advance(te - ts)
            if any(self._held):
                self._update_contacts()
        self._tick += 1
        return applied, q_start, qd_start, decay, layer

    def _boundary_layer(self, applied):
        """Apply the current transient's impulse; return e^{-T/tau_e} and delta per joint."""
        decay, layer = [0.0, 0.0], [0.0, 0.0]
        if self.open_circuit:
            return decay, layer
        imp = [0.0, 0.0]
        qd, acc, cur = self._qd, self._acc, self._i
        for j, jc in enumerate(self.joints):
            if not jc.driven:
                continue
            d = self._decay[j]
            slow = (applied[j] - jc.ke * (qd[j] - jc.tau_e * acc[j])) / jc.r
            layer[j] = lj = cur[j] - slow
            decay[j] = d
            imp[j] = jc.kt * lj * jc.tau_e * (1.0 - d)
        m11, m12, m22 = self._m
        m11 -= self._a[0]
        m22 -= self._a[1]
        h1, h2 = self._held
        if not h1 and not h2:
            det = m11 * m22 - m12 * m12
            dv = [(imp[0] * m22 - imp[1] * m12) / det, (imp[1] * m11 - imp[0] * m12) / det]
        else:
            dv = [0.0 if h1 else imp[0] / m11, 0.0 if h2 else imp[1] / m22]
        for j in (0, 1):
            if self._held[j] or dv[j] == 0.0:
                continue
            v = self._qd[j] + dv[j]
            if self.joints[j].fc > 0.0 and self._sign[j] * v < 0.0:
                self._qd[j] = 0.0
                self._held[j] = True
                self._make_accel()
            else:
                self._qd[j] = v
        return decay, layer

    def _measure(self, applied, q_start, qd_start, decay, layer):
        """(counts, voltage, current, voltage_true, current_true) at the end of the period
        (lists; see :class:`SensorSample`); updates the current and the cached M."""
        T, noise = self.dt, self.noise
        gauss = self._rng.gauss
        q1, q2 = self._q
        mass = getattr(self._dyn, "mass", None)  # M alone on the fitted 2R evaluator
        self._m = mass(q2) if mass is not None else self._dyn(q1, q2, *self._qd)[:3]
        v_true, i_true, v_meas, i_meas = [], [], [], []
        q, qd, cur, held, acc = self._q, self._qd, self._i, self._held, self._acc
        t_end, drift = self._tick * T, self.current_drift_a_per_s
        for j, (driven, r, te, k, vsense, isense) in enumerate(self._sensing):
            if not driven:
                vm, im = 0.0, 0.0
                cur[j] = 0.0
            elif self.open_circuit:
                vm, im = k * (q[j] - q_start[j]) / T, 0.0
                cur[j] = 0.0
            else:
                v, lj, dj = applied[j], layer[j], decay[j]
                im = (v * T - k * (q[j] - q_start[j])) / r + te * k * (qd[j] - qd_start[j]) / r
                im = (im + lj * te * (1.0 - dj)) / T
                a = acc[j] if not held[j] else 0.0
                cur[j] = (v - k * qd[j]) / r + te * k * a / r + lj * dj
                vm = v
            v_true.append(vm)
            i_true.append(im)
            if drift[j]:  # the sensor's zero, before its ADC
                im += drift[j] * t_end
            if vsense is not None:
                full_range, bits, sigma = vsense
                vm = adc_quantise(vm + (gauss(0.0, sigma) if noise else 0.0), full_range, bits)
            if isense is not None:
                full_range, bits, sigma = isense
                im = adc_quantise(im + (gauss(0.0, sigma) if noise else 0.0), full_range, bits)
            v_meas.append(vm)
            i_meas.append(im)
        if self._single:
            self._count_edges(q1, q2)
            counts = list(self._counts)
        else:
            counts = [math.floor(q1 * self._per_rad[0]), math.floor(q2 * self._per_rad[1])]
        return counts, v_meas, i_meas, v_true, i_true


def encoder_phase_q0(description, seed: int) -> list[float]:
    """Start angles [rad]: each joint at a random point within its first encoder count,
    drawn from ``seed`` (its own stream, independent of the sensor noise's).

    A real robot's counter is zeroed wherever the joint happens to rest, so where the
    motion falls on the count grid differs from run to run; on the grid (q0 = 0) every
    seed of a closed-loop run would share the same quantisation error and the same motion.
    """
    rng = random.Random(f"encoder-phase-{seed}")
    return [
        rng.random() / jc.counts_per_rad if jc.counts_per_rad else 0.0
        for jc in joint_constants(description, friction=True, limits=True)
    ]


def make_plant(description, options) -> Plant:
    """Plant for the fake port from its options (seed, noise, payload_time/mass/com, phase:
    :func:`encoder_phase_q0`, start: :func:`start_pose_q0`, supply and ripple:
    :class:`SupplyVariation`; twin: a :class:`guardid.twin.Twin` run instead of the
    description's rigid body), behind its ``wiring`` faults (:mod:`guardid.plant.wiring`)."""
    from guardid.plant.payload import PayloadChange

    payload = ()
    if getattr(options, "payload_time", None) is not None:
        payload = (PayloadChange(options.payload_time, options.payload_mass,
                                 tuple(options.payload_com)),)  # fmt: skip
    q0 = encoder_phase_q0(description, options.seed) if getattr(options, "phase", False) else None
    if getattr(options, "start", 0.0):
        q0 = start_pose_q0(description, options.seed, options.start)
    supply = SupplyVariation(getattr(options, "supply", 0.0), getattr(options, "ripple", 0.0))
    twin = getattr(options, "twin", None)  # params=: the identified robot (guardid.twin)
    if twin is not None:
        plant = Plant(twin.description, model=twin.model, substeps=twin.substeps,
                      seed=options.seed, noise=options.noise, q0=q0, supply=supply)  # fmt: skip
    else:
        plant = Plant(description, seed=options.seed, noise=options.noise, payload=payload,
                      q0=q0, supply=supply)  # fmt: skip
    return wire(plant, description, getattr(options, "wiring", ()))
