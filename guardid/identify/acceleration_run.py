"""Identification path, acceleration form: one run conditioned, and its equation rows.

Takes a run (t [s] (N,), q (N, n) [rad | m], effort (N, n) [A | N m | N][, measured qd]),
the options and a cut-off [Hz]; gives its conditioned signals
(:func:`guardid.conditioning.condition`: zero-phase low-pass, twice differentiated,
period-mean current aligned and turned into torque, rows near stiction and hard stops
masked, decimated) and the equation rows tau - known = Y(q, qd, qdd) theta on every
conditioned sample: A (M, n, b') the identified base-regressor columns, y (M, n)
[N m | N | effort unit]. Used for the final rows (:mod:`guardid.identify.acceleration_rows`),
for scoring the cut-off candidates (:mod:`guardid.identify.cutoff_scores`) and the parallel
filter (:mod:`guardid.identify.parallel_rows`), and for the simulated closed loop's rows
(:mod:`guardid.closedloop.rows`).
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from guardid.conditioning import condition
from guardid.conditioning.filters import DEFAULT_ORDER, decimation_factor, zero_phase_lowpass
from guardid.conditioning.stiction import guard_periods
from guardid.identify.equation import (
    effort_gain,
    friction_columns,
    position_limits,
    smooth_friction_joints,
)

STICTION_GUARD_SHARE = 0.95
"""guardid logs: rows closer to a stuck / reversing sample than the span that holds this
share of the low-pass's impulse response are dropped (stick/slip of the PID-tracked joints
smeared by the filter; :func:`~guardid.conditioning.stiction.guard_periods`: 1.04 cut-off
periods at order 4). Measured on the guard robot (``bench/bench_std_check.py``, 20 seeds):
0.6 periods left the pan's Fv1 and Fc1 biased by 1.3-1.4 std on the default excitation;
this guard, 0.4-0.5 std, at the price of a third of the rows (std about 1.3x larger). The
Coulomb columns low-passed like the effort with a narrower guard did worse there."""
STOP_GUARD_SHARE = 0.99
"""Rows closer to a sample at a joint's position limit (a hard stop: contact force and
impact, not in the model) than the span holding this share are dropped (about 1.75 cut-off
periods at order 4). Applies to every log whose robot has position limits."""
STICTION_GUARD_PERIODS = guard_periods(DEFAULT_ORDER, STICTION_GUARD_SHARE)
"""The stiction guard at the default order [cut-off periods] (for callers)."""


def condition_kwargs(options, fs_hz, cutoff_hz, effort_is_torque, description) -> dict:
    """Keyword arguments of :func:`guardid.conditioning.condition` for ``options`` with the
    cut-off ``cutoff_hz`` [Hz] (every automatic choice resolved; see ConditioningOptions)."""
    o = options
    kw = {"cutoff_hz": float(cutoff_hz), "order": o.order, "edge_s": o.edge_s}
    if effort_is_torque:
        kw["align_period_mean"] = False
    guard = o.stiction_guard_s
    if guard is None:
        guard = (
            0.0 if effort_is_torque else guard_periods(o.order, STICTION_GUARD_SHARE) / cutoff_hz
        )
    kw["stiction_guard_s"] = guard
    limits = position_limits(description)
    if limits is not None:
        kw["position_limits"] = limits
        kw["stop_guard_s"] = guard_periods(o.order, STOP_GUARD_SHARE) / cutoff_hz
    kw["flat_is_stuck"] = (not effort_is_torque) if o.flat_is_stuck is None else o.flat_is_stuck
    if o.decimate is not None:
        kw["decimate"] = o.decimate
    elif effort_is_torque:
        kw["decimate"] = decimation_factor(fs_hz, cutoff_hz)
    else:
        kw["decimate"] = max(1, int(fs_hz / (2.0 * cutoff_hz)))
    if o.parallel_filter_hz:
        kw["decimate"] = 1  # decimation happens after the parallel filter
    if o.stiction_threshold is not None:
        kw["stiction_threshold"] = o.stiction_threshold
    else:  # smooth friction holds through zero velocity: keep those joints' rows
        kw["stiction_threshold"] = np.where(smooth_friction_joints(description), 0.0, np.nan)
    return kw


ROWS_CHUNK = 32768
"""Samples whose regressor is formed at a time in :func:`_rows_of` (its temporaries, the
full regressor before the base projection, stay a few tens of MB on long logs)."""


def _rows_of(model, description, cond, free, in_current_units, mask=None):
    """(A (M, n, b'), y (M, n), y_raw (M, n)) on the rows of ``mask`` (default all)."""
    m = slice(None) if mask is None else mask
    q, qd, qdd, tau = cond.q[m], cond.qd[m], cond.qdd[m], cond.tau[m]
    tau_raw = None if cond.tau_raw is None else cond.tau_raw[m]
    A = y = raw = None
    for s in range(0, max(len(q), 1), ROWS_CHUNK):  # per sample: the same values in chunks
        c = slice(s, s + ROWS_CHUNK)
        A_c, y_c, raw_c = _rows_chunk(model, q[c], qd[c], qdd[c], tau[c],
                                      None if tau_raw is None else tau_raw[c], free,
                                      in_current_units)  # fmt: skip
        if A is None:
            if len(q) <= ROWS_CHUNK:
                return A_c, y_c, raw_c
            A = np.empty((len(q), *A_c.shape[1:]))
            y = np.empty((len(q), *y_c.shape[1:]))
            raw = None if raw_c is None else np.empty((len(q), *raw_c.shape[1:]))
        A[c], y[c] = A_c, y_c
        if raw is not None:
            raw[c] = raw_c
    return A, y, raw


def _rows_chunk(model, q, qd, qdd, tau, tau_raw, free, in_current_units):
    A_all = model.base_regressor(q, qd, qdd)
    known = model.known_torque(q, qd, qdd)
    fixed = [i for i in range(A_all.shape[2]) if i not in free]
    if fixed and not in_current_units:
        known = known + A_all[:, :, fixed] @ model.base.values(model.params)[fixed]
    raw = None if tau_raw is None else tau_raw - known
    return A_all[:, :, free], tau - known, raw


def condition_run(run, description, options, cutoff_hz, in_current_units, effort_is_torque,
                   model, free, friction_filter=False, fallback=True):  # fmt: skip
    """One run (t, q, effort[, qd]) conditioned under ``options`` at ``cutoff_hz`` [Hz]:
    (conditioned signals, A (M, n, b'), y (M, n), y_raw (M, n), A_plain (M, n, b')) on every
    conditioned (decimated) sample; the usable rows are ``cond.mask``.

    With ``friction_filter`` the regressor is computed on every sample before decimation;
    its Coulomb (and Stribeck) columns are low-passed with the same zero-phase filter as the
    effort: the filtered effort carries the friction jump at a reversal smeared over about a
    cut-off period, and so does the column then (parallel filtering of the one strongly
    nonlinear term). ``A_plain`` is the regressor without that (the model's prediction).
    Falls back to no stiction guard when the guard would leave too few rows (3 per
    identified parameter; said in the notes), unless ``fallback`` is False (the cut-off's
    cross-validation: a candidate that keeps too few rows with the guard is not eligible,
    rather than scored on rows the friction model does not hold on).
    """
    t, q, effort, *rest = run
    t = np.asarray(t, dtype=float)
    fs = 1.0 / float(np.median(np.diff(t)))
    kw = condition_kwargs(options, fs, cutoff_hz, effort_is_torque, description)
    k = kw.pop("decimate")
    gain = effort_gain(description, in_current_units, effort_is_torque)
    kw["qd_measured"] = rest[0] if rest else None
    cols = friction_columns(model, free)
    full_rate = bool(cols and friction_filter)  # those columns are filtered at every sample

    def conditioned(k):
        """The run conditioned at every sample; with k > 1 and no column to filter only
        every k-th sample is kept (the regressor is per sample: the same rows, and the
        full-rate signals and regressor, k times larger, are never held)."""
        every = k if k > 1 and not full_rate else 1
        return condition(t, q, effort, gain=gain, decimate=1, keep_every=every, **kw), every

    cond, every = conditioned(k)
    if (fallback and (cond.mask if every > 1 else cond.mask[::k]).sum() <= 3 * len(free)
            and options.stiction_guard_s is None and not effort_is_torque):  # fmt: skip
        kw.update(stiction_guard_s=0.0, flat_is_stuck=False)
        if options.decimate is None and not options.parallel_filter_hz:
            k = decimation_factor(fs, cutoff_hz)
        cond, every = conditioned(k)
        cond.notes.append("too few rows with the stiction guard: guard disabled")
    A, y, raw = _rows_of(model, description, cond, free, in_current_units)
    plain = A
    if cols and friction_filter:
        A = A.copy()
        block = A[:, :, cols]
        flat = zero_phase_lowpass(block.reshape(len(block), -1), fs, cutoff_hz, options.order)
        A[:, :, cols] = flat.reshape(block.shape)
        cond.notes.append("Coulomb columns low-passed like the effort")
    if k > 1:
        fields = ("t", "q", "qd", "qdd", "tau", "mask", "stiction", "tau_raw")
        dropped = {key: int(round(v / k)) for key, v in cond.dropped.items()}
        kept = {} if every > 1 else {f: _kept(getattr(cond, f), k) for f in fields}
        cond = replace(
            cond, decimation=k, **kept, dropped=dropped,
            notes=[*cond.notes, f"decimated by {k}: {fs / k:.4g} Hz"],
        )  # fmt: skip
        if every == 1:
            A, y, raw, plain = A[::k], y[::k], raw[::k], plain[::k]
    return cond, A, y, raw, plain


def _kept(x, k):
    """Every k-th row of ``x`` as its own array (the full-rate one can then be freed)."""
    return None if x is None else np.ascontiguousarray(x[::k])
