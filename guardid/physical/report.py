"""The consistent fit beside identification's: rows, table, params.yaml section."""

from __future__ import annotations

import numpy as np

from guardid.errors import GuardidError
from guardid.estimators import d_tau
from guardid.identify.pipeline import MethodResult, identify
from guardid.identify.rows import stacked_rows
from guardid.physical.fit import BIAS_PER_STD, ConsistentFit, fit_consistent

METHOD = "consistent"
"""Key of the consistent fit in ``Identification.results`` and params.yaml's ``methods``."""


def add_consistent(result, runs, description, effort_is_torque=False):
    """Fit the consistent model on ``result``'s rows and add it as ``results['consistent']``.

    ``runs``: [(t [s], q [rad], effort)] of the runs given to
    :func:`guardid.identify.identify`, which made ``result``: conditioned under
    ``result.conditioning`` (the options identify used, cut-off resolved). Returns the
    :class:`ConsistentFit`.
    """
    if result.torque_unit != "N m":
        raise GuardidError(
            "--consistent: the fit is in current units (no torque gain): "
            "physical parameters need torque"
        )
    _, A, y = stacked_rows(
        runs, description, result.conditioning, effort_is_torque=effort_is_torque
    )
    fit = fit_consistent(A, y, description)
    result.results[METHOD] = MethodResult(
        method=METHOD,
        theta=fit.base,
        d_tau=float(d_tau(A, y, fit.base)),
        d_tau_per_joint=np.asarray(d_tau(A, y, fit.base, per_joint=True)),
        settings={"fit": fit},
    )
    return fit


def identify_consistent(runs, description, options=None):
    """:func:`guardid.identify.identify` plus the consistent fit: (Identification, fit).

    Same arguments: a list of :class:`~guardid.identify.runs.Run`, the description and the
    :class:`~guardid.identify.pipeline.IdentifyOptions`.
    """
    from guardid.identify.prepare import prepared_runs

    result = identify(runs, description, options)
    runs, _, _ = prepared_runs(runs, description, options)  # the runs identify conditioned
    efforts = [(r.t, r.q, r.current) for r in runs]
    return result, add_consistent(result, efforts, description, bool(runs[0].torque))


def standard_table(fit: ConsistentFit) -> str:
    """The full consistent standard set beside the YAML's (text, SI units)."""
    lines = [f"{'standard':10s} {'YAML':>12s} {'CONSISTENT':>12s}"]
    for name, prior, value in zip(fit.names, fit.prior, fit.standard, strict=True):
        lines.append(f"{name:10s} {prior:12.5g} {value:12.5g}")
    lines.append(
        f"consistent fit: prior weight w^2 {fit.prior_weight:.3g} = {BIAS_PER_STD:g} x "
        f"sqrt(lambda_min {fit.lambda_min:.3g}) (scaled units); d_tau {100 * fit.d_tau:.2f} %; "
        + ("every link physically consistent" if not fit.violations else "NOT CONSISTENT")
    )
    return "\n".join(lines)


def yaml_section(fit: ConsistentFit) -> dict:
    """params.yaml's ``consistent`` mapping: the standard set and how it was fitted."""
    return {
        "standard_parameters": [
            {"name": n, "value": float(v), "yaml_value": float(p)}
            for n, v, p in zip(fit.names, fit.standard, fit.prior, strict=True)
        ],
        "prior_weight": fit.prior_weight,
        "lambda_min": fit.lambda_min,
        "bias_per_std": BIAS_PER_STD,
        "violations": list(fit.violations),
        "solver": fit.message,
    }
