"""The offline entry point :func:`condition` and its result :class:`Conditioned`."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from guardid.conditioning import alignment
from guardid.conditioning.bandwidth import choose_cutoff
from guardid.conditioning.filters import (
    DEFAULT_ORDER,
    central_derivatives,
    decimation_factor,
    is_uniform,
    resample,
    uniform_grid,
    zero_phase_lowpass,
)
from guardid.conditioning.stiction import (
    at_position_limit,
    default_stiction_threshold,
    stiction_mask,
)
from guardid.conditioning.units import current_to_torque


@dataclass(frozen=True)
class Conditioned:
    """Conditioned signals, all (M, n) on the same instants ``t`` (M,) [s].

    q [rad], qd [rad/s], qdd [rad/s^2], tau [N m, or the effort's unit when
    ``torque_unit == 'effort'``]. ``mask`` (M,) bool is True for rows usable for
    identification (not near zero velocity, not within ``stiction_guard_s`` of such a
    sample and not within ``edge_s`` of either end);
    ``stiction`` (M,) bool is True where some joint's |qd| < ``threshold`` (n,) [rad/s].
    ``cutoff_hz`` [Hz] and ``decimation`` (k) are the values used; ``notes`` say how
    each choice was made. ``tau_raw`` (M, n) is the effort in tau's unit at the same instants
    before the low-pass (aligned and resampled only): the measured signal a model must predict.
    ``n_flagged`` counts the original samples flagged near zero velocity.
    ``equation``: "acceleration" (these signals and the regressor Y(q, qd, qdd)) or
    "momentum" (:mod:`guardid.conditioning.momentum`: ``tau`` is the filtered drive torque
    of the period equations, ``joint_mask`` (M, n) which joint's equation each row holds,
    ``momentum`` what the rows are made of; q and qd are the raw tick values, qdd their
    difference, for plots and inputs).
    """

    t: np.ndarray
    q: np.ndarray
    qd: np.ndarray
    qdd: np.ndarray
    tau: np.ndarray
    mask: np.ndarray
    stiction: np.ndarray
    threshold: np.ndarray
    cutoff_hz: float
    decimation: int
    torque_unit: str
    notes: list[str] = field(default_factory=list)
    tau_raw: np.ndarray | None = None
    n_flagged: int = 0
    dropped: dict = field(default_factory=dict)
    joint_mask: np.ndarray | None = None
    equation: str = "acceleration"
    momentum: object | None = None


def condition(
    t_s,
    q_rad,
    effort,
    *,
    cutoff_hz: float | None = None,
    decimate: int | None = None,
    stiction_threshold=None,
    align_period_mean: bool = True,
    gain=None,
    highest_harmonic_hz: float | None = None,
    resolution_rad=None,
    order: int = DEFAULT_ORDER,
    edge_s: float | None = None,
    stiction_guard_s: float = 0.0,
    flat_is_stuck: bool = False,
    qd_measured=None,
    position_limits=None,
    stop_guard_s: float = 0.0,
    keep_every: int = 1,
) -> Conditioned:
    """Condition a log for identification: filter, differentiate, align, decimate, mask.

    Parameters
    ----------
    t_s : array_like (N,)
        Sample times [s], strictly increasing; may jitter (then everything is resampled by
        cubic spline onto a uniform grid with the median step before filtering).
    q_rad : array_like (N, n)
        Joint positions [rad] (see :func:`counts_to_rad` for encoder counts).
    effort : array_like (N, n)
        Motor current [A] (or joint torque [N m] with ``gain=1``).
    cutoff_hz : float, optional
        Low-pass cut-off [Hz]; default from the trajectory (:func:`choose_cutoff`, using
        ``highest_harmonic_hz`` if given).
    decimate : int, optional
        Keep every k-th sample after filtering; default: the largest k keeping the new
        Nyquist frequency >= 2 x cutoff; 1 = no decimation.
    stiction_threshold : scalar or (n,) [rad/s], optional
        Default: :func:`default_stiction_threshold` (5 % of peak speed, at least 3
        encoder quanta per sample period if ``resolution_rad`` [rad] is given); a NaN entry
        takes the default for that joint, 0 keeps every row of that joint.
    align_period_mean : bool
        True (guard firmware): effort[k] is the mean over (t_{k-1}, t_k]; it is turned
        into the value at t_k (:func:`align_period_mean`). False: instantaneous samples.
    gain : scalar, (n,) [N m/A], a ChainDescription (N eta kt of its drives) or None
        tau = gain * effort; None keeps the effort unit (identification in current units,
        ``torque_unit == 'effort'``).
    order : int
        Butterworth order (zero-phase: applied forward and backward).
    edge_s : float, optional
        Rows within this time [s] of either end are masked (filter and stencil end
        effects); default one cut-off period, 1 / cutoff_hz.
    stiction_guard_s : float
        Also mask rows within this time [s] of a flagged (stuck or reversing) sample
        (default 0). The low-pass smears the friction jump of a reversal and the holding
        torque of a stuck joint (Karnopp stick/slip: friction is then whatever balances the
        drive, not Fc sign(qd)) over about half a cut-off period on either side, so rows
        that close to a flagged sample do not obey the friction model either.
    flat_is_stuck : bool
        Also flag samples whose raw position equals the previous (or next) one (no encoder
        count in a period: the joint is held or reverses). Only used on uniform time stamps.
    position_limits : array_like (n, 2), optional
        Joint position limits [rad | m] (NaN = none). Samples at (or beyond) a limit rest
        against a hard stop (:func:`~guardid.conditioning.stiction.at_position_limit`): the
        contact force, and the impact on arrival, are not in the model. They are masked, and
        so are the rows within ``stop_guard_s`` [s] of them.
    keep_every : int
        With ``decimate=1``: return only every k-th sample of the outputs (their own arrays,
        so a long log's full-rate ones are freed), everything else as without it (the
        masks, ``n_flagged`` and ``dropped`` counted on every sample, no decimation note):
        the result of ``decimate=1`` followed by slicing ``[::k]``.

    The same zero-phase low-pass is applied to positions and efforts (parallel
    filtering), so both sides of tau = Y(q, qd, qdd) theta see the same filter; q, qd, qdd
    and tau all refer to the instants ``t``.
    """
    t = np.asarray(t_s, dtype=float)
    q = np.asarray(q_rad, dtype=float).reshape(len(t), -1)
    eff = np.asarray(effort, dtype=float).reshape(len(t), -1)
    if q.shape != eff.shape:
        raise ValueError(f"q {q.shape} and effort {eff.shape} must have the same shape")
    notes: list[str] = []
    flat = None
    if is_uniform(t):
        grid, dt = t, float(np.median(np.diff(t)))
        if flat_is_stuck:
            same = np.zeros(q.shape, dtype=bool)
            same[1:] = q[1:] == q[:-1]
            same[:-1] |= same[1:]
            flat = np.any(same, axis=1)
    else:
        grid, dt = uniform_grid(t)
        q = _by_column(lambda x: resample(t, x, grid), q)
        notes.append(f"uneven time stamps: resampled (cubic spline) to a uniform {dt:.6g} s grid")
    fs = 1.0 / dt
    if cutoff_hz is None:
        cutoff_hz = choose_cutoff(grid, q, highest_harmonic_hz=highest_harmonic_hz)
        how = "8 x highest harmonic" if highest_harmonic_hz else "2 x 99.5 % energy bandwidth"
        notes.append(f"cut-off {cutoff_hz:.3g} Hz chosen from the trajectory ({how})")
    else:
        notes.append(f"cut-off {cutoff_hz:.3g} Hz set by the caller")
    if align_period_mean:
        eff = _by_column(lambda m: alignment.align_period_mean(t, m, grid), eff)
        notes.append("effort taken as period means, aligned to the tick instants")
    elif grid is not t:
        eff = _by_column(lambda x: resample(t, x, grid), eff)

    def lowpass(x):
        return zero_phase_lowpass(x, fs, cutoff_hz, order)

    qf = _by_column(lowpass, q)
    tau = _by_column(lowpass, eff)
    raw = eff
    qd = _by_column(lambda x: central_derivatives(x, dt)[0], qf)
    qdd = _by_column(lambda x: central_derivatives(x, dt)[1], qf)
    if qd_measured is not None:
        vel = np.asarray(qd_measured, dtype=float).reshape(len(t), -1)
        if grid is not t:
            vel = _by_column(lambda x: resample(t, x, grid), vel)
        qd = _by_column(lowpass, vel)
        qdd = _by_column(lambda x: central_derivatives(x, dt)[0], qd)
        notes.append("measured velocities used (low-passed alike), qdd differentiated from them")
    if gain is None:
        unit = "effort"
        notes.append("gain=None: tau is the filtered effort (identification in current units)")
    else:
        tau = current_to_torque(tau, gain)
        raw = current_to_torque(raw, gain)
        unit = "N m"
    threshold = default_stiction_threshold(qd, resolution_rad=resolution_rad, sample_period_s=dt)
    if stiction_threshold is not None:
        given = np.broadcast_to(np.asarray(stiction_threshold, float), qd.shape[1:])
        threshold = np.where(np.isnan(given), threshold, given)
    stuck = stiction_mask(qd, threshold)
    if flat is not None:
        stuck = stuck | flat
    n_flagged, n_total = int(stuck.sum()), len(stuck)
    guard = int(round(float(stiction_guard_s) / dt))
    near = _dilate(stuck, guard) if guard > 0 else stuck
    at_stop = near_stop = np.zeros(len(stuck), dtype=bool)
    if position_limits is not None:
        at_stop = at_position_limit(q, position_limits)  # raw positions on the grid
        stop_guard = int(round(float(stop_guard_s) / dt))
        near_stop = _dilate(at_stop, stop_guard) if stop_guard > 0 else at_stop
        if at_stop.any():
            notes.append(
                f"{int(at_stop.sum())} samples at a position limit (hard stop)"
                + (f", rows within {stop_guard * dt:.3g} s of them masked" if stop_guard else "")
            )
    edge = 1.0 / cutoff_hz if edge_s is None else float(edge_s)
    inside = (grid >= grid[0] + edge) & (grid <= grid[-1] - edge)
    k = decimation_factor(fs, cutoff_hz) if decimate is None else int(decimate)
    if k > 1:
        notes.append(f"decimated by {k}: {fs / k:.4g} Hz, Nyquist {fs / (2 * k):.4g} Hz")
    sl = slice(0, None, k)
    if k > 1:  # own arrays: the full-rate ones are freed
        grid, qf, qd, qdd, tau, raw = (
            np.ascontiguousarray(x[sl]) for x in (grid, qf, qd, qdd, tau, raw)
        )
        stuck, near, inside = stuck[sl], near[sl], inside[sl]
        at_stop, near_stop = at_stop[sl], near_stop[sl]
    dropped = {
        "at the ends (filter transients)": int((~inside).sum()),
        "near zero velocity": int((inside & stuck).sum()),
        "next to a near-zero-velocity sample": int((inside & near & ~stuck).sum()),
        "at or next to a hard stop": int((inside & ~near & near_stop).sum()),
    }
    if k == 1 and keep_every > 1:  # the counts above stay those of every sample
        sl = slice(0, None, int(keep_every))
        grid, qf, qd, qdd, tau, raw = (
            np.ascontiguousarray(x[sl]) for x in (grid, qf, qd, qdd, tau, raw)
        )
        stuck, near, inside = stuck[sl], near[sl], inside[sl]
        at_stop, near_stop = at_stop[sl], near_stop[sl]
    how = " or with no encoder count" if flat is not None else ""
    notes.append(
        f"stiction threshold {np.array2string(threshold, precision=4)} rad/s{how}: "
        f"{n_flagged} of {n_total} samples flagged"
        + (f", rows within {guard * dt:.3g} s of them masked" if guard > 0 else "")
    )
    return Conditioned(
        grid,
        qf,
        qd,
        qdd,
        tau,
        inside & ~near & ~near_stop,
        stuck,
        np.array(threshold),
        float(cutoff_hz),
        k,
        unit,
        notes,
        raw,
        n_flagged,
        dropped,
    )


def _by_column(fn, x) -> np.ndarray:
    """``fn`` (N, 1) -> (M, 1) applied to each column of ``x`` (N, n) in turn, into one (M, n)
    array: the same values (every step filters or differentiates each column on its own)
    with the temporaries of one column at a time (peak memory of a long log)."""
    x = np.asarray(x, dtype=float)
    if x.ndim != 2 or x.shape[1] == 1:
        return fn(x)
    out = None
    for j in range(x.shape[1]):
        col = fn(x[:, j : j + 1])
        if out is None:
            out = np.empty((col.shape[0], x.shape[1]))
        out[:, j] = col[:, 0]
        del col
    return out


def _dilate(mask: np.ndarray, half_width: int) -> np.ndarray:
    """True where ``mask`` is True within ``half_width`` samples (boolean (N,))."""
    idx = np.flatnonzero(mask)
    out = np.zeros_like(mask)
    if idx.size:
        diff = np.zeros(mask.size + 1, dtype=int)
        np.add.at(diff, np.maximum(idx - half_width, 0), 1)
        np.add.at(diff, np.minimum(idx + half_width + 1, mask.size), -1)
        out = np.cumsum(diff[:-1]) > 0
    return out
