"""The filtered momentum form of the model: one equation per period, nothing differentiated
twice, one linear filter on both sides (DESIGN.md section 5b).

With p = M(q) q' = Y_p(q, q') theta the generalised momentum and Y_r(q, q') theta =
-C(q, q')^T q' + g(q) + friction(q') the rest (:meth:`ChainModel.momentum_regressor`,
:meth:`ChainModel.rest_regressor`), the drive torque integrated over the period k, from tick
k-1 to tick k, is

    impulse_k = Y_p(q_k, q'_k) theta - Y_p(q_(k-1), q'_(k-1)) theta + integral of Y_r theta dt

A guardid log's current at tick k is the mean over (t_(k-1), t_k] (the firmware's
oversampling ADC; :mod:`guardid.firmware.emulator`, :meth:`guardid.plant.plant.Plant._measure`),
so the impulse is gain x i_k x T exactly. The integral: viscous friction is
Fv (q_k - q_(k-1)) exactly, sign-model Coulomb friction Fc T d_k, d_k the direction of
the motion through the period (:func:`period_direction`; the joint moves the same way
through the period: periods near a stop or reversal are cut), the offset Fo T, the rest
(gravity, Coriolis, smooth friction shapes) by the four-point rule
T/24 (-f_(k-2) + 13 f_(k-1) + 13 f_k - f_(k+1)) (fourth order). Velocities at the ticks
come from the raw positions by a central difference (three points); nothing is low-passed
before the regressor. Logs of instantaneous torque samples: the impulse is the same
four-point rule applied to the torque.

The stencil's own error, for a guardid log's voltage-driven motors: the voltage held over
each period makes the net torque, and so the acceleration, step at every tick, and the
three-point difference then errs by T (a_after - a_before) / 4 instead of O(T^2)
(:func:`kink_weights`); within a period the back-EMF makes the current fall as the joint
speeds up, a slope -(D + Fv) a of the net torque (D = N eta Kt N Ke / R, the drive's
electrical damping from the robot description; :func:`slope_weights`). Both momentum
errors are linear: the drive's part moves to the impulse side (:func:`kink_correction`,
:func:`slope_term`), the rest's to the regressor (its period integrals, the Fv column).
The current rises into each voltage step with the motor's L / R rather than at once; the
stencil's error from that lag goes to the impulse side too
(:func:`~guardid.conditioning.electrical_lag.lag_correction`, from the YAML's inductance).
On the plant's true positions and currents this takes the bias left by the stencil from
about 0.1 to below 0.01 of the measured std (``bench/bench_bias_sources.py``).

Then one causal Butterworth low-pass (order :data:`DEFAULT_ORDER`, cut-off chosen by
:func:`momentum_cutoff`) runs over the impulses and over every column alike: a linear
operator applied to both sides keeps the equation exactly. It removes the differenced
velocity quantisation from the momentum columns (and the current noise). The filter runs
per joint over stretches where that joint's equation holds; where it does not (a stuck,
slow or reversing joint, a hard stop, a missing tick) the stretch ends, and the next starts
with the filter at rest; the first :func:`transient_samples` outputs after each start are
dropped (there the first momentum's velocity error weighs as much as all the others). Each
stretch's first period equations ramp in over one time constant of the filter
(:func:`taper_ticks`, :func:`start_ramp`; both sides alike, so the equation stays exact):
the start's momentum is then the mean of that many ticks' momenta, not one tick's, whose
velocity's rounding error, locked to the closed loop's phase at every start of a run, left
a bias growing with the log on a robot whose PID ran every 10 ms (docs/std_residuals.md).
Rows are kept every ``decimate`` periods (about 1 / (2 fc) apart), divided by T (torque
units); a joint whose filtered equation is not valid at a kept instant has a zero row there.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np
from scipy.signal import butter, sosfilt, tf2sos

from guardid.conditioning.electrical_lag import (
    electrical_time_constants,
    error_steps,
    lag_correction,
    lag_weights,
)
from guardid.conditioning.stiction import at_position_limit, default_stiction_threshold
from guardid.errors import GuardidError

EQUATIONS = ("momentum", "acceleration")
DEFAULT_ORDER = 2
"""Order of the momentum form's causal Butterworth filter (DESIGN.md 5b: a first order
passes the velocity noise into the momentum column; 2-3 worked)."""
HARMONIC_FACTOR = 2.0
"""Cut-off = this x the excitation's highest harmonic when it is known (the order-2 filter
passes it at 0.97) [-], and at least :data:`MIN_CUTOFF_HZ`."""
SPECTRUM_FACTOR = 2.0
"""Otherwise this x the positions' 99.5 % energy bandwidth [-]."""
MIN_CUTOFF_HZ = 2.0
"""The cut-off's floor [Hz]. The equation holds at any cut-off; what it trades is the
quantised velocity's noise in the momentum columns (power about fc^3: errors in variables,
a bias that does not shrink with the log) against rows and the closed loop's transients
above the excitation. Measured on the guard robot (24 seeds, 60 s, WLS, worst |bias| / std
over the parameters): default excitation (0.5 Hz) 1 Hz 0.54, 1.5 Hz 0.53, 2 Hz 0.43,
3 Hz 0.75; Schroeder (1 Hz) 1.5 Hz 0.35, 2 Hz 0.19, 3 Hz 0.45, 4 Hz 1.04."""
MARGIN_TICKS = 2
"""Periods are cut this many ticks beyond a stencil's reach of a flagged tick [-]."""
TRANSIENT_RATIO = 0.05
"""After a start, outputs are dropped while the first momentum's weight squared exceeds this
fraction of the steady-state weight of all the others (:func:`transient_samples`) [-]."""
TAPER_TIME_CONSTANTS = 1.0
"""Each stretch's first periods ramp in over this many of the filter's time constants
1 / (2 pi fc) (:func:`taper_ticks`) [-]: the start's momentum becomes the mean of that many
ticks' momenta, whose rounding errors mostly cancel (docs/std_residuals.md, 2026-11-29)."""
QUADRATURE = np.array([-1.0, 13.0, 13.0, -1.0]) / 24.0
"""Four-point rule over ticks k-2 .. k+1 for the integral over (t_(k-1), t_k] [x T]."""
TICKS_CHUNK = 8192
"""Ticks whose full regressors are formed at a time (peak memory of long logs)."""
STENCILS = {3: (np.array([-0.5, 0.0, 0.5]), 1), 5: (np.array([1, -8, 0, 8, -1]) / 12.0, 2)}
"""Central first-difference stencils (coefficients x 1/T, reach in ticks)."""


@dataclass(frozen=True)
class MomentumState:
    """What the momentum rows of one run are made of, for another model's regressor
    (:func:`regressor_rows`): raw tick signals and the rows' construction."""

    q: np.ndarray  # (N, n) positions at the ticks [rad | m]
    measured_v: np.ndarray | None  # (N, n) measured tick velocities [rad/s | m/s]; None:
    # the ``points`` stencil of ``q``, recomputed when needed (no per-tick array kept)
    dt: float  # tick period [s]
    valid: np.ndarray  # (N, n) period k (ending at tick k) usable for joint j
    sos: np.ndarray  # the filter
    skip: int  # outputs dropped after each start
    rows: np.ndarray  # (M,) tick index of each kept row
    row_mask: np.ndarray  # (M, n) filtered equation valid at the row
    kink: int | None = None  # the stencil whose kink correction the rows carry
    points: int = 3  # the velocity stencil (or 5 for measured velocities: rows_like)
    mean_ticks: int = 1  # after ``sos``, the mean of this many ticks (:func:`row_filter`)
    taper: int = 1  # the start ramp's length m (:func:`start_ramp`; 1: no ramp)

    @property
    def v(self) -> np.ndarray:
        """(N, n) tick velocities [rad/s | m/s]: the measured ones, else the stencil's."""
        if self.measured_v is not None:
            return self.measured_v
        return tick_velocity(self.q, self.dt, self.points)[0]


def momentum_cutoff(fs_hz: float, bandwidth_hz: float, from_harmonic: bool) -> float:
    """The filter's cut-off [Hz]: :data:`HARMONIC_FACTOR` x the excitation's highest harmonic
    (``from_harmonic``) or :data:`SPECTRUM_FACTOR` x the positions' energy bandwidth, at
    least :data:`MIN_CUTOFF_HZ`, at most 0.4 x Nyquist."""
    factor = HARMONIC_FACTOR if from_harmonic else SPECTRUM_FACTOR
    return float(min(max(factor * bandwidth_hz, MIN_CUTOFF_HZ), 0.2 * fs_hz))


def decimation(fs_hz: float, cutoff_hz: float) -> int:
    """Rows about 1 / (2 fc) apart [periods]."""
    return max(1, int(fs_hz / (2.0 * cutoff_hz)))


def correlation_ticks(fs_hz: float, cutoff_hz: float) -> int:
    """Rows this many ticks apart or closer share their noise [ticks]: 2 / fc, four of
    :func:`decimation`'s row spacings, over which the causal filter's impulse response
    (order 2: its envelope at 2 / fc is exp(-2 pi sqrt(2)) = 1.4e-4 of its peak) and the
    stencils' reach spread one tick's error; the window over which least squares counts the
    rows' errors as correlated (:class:`~guardid.estimators.LeastSquares`, ``lag_ticks``)."""
    return 4 * decimation(fs_hz, cutoff_hz)


MAX_ROWS = 65536
"""Rows the momentum form keeps at most by default (:func:`row_spacing`) [-]: about 16 min of
ticks at the guard's 15 ms, and about the rows of a 4 h guard log at the spacing 1 / (2 fc).
Beyond, a row every few ticks keeps identify's memory about that of the spaced rows
(issue 30: a 4 h log under 250 MiB); rows a few ticks apart share most of their noise
through the filter, so the longer log's rows at every tick would add little."""


def ticks_needed(n_params: int, window_ticks: int) -> int:
    """Usable ticks a run needs for the std of rows closer than 1 / (2 fc) [ticks]: 2 x the
    fit's parameters x the ``window_ticks`` + 1 over which rows share their noise (what the
    fit takes up of the residuals, about p (L + 1) / ticks, would otherwise pass one half)."""
    return 2 * int(n_params) * (int(window_ticks) + 1)


def tick_count(t_s, dt: float) -> np.ndarray:
    """(N,) int64 each time stamp's tick from the first, (t - t0) / dt rounded half up (not
    numpy's half to even, which would give two stamps half a tick apart one tick)."""
    t = np.asarray(t_s, dtype=float)
    if not t.size:
        return np.zeros(0, np.int64)
    return np.floor((t - t[0]) / dt + 0.5).astype(np.int64)


def row_spacing(ticks: int, fs_hz: float, cutoff_hz: float) -> int:
    """The momentum form's default row spacing [ticks] for a log of ``ticks`` ticks: every
    tick up to :data:`MAX_ROWS` ticks, else every m-th (``ticks`` / MAX_ROWS rounded up),
    never sparser than :func:`decimation`'s 1 / (2 fc)."""
    return int(min(max(1, -(-int(ticks) // MAX_ROWS)), decimation(fs_hz, cutoff_hz)))


def row_filter(cutoff_hz: float, fs_hz: float, order: int, mean_ticks: int = 1) -> np.ndarray:
    """The rows' filter (second-order sections): :func:`filter_sos`, then for ``mean_ticks``
    m > 1 the mean of the last m ticks (an FIR with zeros at the multiples of fs / m: what
    rows m ticks apart would alias onto their band), linear as the Butterworth, so the
    filtered equation holds as exactly."""
    sos = filter_sos(cutoff_hz, fs_hz, order)
    if int(mean_ticks) > 1:
        sos = np.vstack([sos, tf2sos(np.full(int(mean_ticks), 1.0 / int(mean_ticks)), [1.0])])
    return sos


def filter_sos(cutoff_hz: float, fs_hz: float, order: int) -> np.ndarray:
    """The causal Butterworth low-pass (second-order sections)."""
    if not 0.0 < cutoff_hz < 0.5 * fs_hz:
        raise GuardidError(f"cut-off {cutoff_hz:g} Hz must lie in (0, {0.5 * fs_hz:g}) Hz")
    return butter(int(order), cutoff_hz, btype="low", fs=fs_hz, output="sos")


def transient_samples(sos) -> int:
    """Outputs to drop after a start: the first n with h_m^2 <= :data:`TRANSIENT_RATIO` x
    sum_i (h_i - h_(i-1))^2 for every m >= n (h the impulse response; the filtered momentum
    difference weighs the start's momentum by h_m, every later one by h_i - h_(i-1))."""
    n = 1
    while True:
        x = np.zeros(64 * n)
        x[0] = 1.0
        h = sosfilt(sos, x)
        if abs(h[-1]) < 1e-9 * np.abs(h).max() or n > 4096:
            break
        n *= 2
    steady = float(np.sum(np.diff(h, prepend=0.0) ** 2))
    above = np.flatnonzero(h**2 > TRANSIENT_RATIO * steady)
    return int(above[-1]) + 1 if above.size else 0


def taper_ticks(cutoff_hz: float, fs_hz: float) -> int:
    """The start ramp's length m [ticks]: :data:`TAPER_TIME_CONSTANTS` x the filter's time
    constant fs / (2 pi fc), rounded, at least 1 (no ramp)."""
    return max(1, int(round(TAPER_TIME_CONSTANTS * fs_hz / (2.0 * np.pi * cutoff_hz))))


def start_ramp(taper: int) -> np.ndarray:
    """(m - 1,) weights 1/m, 2/m, .., (m-1)/m of a stretch's first m - 1 period equations
    (the later ones weigh 1). Both sides of each period's equation are scaled alike, so
    the equation stays exact; summed over the stretch, the momentum differences then leave
    p_t - mean(p_(s-1) .. p_(s+m-2)) instead of p_t - p_(s-1), s the first period: the
    start's momentum, and its velocity's rounding error, is the mean of m ticks' (the
    three-point velocities' mean over m ticks telescopes to a difference over m + 1
    periods, so that error falls as 1 / m)."""
    return np.arange(1, int(taper), dtype=float) / int(taper)


def _ramped(block, done: int, taper: int):
    """``block`` (L, ...) of a stretch's periods ``done`` .. ``done`` + L - 1, its rows within
    the start ramp scaled by :func:`start_ramp` (a new array then; ``block`` as it is
    otherwise)."""
    w = start_ramp(taper)[int(done) :]
    if not w.size or not len(block):
        return block
    w = w[: len(block)]
    out = np.array(block, dtype=float, copy=True)
    out[: len(w)] *= w.reshape((-1,) + (1,) * (out.ndim - 1))
    return out


def tick_velocity(q, dt: float, points: int = 3):
    """(v (N, n) [unit/s], ok (N,) bool): central difference of the raw positions at the
    ticks; ``ok`` False within the stencil's reach of either end."""
    coef, reach = STENCILS[points]
    n = len(q)
    v = np.zeros_like(q, dtype=float)
    ok = np.zeros(n, dtype=bool)
    if n > 2 * reach:
        inner = sum(c * q[k : n - 2 * reach + k] for k, c in enumerate(coef) if c) / dt
        v[reach : n - reach] = inner
        ok[reach : n - reach] = True
    return v, ok


def kink_weights(points: int = 3) -> tuple[np.ndarray, int]:
    """(W, first): the stencil's velocity error per unit of each period's mean acceleration,
    v_hat_k - v_k = T sum_i W[i] a_mean(period ending at tick k + first + i) [-].

    A motor voltage held over each period makes the acceleration jump at the ticks; the
    difference stencil then errs by about T (a_after - a_before) / 4 (three points)
    instead of the O(T^2) of a smooth motion. Exactly, for an acceleration constant over each
    period: q_(k+m) - q_k - m T v_k = T^2 sum over the periods in between of (m - i + 1/2)
    a_i (m > 0; mirrored for m < 0)."""
    coef, reach = STENCILS[points]
    first = -reach + 1  # periods ending at ticks k - reach + 1 .. k + reach
    W = np.zeros(2 * reach)
    for m_idx, c in enumerate(coef):
        m = m_idx - reach
        if m > 0:
            for i in range(1, m + 1):
                W[i - first] += c * (m - i + 0.5)
        elif m < 0:
            for i in range(m + 1, 1):
                W[i - first] += c * (i - m - 0.5)
    return W, first


def slope_weights(points: int = 3) -> tuple[np.ndarray, int]:
    """(U, first): the stencil's velocity error per unit of each period's acceleration slope,
    v_hat_k - v_k = ... + T^2 sum_i U[i] a'(period ending at tick k + first + i) [-]
    (a linear acceleration over each period: the period-mean part is :func:`kink_weights`').
    A slope a' has the first moment a' T^3 / 12 about its period's start, so U is the
    first-moment weights of :func:`~guardid.conditioning.electrical_lag.lag_weights` / 12."""
    V, first = lag_weights(*STENCILS[points])
    return V / 12.0, first


def slope_term(v, dt: float, points: int = 3) -> np.ndarray:
    """(N, n) [rad | m]: s_k - s_(k-1) with s_k = T sum_i U_i (v_i - v_(i-1))
    (:func:`slope_weights`, v the tick velocities): within a period the held voltage's
    current falls with the back-EMF (and viscous friction grows), so the net torque has a
    slope -(D + Fv) a; the stencil's momentum error from it is (D + Fv) s_k (D the drive's
    electrical damping)."""
    U, first = slope_weights(points)
    dv = np.zeros_like(v)
    dv[1:] = v[1:] - v[:-1]
    return kink_correction(dv, dt, points, U, first)


def kink_correction(torque_mean, dt: float, points: int = 3, W=None, first=None) -> np.ndarray:
    """(N, n) to add to the period impulses [torque x s]: e_k - e_(k-1) with e_k = T sum_i
    W_i tau_i (:func:`kink_weights`, tau_i the drive's period-mean torque): the momentum
    error the stencil's velocity makes at tick k where the drive torque steps at the ticks
    (M a jumps by the drive's jump; the rest of the torque is continuous while the joint
    moves). Zero where the stencil leaves the log (those periods are cut anyway)."""
    if W is None:
        W, first = kink_weights(points)
    return error_steps(torque_mean, W, first, dt)


def electrical_damping(description, gain) -> np.ndarray:
    """(n,) D = gain x N Ke / R per joint: the period-mean effort's loss per unit joint speed
    from the back-EMF [N m s/rad with the gain, A s/rad without] (0 without a drive)."""
    out = np.zeros(len(description.joints))
    for j, joint in enumerate(description.joints):
        d = joint.drive
        if d is not None and d.resistance > 0:
            out[j] = d.gear_ratio * d.ke / d.resistance
    return out * (1.0 if gain is None else np.asarray(gain, dtype=float))


def period_direction(q, v) -> np.ndarray:
    """(N, n) the direction each joint moves through period k (from tick k-1 to tick k):
    the sign of its count change, or, for a period without a count, of the velocities at
    its two ticks (a joint that creeps under a count per period moves on between counts;
    periods where it is stuck or turns are cut, :func:`slow_ticks`). Row 0 is 0."""
    d = np.zeros_like(q)
    d[1:] = np.sign(q[1:] - q[:-1])
    flat = d == 0.0
    flat[0] = False
    d[flat] = np.sign(v[:-1] + v[1:])[flat[1:]]
    return d


def period_regressor(model, q, v, dt: float, kink_points: int | None = None,
                     direction=None) -> np.ndarray:  # fmt: skip
    """Phi (N, n, b) base regressor of the period equations (module docstring): row k is the
    period ending at tick k (rows 0, 1 and N-1 are not defined and are zero).

    ``kink_points``: the velocities come from that stencil and the drive steps at the ticks;
    the stencil's momentum error from the steps of the rest of the torque (its period
    integrals R_k, linear in the parameters) is added, :func:`kink_correction` of R / T, as
    the drive's is to the impulses: together the net torque's steps. ``direction`` (N, n):
    d_k of the Coulomb column, None for :func:`period_direction` of ``q``, ``v``."""
    n_t, n = q.shape
    B = model.base.B
    if direction is None:
        direction = period_direction(q, v)
    exact = np.zeros((n_t, n, B.shape[1]))
    dq = np.zeros_like(q)
    dq[1:] = q[1:] - q[:-1]
    exact_cols = []  # (joint, full-parameter columns integrated exactly)
    for j, joint in enumerate(model.description.joints):
        k = model.friction_index(j)
        if k is None:
            continue
        exact[:, j, :] += np.outer(dq[:, j], B[k])  # viscous: Fv (q_k - q_(k-1))
        exact[:, j, :] += dt * B[k + 2]  # offset: Fo T
        cols = [k, k + 2]
        if joint.friction.model == "sign":  # the joint moves one way through the period
            exact[:, j, :] += np.outer(dt * direction[:, j], B[k + 1])
            cols.append(k + 1)
        exact_cols.append((j, cols))
    p_mom, rest = np.empty_like(exact), np.empty_like(exact)
    for s in range(0, n_t, TICKS_CHUNK):  # per tick; the full-parameter temporaries in chunks
        c = slice(s, s + TICKS_CHUNK)
        mom_full, rest_full = model.momentum_and_rest_regressors(q[c], v[c])
        p_mom[c] = _times(mom_full, B)
        del mom_full
        for j, cols in exact_cols:
            rest_full[:, j, cols] = 0.0
        rest[c] = _times(rest_full, B)
        del rest_full
    out = np.zeros_like(exact)
    if n_t >= 4:
        w = QUADRATURE * dt
        integral = exact  # R_k: the rest's integral over period k
        integral[2:-1] += (w[0] * rest[:-3] + w[1] * rest[1:-2] + w[2] * rest[2:-1]
                           + w[3] * rest[3:])  # fmt: skip
        integral[[0, 1, -1]] = 0.0
        out[1:] = p_mom[1:] - p_mom[:-1]
        out += integral
        if kink_points:
            out += kink_correction(integral / dt, dt, kink_points)
            slope = slope_term(v, dt, kink_points)
            for j in range(n):  # viscous friction's share of the net torque's slope
                k = model.friction_index(j)
                if k is not None:
                    out[:, j, :] += np.outer(slope[:, j], B[k])
        out[[0, 1, -1]] = 0.0
    return out


def _times(Y, B) -> np.ndarray:
    """Y (N, n, P) @ B (P, b) as one matrix product of Y's (N n, P) rows (numpy's 3-d @
    2-d is a product per sample, several times slower; the same numbers)."""
    N, n, P = Y.shape
    return (np.ascontiguousarray(Y).reshape(N * n, P) @ B).reshape(N, n, B.shape[1])


def period_impulse(effort, dt: float, gain, effort_is_torque: bool) -> np.ndarray:
    """(N, n) drive impulse of the period ending at each tick [N m s | N s | effort x s]:
    gain x period-mean current x T, or the four-point rule over torque samples."""
    e = np.asarray(effort, dtype=float)
    if gain is not None:
        e = e * np.asarray(gain, dtype=float)
    if not effort_is_torque:
        return e * dt
    out = np.zeros_like(e)
    w = QUADRATURE * dt
    out[2:-1] = w[0] * e[:-3] + w[1] * e[1:-2] + w[2] * e[2:-1] + w[3] * e[3:]
    return out


def _dilate(bad, before: int, after: int) -> np.ndarray:
    """(N, n): True where ``bad`` (N, n) is True at any of the ticks k - before .. k + after."""
    c = np.concatenate([np.zeros((1, bad.shape[1]), int), np.cumsum(bad, axis=0)])
    n = len(bad)
    hi = np.minimum(np.arange(n) + after + 1, n)
    lo = np.clip(np.arange(n) - before, 0, n)
    return (c[hi] - c[lo]) > 0


def flagged_ticks(q, v, dt, *, threshold, flat_is_stuck, position_limits, resolution=None):
    """(N, n) bool: ticks where a joint's equation does not hold nearby: |v| below
    ``threshold`` (n,) [unit/s] (stuck, reversing), no count in either period next to a
    tick (``flat_is_stuck``, :func:`slow_ticks`), or some joint at a position limit
    (:func:`at_stop`)."""
    bad = slow_ticks(q, v, threshold=threshold, flat_is_stuck=flat_is_stuck)
    if position_limits is not None:
        bad |= at_stop(q, position_limits, resolution)[:, None]
    return bad


def slow_ticks(q, v, *, threshold, flat_is_stuck):
    """(N, n) bool: |v| below ``threshold`` (n,) [unit/s], a reversal of the count
    direction (the ticks between the last count one way and the first the other way: a
    turn through periods without a count included), or (``flat_is_stuck``) no count in
    either period next to a tick (and the ticks either side of it). One period without a
    count is not a stuck joint: a joint that creeps at under a count per period has such
    periods while it moves, and cutting them would choose rows by the rounding's phase (a
    selection that biased the friction pair of a slowly moving joint by about 0.2 std,
    ``bench/bench_std_check.py --sets fast120``); :func:`period_direction` gives them
    their direction. A joint stuck for two periods or more has a tick with no count on
    either side."""
    bad = np.abs(v) < np.asarray(threshold, dtype=float)
    dq = np.diff(q, axis=0)
    if flat_is_stuck:  # no count in either period next to a tick: stuck there
        still = (dq[:-1] == 0.0) & (dq[1:] == 0.0)
        bad[:-2] |= still
        bad[1:-1] |= still
        bad[2:] |= still
    bad[1:-1] |= _turns(dq)
    return bad


def _turns(dq) -> np.ndarray:
    """(N-2, n) bool, ticks 1 .. N-2: the last count change before the tick and the
    first after it have opposite signs (a reversal, at the tick or through the periods
    without a count around it); dq (N-1, n) the count changes."""
    way = np.vstack([np.sign(dq), np.zeros((1, dq.shape[1]))])  # row -1 / N-1: none
    at = np.arange(dq.shape[0])[:, None]
    last = np.maximum.accumulate(np.where(way[:-1] != 0.0, at, -1), axis=0)
    first = np.minimum.accumulate(np.where(way[:-1] != 0.0, at, dq.shape[0])[::-1], axis=0)
    before = np.take_along_axis(way, last[:-1], axis=0)
    after = np.take_along_axis(way, first[::-1][1:], axis=0)
    return before * after < 0.0


def at_stop(q, position_limits, resolution=None) -> np.ndarray:
    """(N,) bool: some joint at (or beyond) a position limit
    (:func:`~guardid.conditioning.stiction.at_position_limit`). The stop's contact torque
    acts on its own joint, but the impact's velocity jump breaks every joint's velocity
    stencil (the momentum couples the joints): every joint is cut there."""
    return at_position_limit(q, position_limits, resolution)


def period_validity(n_t, broken, vel_reach, bad):
    """(N, n) bool: period k usable for joint j: every tick its terms use (k-2-reach ..
    k+1+reach; ``vel_reach`` the velocity stencil's, twice it with the kink correction)
    lies in one unbroken stretch of the log, and no flagged tick of joint j
    lies within that span plus :data:`MARGIN_TICKS`. ``broken`` (N,): the period ending at
    tick k is missing (a lost tick, a gap)."""
    lo, hi = 2 + vel_reach, 1 + vel_reach
    brk = np.zeros((n_t, 1), bool)
    brk[:, 0] = broken
    brk[0] = True  # no period ends at the first tick
    # periods k-lo+1 .. k+hi must all exist
    span_bad = _dilate(brk, hi, lo - 1)[:, 0]
    idx = np.arange(n_t)
    inside = (idx - lo >= 0) & (idx + hi <= n_t - 1)
    ok = inside & ~span_bad
    near = _dilate(bad, lo + MARGIN_TICKS, hi + MARGIN_TICKS)
    return ok[:, None] & ~near


HALO_TICKS = 8
"""Ticks either side of a chunk whose period regressor is formed with it: the four-point
rule and the stencil corrections make a window's first 3 and last 2 rows differ from the
whole log's (a halo of 2 is caught by tests/test_momentum_form.py); 8 leaves room."""


def period_chunks(model, q, v, dt: float, kink_points: int | None = None):
    """:func:`period_regressor` by chunks of :data:`TICKS_CHUNK` ticks: yields (a, b, Phi
    (b - a, n, b') rows a .. b - 1), each chunk formed with :data:`HALO_TICKS` neighbours
    either side (the same numbers as the whole log's, in memory of one chunk)."""
    n_t = len(q)
    for a in range(0, n_t, TICKS_CHUNK):
        b = min(a + TICKS_CHUNK, n_t)
        lo, hi = max(a - HALO_TICKS, 0), min(b + HALO_TICKS, n_t)
        yield a, b, period_regressor(model, q[lo:hi], v[lo:hi], dt, kink_points)[a - lo : b - lo]


def filtered_rows(chunks, imp, valid, sos, skip: int, rows, n_cols: int, mean_ticks: int = 1,
                  taper: int = 1):  # fmt: skip
    """Each joint's valid stretches filtered (at rest at every start, the first ``taper`` - 1
    periods weighted by :func:`start_ramp`, the first ``skip`` outputs dropped), kept at the
    ticks ``rows`` (M,) only: (A (M, n, n_cols) filtered
    regressor, y (M, n) filtered impulses (zero without ``imp``), good (M, n) filtered
    equation valid, transient: valid periods dropped in the filters' starts). The filter:
    ``sos``, then for ``mean_ticks`` m > 1 the mean of the last m outputs (zero before a
    stretch's start), formed at the kept rows only (:func:`row_filter`'s numbers).

    ``chunks`` yields (a, b, Phi (b - a, n, n_cols)) over consecutive ticks
    (:func:`period_chunks`); ``imp`` (N, n) or None; ``valid`` (N, n). The causal filter's
    state (``sosfilt``'s zi) and each stretch's length so far carry across chunk
    boundaries, so the numbers are those of one filter run over each whole stretch."""
    n_t, n = valid.shape
    A = np.zeros((len(rows), n, n_cols))
    y = np.zeros((len(rows), n))
    good = np.zeros((len(rows), n), dtype=bool)
    zi, done = [None] * n, np.zeros(n, dtype=int)  # carried state, stretch length so far
    m = int(mean_ticks)
    tail = [None] * n  # a stretch's last m - 1 outputs, carried into the next chunk
    transient = 0
    out_rows = (A, y, good)
    for a, b, Phi in chunks:
        r0, r1 = np.searchsorted(rows, [a, b])
        for j in range(n):
            v = np.concatenate([[False], valid[a:b, j], [False]])
            starts = np.flatnonzero(~v[:-1] & v[1:])
            ends = np.flatnonzero(v[:-1] & ~v[1:])
            alone = np.zeros(len(starts), dtype=bool)  # filtered on their own: carried state
            if len(starts):
                alone[0] = starts[0] == 0 and zi[j] is not None  # goes on from the last chunk
                alone[-1] |= bool(valid[b - 1, j])  # runs on into the next chunk
            for s, e in zip(starts[alone], ends[alone], strict=True):
                block = (
                    Phi[s:e, j, :]
                    if imp is None
                    else np.column_stack([imp[a + s : a + e, j], Phi[s:e, j, :]])
                )
                if s > 0 or zi[j] is None:  # a new stretch: the filter at rest
                    zi[j], done[j] = np.zeros((len(sos), 2, block.shape[1])), 0
                    tail[j] = np.zeros((m - 1, block.shape[1]))
                block = _ramped(block, done[j], taper)
                out, zi[j] = sosfilt(sos, block, axis=0, zi=zi[j])
                out = np.concatenate([tail[j], out]) if m > 1 else out  # row i + m - 1: tick i
                transient += int(min(e - s, max(skip - done[j], 0)))
                at = np.arange(r0, r1)[(rows[r0:r1] >= a + s) & (rows[r0:r1] < a + e)]
                i = rows[at] - (a + s)
                ok = done[j] + i >= skip
                _keep(out_rows, j, at[ok], _window_mean(out, i[ok], m), imp is not None)
                tail[j] = out[len(out) - (m - 1) :] if m > 1 else None
                done[j] += e - s
            new_s, new_e = starts[~alone], ends[~alone]
            transient += int(np.minimum(new_e - new_s, skip).sum())
            _filter_from_rest(sos, Phi, imp, a, j, new_s, new_e, rows, skip, out_rows, m, taper)
            if not valid[b - 1, j]:  # no stretch runs on into the next chunk
                zi[j] = None
    return A, y, good, transient


def _window_mean(out, i, m: int):
    """The mean of ``out``'s rows i .. i + m - 1 for each i in ``i`` (m = 1: row i), added in
    order (no running sum: no cancellation over long stretches); ``i`` an index array, or
    (rows, lanes) along out's first two axes."""
    rows, rest = (i[0], i[1:]) if isinstance(i, tuple) else (i, ())
    total = out[(rows, *rest)].copy()
    for k in range(1, m):
        total += out[(rows + k, *rest)]
    return total / m if m > 1 else total


def _keep(out_rows, j, at, out, with_imp: bool) -> None:
    """Joint ``j``'s filtered rows ``out`` (m, cols) into rows ``at`` (m,) of (A, y, good)."""
    A, y, good = out_rows
    if with_imp:
        y[at, j] = out[:, 0]
        A[at, j, :] = out[:, 1:]
    else:
        A[at, j, :] = out
    good[at, j] = True


def _filter_from_rest(sos, Phi, imp, a, j, starts, ends, rows, skip, out_rows, m=1,
                      taper=1) -> None:  # fmt: skip
    """Joint ``j``'s stretches ``starts`` .. ``ends`` (chunk ticks, from ``a``) of a chunk,
    each filtered from rest with nothing carried out, many in one ``sosfilt`` call: the
    stretches side by side, zero-padded to a common length per power of two of their
    lengths (a causal filter's outputs do not depend on what follows, and each lane's
    arithmetic is that of its own call); their kept rows past ``skip`` into ``out_rows``,
    each the mean of its last ``m`` outputs (:func:`filtered_rows`)."""
    if not len(starts):
        return
    lens = ends - starts
    lo, hi = np.searchsorted(rows, a + starts), np.searchsorted(rows, a + ends)
    width = np.ceil(np.log2(lens)).astype(int)
    cols = Phi.shape[2] + (imp is not None)
    for w in np.unique(width):
        sel = np.flatnonzero(width == w)
        X = np.zeros((int(lens[sel].max()), len(sel), cols))
        for lane, k in enumerate(sel.tolist()):
            s, e = int(starts[k]), int(ends[k])
            if imp is None:
                X[: e - s, lane] = Phi[s:e, j, :]
            else:
                X[: e - s, lane, 0] = imp[a + s : a + e, j]
                X[: e - s, lane, 1:] = Phi[s:e, j, :]
        X = _ramped(X, 0, taper)  # every lane starts at its row 0
        out = sosfilt(sos, X, axis=0)
        if m > 1:  # each lane from rest: zeros before its start
            out = np.concatenate([np.zeros((m - 1, *out.shape[1:])), out])
        count = hi[sel] - lo[sel]
        first = np.repeat(lo[sel] - np.cumsum(count) + count, count)
        at = first + np.arange(int(count.sum()))  # the kept rows of every lane, in order
        lane = np.repeat(np.arange(len(sel)), count)
        i = rows[at] - (a + starts[sel][lane])
        ok = i >= skip
        _keep(out_rows, j, at[ok], _window_mean(out, (i[ok], lane[ok]), m), imp is not None)


def rows_like(state: MomentumState, model, q) -> np.ndarray:
    """The filtered period regressor (M, n, b) [torque units] of positions ``q`` (N, n) on
    the ticks, cuts, filter and kept rows of ``state`` (velocities from ``q`` by the same
    stencil): a simulated run's rows aligned with the measured one's."""
    v, _ = tick_velocity(q, state.dt, state.points)
    return regressor_rows(replace(state, q=q, measured_v=v), model)


def regressor_rows(state: MomentumState, model) -> np.ndarray:
    """The filtered period regressor (M, n, b) of ``model`` on the rows of ``state`` (another
    parameter set's model scored on the same rows) [torque units]."""
    chunks = period_chunks(model, state.q, state.v, state.dt, state.kink)
    A, _, _, _ = filtered_rows(chunks, None, state.valid, state.sos, state.skip, state.rows,
                               model.base.B.shape[1], state.mean_ticks, state.taper)  # fmt: skip
    return A * state.row_mask[:, :, None] / state.dt


def condition_momentum(t_s, q, effort, model, *, gain, cutoff_hz: float, order: int = DEFAULT_ORDER,
                       decimate: int | None = None, effort_is_torque: bool = False,
                       stiction_threshold=None, flat_is_stuck: bool = False,
                       position_limits=None, points: int | None = None,
                       velocity=None, mean_ticks: int = 1):  # fmt: skip
    """One run in the momentum form: (Conditioned, Phi (M, n, b) filtered base regressor of
    all base columns [torque units], y (M, n) filtered drive torque) on every ``decimate``-th
    tick (default about 1 / (2 fc) apart); the usable rows are ``cond.mask``, each joint's
    ``cond.joint_mask`` (a zero row where a joint's equation is cut).

    ``t_s`` (N,) tick times [s] (steps other than the median one are cuts: lost ticks,
    gaps); ``q`` (N, n) raw positions [rad | m]; ``effort`` (N, n) period-mean motor current
    [A] (``effort_is_torque``: instantaneous torque samples [N m | N]); ``gain`` (n,) torque
    per effort unit or None (current units). ``stiction_threshold``: per joint [unit/s]
    (NaN: 5 % of the joint's peak speed; 0: never flagged by speed); ``flat_is_stuck``: a
    tick without an encoder count in either adjacent period flags it (:func:`slow_ticks`);
    ``position_limits`` (n, 2) or None.
    ``velocity`` (N, n) [unit/s]: measured joint velocities, used instead of the difference
    stencil (``points``: 3, or 5; default 3 with its corrections for a period-mean current,
    5 for torque samples, whose motion is smooth). ``mean_ticks`` > 1: the filter is
    followed by the mean of that many consecutive ticks (:func:`row_filter`), both sides
    alike, so that rows ``decimate`` ticks apart do not fold the noise above their Nyquist
    rate into the regressor's band.
    """
    from guardid.conditioning.pipeline import Conditioned

    t = np.asarray(t_s, dtype=float)
    q = np.asarray(q, dtype=float).reshape(len(t), -1)
    effort = np.asarray(effort, dtype=float).reshape(q.shape)
    n_j = q.shape[1]
    steps = np.diff(t)
    dt = float(np.median(steps))
    fs = 1.0 / dt
    broken = np.zeros(len(t), dtype=bool)
    broken[1:] = np.abs(steps - dt) > 1e-6 * dt
    if points is None:  # torque samples: smooth motion, the fourth-order stencil
        points = 5 if effort_is_torque else 3
    if velocity is None:
        v, vel_ok = tick_velocity(q, dt, points)
        reach = STENCILS[points][1]
        how = f"{points}-point central difference of the raw positions"
    else:
        v, reach = np.asarray(velocity, dtype=float).reshape(q.shape), 0
        vel_ok = np.ones(len(t), dtype=bool)
        how = "measured"
    for k in np.flatnonzero(broken):  # no stencil across a cut
        vel_ok[max(k - reach, 0) : k + reach] = False
    base_thr = default_stiction_threshold(v[vel_ok] if vel_ok.any() else v)
    thr = base_thr
    if stiction_threshold is not None:
        given = np.broadcast_to(np.asarray(stiction_threshold, float), base_thr.shape)
        thr = np.where(np.isnan(given), base_thr, given)
    slow = slow_ticks(q, v, threshold=thr, flat_is_stuck=flat_is_stuck)
    stop = np.zeros(len(t), dtype=bool)
    if position_limits is not None:
        stop = at_stop(q, position_limits)
    bad = slow | stop[:, None]
    kink = points if velocity is None and not effort_is_torque else None  # steps at ticks
    span = 2 * reach if kink else reach  # the kink correction reaches one stencil further
    valid = period_validity(len(t), broken, span, bad)
    cut = ~period_validity(len(t), broken, span, np.zeros_like(bad))  # ends, gaps
    cut_slow = ~period_validity(len(t), broken, span, slow) & ~cut
    cut_stop = ~valid & ~cut & ~cut_slow
    sos = filter_sos(cutoff_hz, fs, order)  # then the mean (filtered_rows, at the rows)
    skip = transient_samples(row_filter(cutoff_hz, fs, order, mean_ticks))
    taper = taper_ticks(cutoff_hz, fs)
    k = decimation(fs, cutoff_hz) if decimate is None else int(decimate)
    imp = period_impulse(effort, dt, gain, effort_is_torque)
    if kink:
        damping = electrical_damping(model.description, gain)
        drive = imp / dt  # the drive's period-mean torque
        imp = imp + kink_correction(drive, dt, points)
        imp = imp - damping * slope_term(v, dt, points)
        imp = imp + lag_correction(drive, q, dt, *STENCILS[points],
                                   electrical_time_constants(model.description), damping,
                                   broken)  # fmt: skip
    rows = np.arange(0, len(t), k)
    if mean_ticks > 1:  # on the tick count, not the samples: a lost tick does not shift them
        rows = np.flatnonzero(tick_count(t, dt) % k == 0)
    chunks = period_chunks(model, q, v, dt, kink)  # only the kept rows' filtered values stay
    A, y, jm, transient = filtered_rows(chunks, imp, valid, sos, skip, rows, model.base.B.shape[1],
                                        mean_ticks, taper)  # fmt: skip
    A *= jm[:, :, None] / dt  # in place: at every tick A is the run's largest array
    y = y * jm / dt
    mask = np.any(jm, axis=1)
    qdd = np.zeros((len(rows), n_j))  # central difference of v, at the kept rows only
    inner = (rows > 0) & (rows < len(t) - 1)
    qdd[inner] = (v[rows[inner] + 1] - v[rows[inner] - 1]) / (2.0 * dt)
    state = MomentumState(q, None if velocity is None else v, dt, valid, sos, skip, rows, jm,
                          kink, points if velocity is None else 5, int(mean_ticks),
                          taper)  # fmt: skip
    share = 100.0 * valid.sum(0) / max(len(t), 1)
    notes = [
        f"cut-off {cutoff_hz:.3g} Hz",
        "equation: filtered momentum (impulse per period = momentum change + integral of "
        f"the rest; causal Butterworth order {order} at {cutoff_hz:.3g} Hz on both sides, "
        f"{skip} periods dropped after each start, the first {taper - 1} weighted 1/{taper} "
        f"to {taper - 1}/{taper})",
        f"velocities at the ticks: {how}",
        "periods usable per joint: "
        + ", ".join(f"{s:.0f} %" for s in share)
        + f" (stiction threshold {np.array2string(thr, precision=4)}, stencil reach "
        f"+ {MARGIN_TICKS} ticks)",
    ]
    if broken[1:].any():
        notes.append(f"{int(broken[1:].sum())} missing or uneven tick steps: cut there")
    if stop.any():
        notes.append(f"{int(stop.sum())} samples at a position limit (hard stop): every "
                     "joint's periods near them cut")  # fmt: skip
    if k > 1:
        notes.append(f"decimated by {k}: {fs / k:.4g} Hz")
    dropped = {  # joint periods, in rows (/ decimation)
        "at the ends or a gap (stencils)": int(round(cut.sum() * n_j / k)),
        "near zero velocity": int(round(cut_slow.sum() / k)),
        "at or next to a hard stop": int(round(cut_stop.sum() / k)),
        "in the filter's start after a cut": int(round(transient / k)),
    }
    cond = Conditioned(
        t[rows], q[rows], v[rows], qdd, y, mask, np.any(bad[rows], axis=1),
        np.asarray(thr, dtype=float), float(cutoff_hz), k,
        "N m" if gain is not None else "effort", notes, None, int(np.any(bad, axis=1).sum()),
        dropped, joint_mask=jm, equation="momentum", momentum=state,
    )  # fmt: skip
    return cond, A, y


QUANTISATION_DRAWS = 1
"""Independent draws of the encoder's rounding error per window (:func:`quantisation_noise`)
[-]: one gives each moment to a few % over the rows of 16 384 ticks (the correction it
scales is itself a fraction of a std), at two passes of the regressor per window."""
QUANTISATION_WINDOW_TICKS = 2048
"""Ticks per window of :func:`quantisation_noise` [-]."""
QUANTISATION_WINDOWS = 8
"""At most this many windows, evenly spread over the run (a run no longer than them all is
one window) [-]: the noise's moments come from at most 16 384 ticks, so the cost does not
grow with the log."""
QUANTISATION_SEED = 0
"""The draws' seed: the same log gives the same estimate [-]."""


def on_grid(q, resolution) -> np.ndarray:
    """(n,) bool: joint j's positions lie on a grid of ``resolution`` (n,) [rad | m] steps
    (whole encoder counts from any offset): every one within 1 % of a step of it."""
    r = np.asarray(q, dtype=float) / np.asarray(resolution, dtype=float)
    if not len(r):
        return np.zeros(r.shape[1], dtype=bool)
    off = (r - r[:1] + 0.5) % 1.0 - 0.5  # whole steps from the first position
    return np.all(np.abs(off) <= 0.01, axis=0)


def quantisation_noise(state: MomentumState, model, resolution, damping, *,
                       draws: int = QUANTISATION_DRAWS,
                       window_ticks: int = QUANTISATION_WINDOW_TICKS,
                       windows: int = QUANTISATION_WINDOWS,
                       seed: int = QUANTISATION_SEED):  # fmt: skip
    """The columns' noise from the encoder's rounding, on the run's rows (``state``): (S (n,
    b, b) with S_j = E[dA_j^T dA_j], c (n, b) with c_j = E[dA_j^T dy_j], both summed over
    joint j's usable rows) [in the units of A^T A and A^T y of :func:`condition_momentum`'s
    rows], b all base columns of ``model``.

    The rows' positions are whole counts: q = q_true + e, e uniform over a step
    ``resolution`` (n,) [rad | m] and independent from tick to tick where the joint moves
    (slower ticks are cut). That e runs through the velocity stencil into the momentum,
    Coriolis and friction columns (and, through the back-EMF slope term with ``damping``
    (n,) D [torque units x s/rad], into y): errors in the variables, which bias least
    squares by about S theta however long the log. The moments are estimated by adding
    fresh draws of such e to the counts and forming the rows again (their difference is
    the noise, to first order in e: the stencils and filter are linear, the rest smooth),
    on ``windows`` windows of ``window_ticks`` ticks evenly spread over the run (each cut
    at its ends like a gap), scaled per joint by the run's usable rows over the windows'.
    Each draw keeps every period's direction (:func:`period_direction` of the counts): the
    rounding does not turn the joint. (Drawing e instead by rounding the plant's true
    trajectory afresh, with a random offset per draw, gave the same estimates to 0.03 std on
    a slowly moving joint: docs/std_residuals.md.)"""
    q, valid = state.q, state.valid
    n_t, n = q.shape
    res = np.asarray(resolution, dtype=float)
    damping = np.asarray(damping, dtype=float)
    n_b = model.base.B.shape[1]
    tau_e = electrical_time_constants(model.description)
    S, c = np.zeros((n, n_b, n_b)), np.zeros((n, n_b))
    counted = np.zeros(n)
    rng = np.random.default_rng(seed)
    width, count = int(window_ticks), int(windows)
    if n_t <= width * count:  # the whole run as one window
        width, count = n_t, 1
    starts = np.linspace(0, n_t - width, count).round().astype(int)
    edge = HALO_TICKS  # a window's first and last ticks: the stencils leave it there
    for a in starts.tolist():
        b = a + width
        q_w = q[a:b]
        valid_w = valid[a:b].copy()
        valid_w[:edge] = False
        valid_w[-edge:] = False
        at = (state.rows >= a) & (state.rows < b)
        rows_w = state.rows[at] - a
        mask_w = state.row_mask[at]
        v_w = tick_velocity(q_w, state.dt, state.points)[0]
        way = period_direction(q_w, v_w)  # the rounding does not turn the joint
        base = period_regressor(model, q_w, v_w, state.dt, state.kink, way)
        for _ in range(int(draws)):
            q_e = q_w + (rng.random(q_w.shape) - 0.5) * res
            v_e = tick_velocity(q_e, state.dt, state.points)[0]
            d_phi = period_regressor(model, q_e, v_e, state.dt, state.kink, way) - base
            d_imp = np.zeros_like(q_w)
            if state.kink:
                d_imp = -damping * slope_term(v_e - v_w, state.dt, state.kink)
                d_imp += lag_correction(np.zeros_like(q_w), q_e - q_w, state.dt,
                                        *STENCILS[state.kink], tau_e, damping)  # fmt: skip
            dA, dy, good, _ = filtered_rows([(0, width, d_phi)], d_imp, valid_w, state.sos,
                                            state.skip, rows_w, n_b, state.mean_ticks,
                                            state.taper)  # fmt: skip
            good &= mask_w
            dA = dA * good[:, :, None] / state.dt
            dy = dy * good / state.dt
            S += np.einsum("mja,mjb->jab", dA, dA) / draws
            c += np.einsum("mja,mj->ja", dA, dy) / draws
        counted += good.sum(axis=0)
    scale = np.where(counted > 0, state.row_mask.sum(axis=0) / np.maximum(counted, 1), 0.0)
    return S * scale[:, None, None], c * scale[:, None]
