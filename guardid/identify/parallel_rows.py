"""Identification path, acceleration form: the parallel filter, chosen and applied.

Takes the runs conditioned in the acceleration form (:mod:`guardid.identify.acceleration_run`)
at the resolved cut-off [Hz]; gives the parallel filter's cut-off [Hz] chosen from the data
(:func:`chosen_parallel_filter`, by :func:`guardid.identify.cutoff.choose_parallel_filter`'s
rule, or off) and a run's rows after it (:func:`parallel_filtered`: Gautier's filter on
the regressor and the effort, then decimation; :mod:`guardid.conditioning.parallel`).
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from guardid.conditioning.filters import decimation_factor
from guardid.conditioning.parallel import parallel_filter
from guardid.errors import GuardidError
from guardid.identify.acceleration_run import condition_run
from guardid.identify.cutoff import MIN_BLOCKS, ParallelChoice, choose_parallel_filter
from guardid.identify.cutoff_scores import covariance_log_volume, kfold_error
from guardid.identify.equation import smooth_or_frictionless_joints

PARALLEL_EDGE_PERIODS = 3.0
"""The parallel filter spreads the rows at the ends (filter transients, stencil edges) over
about this many of its periods: rows that close to the first-stage's ends are dropped [-]
(the padding of :func:`~guardid.conditioning.filters.zero_phase_lowpass` too)."""


def parallel_filtered(cond, A_all, y, free, hz, decimate=None):
    """Gautier's parallel filter at ``hz`` [Hz] on the regressor and the torque of every
    conditioned sample, then decimation by ``decimate`` (default: new Nyquist >= 2 hz;
    docs/FOREIGN_LOGS.md)."""
    fs = 1.0 / float(np.median(np.diff(cond.t)))
    if not 0.0 < hz < 0.5 * fs:
        raise GuardidError(f"--parallel-filter: {hz:g} Hz must be in (0, {0.5 * fs:g}) Hz")
    sig = (cond.q, cond.qd, cond.qdd, cond.stiction)
    k, (A_all, y, tau, mask, q, qd, qdd, stuck) = parallel_filter(
        fs, hz, A_all, y, cond.tau, cond.mask, *sig, decimate=decimate
    )
    t = cond.t[::k]
    usable = cond.t[cond.mask] if cond.mask.any() else cond.t
    edge = PARALLEL_EDGE_PERIODS / hz
    mask = mask & (t >= usable[0] + edge) & (t <= usable[-1] - edge)
    note = f"parallel filter {hz:.3g} Hz on the regressor and the torque, then decimation by {k}"
    raw = None if cond.tau_raw is None else cond.tau_raw[::k]
    cond = replace(
        cond, t=t, q=q, qd=qd, qdd=qdd, tau=tau, mask=mask, stiction=stuck, tau_raw=raw,
        decimation=cond.decimation * k, notes=[*cond.notes, note],
    )  # fmt: skip
    return cond, A_all[mask], y[mask]


def chosen_parallel_filter(runs, description, used, in_current_units, effort_is_torque, model,
                           free):  # fmt: skip
    """The parallel filter chosen from the data (:func:`choose_parallel_filter`) for the
    runs conditioned under ``used`` (cut-off resolved). Off when some row inside the ends
    was dropped (near zero velocity, stuck): the filter mixes neighbouring samples, so the
    model must hold on every one of them."""
    off_msg = "parallel filter off: rows near zero velocity were dropped"
    if used.stiction_threshold is None and not np.all(smooth_or_frictionless_joints(description)):
        return ParallelChoice(None, f"{off_msg} (sign friction; the filter would mix them "
                              "back in)")  # fmt: skip
    flags = (in_current_units, effort_is_torque, model, free, used.friction_filter)
    fine = [condition_run(r, description, replace(used, decimate=1), used.cutoff_hz, *flags)
            for r in runs]  # fmt: skip
    inside = sum(c.dropped.get(k, 0) for c, *_ in fine for k in c.dropped if "velocity" in k)
    if inside:
        return ParallelChoice(None, f"{off_msg} (the filter would mix them back in)")

    off = [condition_run(r, description, used, used.cutoff_hz, *flags) for r in runs]
    blocks = max(1, -(-MIN_BLOCKS // len(runs)))

    def block_of(t, c):
        span = max(float(c.t[-1] - c.t[0]), 1e-300)
        return np.minimum(((t - c.t[0]) / span * blocks).astype(int), blocks - 1)

    def score(hz):
        if hz is None:
            fits = [(A[c.mask], y[c.mask], c.t[c.mask]) for c, A, y, _, _ in off]
        else:
            k = parallel_decimation(fine[0][0], hz)
            fits = [parallel_filtered(c, A, y, free, hz, k) for c, A, y, _, _ in fine]
            fits = [(A, y, c.t[c.mask]) for c, A, y in fits]
        parts = []
        for (A, y, t), (c, _, _, raw, plain) in zip(fits, off, strict=True):
            fit_block, eval_block = block_of(t, c), block_of(c.t, c)
            for b in range(blocks):
                ev = c.mask & (eval_block == b)
                parts.append((b, A[fit_block == b], y[fit_block == b], plain[ev], raw[ev]))
        held_out, _ = kfold_error(parts, min_rows=3 * len(free))
        A = np.concatenate([f[0] for f in fits])
        y = np.concatenate([f[1] for f in fits])
        return covariance_log_volume(A, y), held_out

    choice = choose_parallel_filter(used.cutoff_hz, score)
    if choice.hz is not None:
        choice.decimate = parallel_decimation(fine[0][0], choice.hz)
    return choice


def parallel_decimation(cond, hz: float) -> int:
    """Decimation after an automatic parallel filter at ``hz`` [Hz]: new Nyquist about
    ``hz``, so that a residual white before the filter stays about white on the kept rows
    (closer rows would be correlated and least squares' std too small)."""
    fs = 1.0 / float(np.median(np.diff(cond.t)))
    return decimation_factor(fs, hz, nyquist_margin=1.0)
