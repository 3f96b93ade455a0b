"""Identification path, acceleration form: every run's rows, cut-off and filter chosen.

Takes the runs (t [s] (N,), q (N, n) [rad | m], effort (N, n) [A | N m | N][, measured qd])
and the options, equation form resolved (:func:`guardid.identify.equation.resolve_equation`);
gives :class:`~guardid.identify.equation.FormRows`: the cut-off [Hz] given or chosen once
for all runs by cross-validation (:func:`guardid.identify.cutoff.choose_cutoff_cv` on
:func:`guardid.identify.cutoff_scores.cutoff_scores`), the parallel filter given or chosen
from the data (:mod:`guardid.identify.parallel_rows`), and per run its usable rows of
tau - known = Y(q, qd, qdd) theta (:func:`guardid.identify.acceleration_run.condition_run`).
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from guardid.identify.acceleration_run import condition_run
from guardid.identify.cutoff import choose_cutoff_cv
from guardid.identify.cutoff_scores import cutoff_scores
from guardid.identify.equation import FormRows
from guardid.identify.parallel_rows import chosen_parallel_filter, parallel_filtered


def acceleration_rows(runs, description, options, why, model, free, in_current_units,
                      effort_is_torque, highest_harmonic_hz) -> FormRows:  # fmt: skip
    """The rows of :func:`guardid.identify.rows.stacked_rows` in the acceleration form
    (module docstring); ``why``: why this form (said in the notes); ``model``, ``free``:
    the description's model and its identified columns."""
    choice = None
    cutoff = options.cutoff_hz
    if cutoff is None:
        fs = 1.0 / float(np.median(np.diff(np.asarray(runs[0][0], dtype=float))))

        def score(cands, blocks):
            return cutoff_scores(runs, description, options, cands, blocks, in_current_units,
                                 effort_is_torque)  # fmt: skip

        choice = choose_cutoff_cv(runs, score, fs, highest_harmonic_hz)
        cutoff = choice.cutoff_hz
    ff = options.friction_filter
    if ff is None:
        ff = bool(choice.friction_filter) if choice is not None else False
    used = replace(options, cutoff_hz=float(cutoff), friction_filter=ff)
    parallel = None
    if options.cutoff_hz is None and options.parallel_filter_hz is None:
        flags = (in_current_units, effort_is_torque, model, free)
        parallel = chosen_parallel_filter(runs, description, used, *flags)
        if parallel.hz is not None:
            used = replace(used, parallel_filter_hz=parallel.hz, decimate=parallel.decimate)
    conds, As, ys = [], [], []
    for run in runs:
        c, A, y, _, _ = condition_run(run, description, used, cutoff, in_current_units,
                                       effort_is_torque, model, free, ff)  # fmt: skip
        if used.parallel_filter_hz:
            c, A, y = parallel_filtered(c, A, y, free, used.parallel_filter_hz, used.decimate)
        else:
            A, y = A[c.mask], y[c.mask]
        conds.append(c)
        As.append(A)
        ys.append(y)
    if choice is not None:
        first = [f"cut-off {cutoff:g} Hz: {choice.reason}"]
    else:
        first = [f"cut-off {cutoff:g} Hz set by the caller"]
    first.append(f"equation: acceleration form ({why})")
    if choice is not None and parallel is not None:
        first.append(parallel.reason)
    return FormRows(conds, As, ys, used, choice, first)
