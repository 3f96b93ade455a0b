"""``guardid identify --cv``: leave-one-run-out cross-validation over the given runs.

Each run is held out once: the others are identified together (default conditioning, the
cut-off chosen from them alone), and every method's estimate predicts the held-out run's
effort under that same conditioning. The score is the stacked relative rms error over all
joints, rms(tau - tau_model) / rms(tau) (:mod:`guardid.identify.validation`).
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from guardid.identify.pipeline import identify
from guardid.identify.rows import stacked_rows
from guardid.identify.validation import ParameterSet, _run_tuple, score_sets


def fold_scores(runs, description, options):
    """Per held-out run: (cut-off [Hz], {method: stacked relative rms error [-]}) of
    ``options`` (:class:`~guardid.identify.pipeline.IdentifyOptions`)."""
    methods, current_units = options.methods, options.in_current_units
    torque = bool(runs[0].torque)
    out = []
    for i, held in enumerate(runs):
        # the cut-off is chosen from the training runs' data alone (no header hint)
        train = [replace(r, highest_harmonic_hz=None) for k, r in enumerate(runs) if k != i]
        result = identify(train, description, options)
        nominal = dict(zip(result.names, result.nominal, strict=True))
        sets = []
        for m in methods:
            values = _all_base_values(description, nominal)
            values.update(dict(zip(result.names, result.results[m].theta, strict=True)))
            sets.append(ParameterSet(m.upper(), values, description))
        cond = stacked_rows(
            [_run_tuple(held)], description, result.conditioning,
            in_current_units=current_units, effort_is_torque=torque,
        ).cond  # fmt: skip
        scores = score_sets([cond], sets, [held.path], current_units)
        out.append((result.conditioning.cutoff_hz, {s.label.lower(): s.stacked for s in scores}))
    return out


def _all_base_values(description, identified):
    from guardid.dynamics import build_model

    model = build_model(description)
    values = dict(zip(model.base.names, model.base.values(model.params), strict=True))
    values.update(identified)
    return values


def leave_one_run_out(logs, runs, description, options) -> str:
    """The ``--cv`` table: one line per held-out log, then the mean over the folds."""
    methods = options.methods
    folds = fold_scores(runs, description, options)
    width = max(len(str(x)) for x in logs) + 2
    head = f"{'held-out run':{width}s} {'cut-off':>8s}" + "".join(
        f" {m.upper():>9s}" for m in methods
    )
    lines = [
        "leave-one-run-out: fit on the other runs, stacked relative rms error on the held-out one",
        head,
    ]
    for log, (fc, sc) in zip(logs, folds, strict=True):
        cells = "".join(f" {100 * sc[m]:8.2f}%" for m in methods)
        lines.append(f"{str(log):{width}s} {fc:6.3g}Hz{cells}")
    mean = "".join(f" {100 * np.mean([sc[m] for _, sc in folds]):8.2f}%" for m in methods)
    lines.append(f"{'mean':{width}s} {'':8s}{mean}")
    return "\n".join(lines)
