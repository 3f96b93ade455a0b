"""``identify --quantisation-bootstrap K``: the bootstrap applied to an identification's
reference method (its estimate corrected, its covariance widened; the figures recorded in
the method's settings, written to params.yaml)."""

from __future__ import annotations

import numpy as np

from guardid.errors import GuardidError


def apply_bootstrap(result, runs, description, identify_options, options, progress=None):
    """Correct ``result``'s reference method (WLS, else LS) in place with the bootstrap of
    ``runs``; '' when done, else one phrase why it cannot run (a log without setpoints, a
    robot without ``pid:``, an estimate the closed loop cannot be simulated with)."""
    from guardid.identify.untrusted import reference_method
    from guardid.uncertainty.bootstrap import quantisation_bootstrap

    method = reference_method(result.results)
    if method is None or result.results[method].cov is None:
        return "no method with a covariance (wls or ls) among --method"
    if any(r.torque for r in runs):
        return "the effort is measured torque, not a guardid log's motor current"
    fit = result.results[method]
    try:
        bs = quantisation_bootstrap(runs, description, result, method, options,
                                    identify_options, progress)  # fmt: skip
        cov = bs.covariance(fit.cov)
    except GuardidError as exc:
        return str(exc).removeprefix("replica: ")
    except np.linalg.LinAlgError:
        return "the replicas' errors give no covariance"
    before = np.diag(fit.cov).copy()
    fit.theta, fit.cov = bs.corrected(fit.theta), cov
    fit.std = np.sqrt(np.diag(cov))
    fit.rel_std_pct = 100.0 * fit.std / np.maximum(np.abs(fit.theta), 1e-300)
    repeating = fit.settings.get("repeating_residual", {})
    if "variance_share" in repeating:  # the repeating part's variance over the wider total
        with np.errstate(divide="ignore", invalid="ignore"):
            share = np.asarray(repeating["variance_share"]) * before / np.diag(cov)
        repeating["variance_share"] = [round(float(x), 4) for x in np.nan_to_num(share)]
    fit.settings["quantisation_bootstrap"] = {
        "replicas": bs.replicas,
        "bias_removed": [float(x) for x in bs.bias],
        "persistent_std": [float(x) for x in np.sqrt(np.diag(bs.persistent))],
    }
    return ""
