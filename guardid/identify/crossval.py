"""``guardid identify --cv``: leave-one-run-out cross-validation over the given runs.

Each run (log file) is held out once: the others are identified together (default
conditioning, the cut-off chosen from them alone), and every method's estimate predicts the
held-out run's effort under that same conditioning. A run split at a long gap
(:mod:`guardid.identify.segments`) stays one fold: its segments are conditioned separately
and held out together (segments of one recording are not independent of each other). The
score is the stacked relative rms error over all joints, rms(tau - tau_model) / rms(tau)
(:mod:`guardid.identify.validation`).
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from guardid.identify.checks import call_naming_logs
from guardid.identify.pipeline import identify
from guardid.identify.rows import stacked_rows
from guardid.identify.segments import split_runs
from guardid.identify.validation import ParameterSet, _run_tuple, score_sets


def fold_scores(runs, description, options):
    """Per held-out run: (cut-off [Hz], {method: stacked relative rms error [-]}) of
    ``options`` (:class:`~guardid.identify.pipeline.IdentifyOptions`)."""
    methods, current_units = options.methods, options.in_current_units
    torque = bool(runs[0].torque)
    cutoff_hz = _cutoff(options)
    out = []
    for i, held in enumerate(runs):
        # the cut-off is chosen from the training runs' data alone (no header hint)
        train = [replace(r, highest_harmonic_hz=None) for k, r in enumerate(runs) if k != i]
        train = split_runs(train, cutoff_hz, description=description).runs  # segments as runs
        files = list(dict.fromkeys(r.source or r.path for r in train))
        result = call_naming_logs(files, identify, train, description, options)
        nominal = dict(zip(result.names, result.nominal, strict=True))
        sets = []
        for m in methods:
            values = _all_base_values(description, nominal)
            values.update(dict(zip(result.names, result.results[m].theta, strict=True)))
            sets.append(ParameterSet(m.upper(), values, description))
        from guardid.identify.current_zero import subtract_zeros
        from guardid.identify.prepare import current_on_adc_levels

        held = current_on_adc_levels(held, description)  # scored on what the fit reads
        (held,), _ = subtract_zeros([held], description, options.current_zero)
        parts = split_runs([held], cutoff_hz, description=description).runs  # the same rule
        conds = [
            stacked_rows(
                [_run_tuple(part)], description, result.conditioning,
                in_current_units=current_units, effort_is_torque=torque,
            ).cond
            for part in parts
        ]  # fmt: skip
        scores = score_sets(conds, sets, [p.path for p in parts], current_units)
        out.append((result.conditioning.cutoff_hz, _stacked_per_set(scores)))
    return out


def _cutoff(options) -> float | None:
    """The cut-off given in ``options`` [Hz] (None: chosen from the data)."""
    return options.conditioning.cutoff_hz if options.conditioning is not None else None


def _stacked_per_set(scores) -> dict:
    """{method: stacked relative rms error [-]} over every scored run (segments of one
    held-out file pooled: sum of squared residuals over sum of squared efforts)."""
    num, den = {}, {}
    for s in scores:
        key = s.label.lower()
        num[key] = num.get(key, 0.0) + s.stacked**2 * s.ref2
        den[key] = den.get(key, 0.0) + s.ref2
    return {k: float(np.sqrt(num[k] / den[k])) if den[k] > 0 else float("nan") for k in num}


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
    split = split_runs(runs, _cutoff(options), description=description)
    if split.gaps or split.jumps:
        lines.append("a run split at a gap is one fold (its segments held out together):")
        lines += [f"warning: {w}" for w in split.lines()]
    return "\n".join(lines)
