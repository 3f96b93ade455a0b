"""The parametric bootstrap of the quantisation through the closed loop: K replicas of the
runs (:func:`~guardid.uncertainty.replicas.replica_run`, each from its own sub-count start
pose, on the supply level and ripple measured from the run,
:func:`~guardid.uncertainty.supply.measured_supply`), each fitted as the runs were, their
errors against the simulated parameters.

Mean error ``bias`` (b,) is the quantisation's bias; the covariance of the errors less the
mean covariance the fit reports on them (the part the residuals see, already in the run's
own covariance) is ``persistent`` (b, b), the part that does not shrink with the log's
length. The run's estimate is reported as theta - bias, with the covariance cov + persistent
+ errors' covariance / K (the bias's own sampling error).
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np


@dataclass(frozen=True)
class BootstrapOptions:
    """``replicas``: the most replicas K; ``min_replicas``: the fewest; stop as soon as the
    bias's standard error is below ``tolerance`` x the run's std on every parameter [-];
    ``seed``: the start poses' draws."""

    replicas: int = 16
    min_replicas: int = 4
    tolerance: float = 0.25
    seed: int = 0


@dataclass(frozen=True)
class QuantisationBootstrap:
    """``names`` (p,), ``simulated`` (p,) the values the replicas were simulated with,
    ``errors`` (K, p) each replica's estimate minus ``simulated``, ``covs`` (K, p, p) the
    covariance the fit reported on each replica."""

    names: tuple
    simulated: np.ndarray
    errors: np.ndarray
    covs: np.ndarray

    @property
    def replicas(self) -> int:
        return len(self.errors)

    @property
    def bias(self) -> np.ndarray:
        """(p,) the quantisation's bias [SI]: the replicas' mean error."""
        return self.errors.mean(axis=0)

    @property
    def spread(self) -> np.ndarray:
        """(p, p) the covariance of the replicas' errors."""
        return np.atleast_2d(np.cov(self.errors, rowvar=False, ddof=1))

    @property
    def persistent(self) -> np.ndarray:
        """(p, p) the errors' covariance less the mean covariance the fits report on the
        replicas, its negative eigenvalues set to zero (a covariance)."""
        c = self.spread - self.covs.mean(axis=0)
        w, v = np.linalg.eigh(0.5 * (c + c.T))
        return (v * np.clip(w, 0.0, None)) @ v.T

    def corrected(self, theta) -> np.ndarray:
        """(p,) the run's estimate less the quantisation's bias."""
        return np.asarray(theta, dtype=float) - self.bias

    def covariance(self, cov) -> np.ndarray:
        """(p, p) the corrected estimate's covariance: the run's ``cov`` + the persistent
        part + the bias's sampling covariance (errors' covariance / K)."""
        return np.asarray(cov, dtype=float) + self.persistent + self.spread / self.replicas


def quantisation_bootstrap(
    runs, description, result, method="wls", options=None, identify_options=None, progress=None
) -> QuantisationBootstrap:
    """The bootstrap of ``result`` (an :class:`~guardid.identify.pipeline.Identification`
    of ``runs``) for ``method``'s estimate: replicas until the bias's standard error is
    small (``options``, :class:`BootstrapOptions`), each fitted with ``identify_options``
    (the run's :class:`~guardid.identify.pipeline.IdentifyOptions`) for ``method`` alone
    with the run's resolved conditioning. ``progress(k, K, ratio)`` after each replica
    (ratio: the bias's largest standard error over the run's std, NaN before 2 replicas).
    ConfigError when a run has no setpoints or the robot no ``pid:``; GuardidError when
    the estimate cannot be simulated."""
    from guardid.errors import GuardidError
    from guardid.identify.pipeline import IdentifyOptions, identify
    from guardid.replay import check_replayable
    from guardid.uncertainty.replicas import replica_run, simulated_values
    from guardid.uncertainty.supply import measured_supply

    for run in runs:  # one line before any work: setpoints, ticks, pid: gains
        check_replayable(run, description, "replica")
    options = options or BootstrapOptions()
    fit = result.results[method]
    theta, std = np.asarray(fit.theta, dtype=float), np.asarray(fit.std, dtype=float)
    values = simulated_values(description, result.names, theta)
    base = identify_options or IdentifyOptions()
    fit_options = replace(base, methods=(method,), conditioning=result.conditioning)
    rng = np.random.default_rng(options.seed)
    supplies = [measured_supply(r, description) for r in runs]
    errors, covs = [], []
    for k in range(options.replicas):
        phases = rng.random((len(runs), len(description.joints)))  # of a count, per run
        seeds = rng.integers(0, 2**31, len(runs))
        replicas = [replica_run(r, description, values, ph, s, int(z))
                    for r, ph, s, z in zip(runs, phases, supplies, seeds, strict=True)]  # fmt: skip
        own = identify(replicas, description, fit_options).results[method]
        error, cov = np.asarray(own.theta, dtype=float) - theta, np.asarray(own.cov, dtype=float)
        if not (np.all(np.isfinite(error)) and np.all(np.isfinite(cov))):
            raise GuardidError(f"replica {k + 1}: its fit is not finite (the closed loop "
                               "simulated with the estimate does not move as the log)")  # fmt: skip
        errors.append(error)
        covs.append(cov)
        ratio = float("nan")
        if len(errors) >= 2:
            se = np.std(errors, axis=0, ddof=1) / np.sqrt(len(errors))
            ratio = float(np.max(se / std))
        if progress is not None:
            progress(k + 1, options.replicas, ratio)
        if len(errors) >= options.min_replicas and ratio <= options.tolerance:
            break
    return QuantisationBootstrap(tuple(result.names), theta, np.array(errors), np.array(covs))
