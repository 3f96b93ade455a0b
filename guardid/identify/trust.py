"""Results a user can trust: physically impossible estimates flagged, a bounded fit, and
estimators whose fit is much worse than least squares' marked as not converged.

* Impossible values: negative viscous, Coulomb or Stribeck friction (Fv, Fc, Fs), negative
  reflected rotor inertia (Ia), and a mass matrix M(q) that is not positive definite at
  some sample of the data. M(q) is rebuilt from the base parameters through the regressor:
  column i of M(q) = Y(q, 0, e_i) theta - Y(q, 0, 0) theta (gravity and offsets cancel).
* ``bls``: WLS with its error model (the rows' correlated and repeating errors, the
  encoder's rounding removed: the verdict's fit), then, where it breaks a lower bound 0 on
  Fv, Fc, Fs or Ia, the point inside the bounds nearest to it in its own covariance's metric
  (min (theta - theta_w)^T C^-1 (theta - theta_w), theta >= lower: scipy's ``lsq_linear``
  on the whitened problem; the bounded maximum-likelihood estimate under the fit's normal
  approximation). Its covariance is WLS's: the projection onto a convex set that holds the
  truth brings the estimate no further from it in that metric. Within the bounds it is WLS.
* Not converged: an estimator whose in-sample stacked relative rms error exceeds
  :data:`NOT_CONVERGED_RATIO` x least squares' (and LS's plus 1 percentage point).
"""

from __future__ import annotations

import numpy as np
from scipy.optimize import lsq_linear

from guardid.estimators._base import as_blocks

NOT_CONVERGED_RATIO = 1.5
NONNEGATIVE_PREFIXES = ("Fv", "Fc", "Fs", "Ia")
MAX_MASS_SAMPLES = 400


def lower_bounds(names) -> np.ndarray:
    """Lower bound per base parameter: 0 for friction and rotor inertia, else -inf."""
    return np.array([0.0 if n.startswith(NONNEGATIVE_PREFIXES) else -np.inf for n in names])


def stacked_error(A, y, theta) -> float:
    """rms(y - A theta) / rms(y) over every row and joint stacked [-]."""
    A3, y2 = as_blocks(A, y)
    r = y2 - A3 @ np.asarray(theta, dtype=float)
    return float(np.sqrt(np.mean(r**2) / np.mean(y2**2)))


class BoundedLeastSquares:
    """WLS with ``lower`` bounds (b,) (module docstring); ``wls_options``: the keywords of
    :class:`~guardid.estimators.WeightedLeastSquares` (the rows' error model).

    Attributes after ``fit``: ``theta_``, ``cov_`` (WLS's), ``std_``, ``rel_std_`` [%],
    ``active_`` (bool (b,), a bound holds), ``wls_`` the unbounded fit.
    """

    def __init__(self, lower, **wls_options):
        self.lower = np.asarray(lower, dtype=float)
        self.wls_options = wls_options

    def fit(self, A, y):
        from guardid.estimators import WeightedLeastSquares

        wls = self.wls_ = WeightedLeastSquares(**self.wls_options).fit(A, y)
        theta, cov = np.asarray(wls.theta_, dtype=float), np.asarray(wls.cov_, dtype=float)
        lower = np.where(np.isfinite(self.lower), self.lower, -np.inf)
        if np.any(theta < lower):
            theta = _nearest_inside(theta, cov, lower)
        self.theta_, self.cov_, self.std_ = theta, cov, np.asarray(wls.std_, dtype=float)
        self.rel_std_ = 100 * self.std_ / np.maximum(np.abs(theta), 1e-300)
        self.active_ = np.isfinite(lower) & (theta <= lower)
        return self


def _nearest_inside(theta, cov, lower) -> np.ndarray:
    """argmin (x - theta)^T cov^-1 (x - theta) subject to x >= lower (b,), solved on the
    correlation matrix (each parameter in units of its std, so that scales many decades
    apart do not decide which directions count); a direction the covariance gives (nearly)
    no variance is held all the stiffer (its eigenvalue floored at 1e-12 of the largest,
    never dropped). ``theta`` clipped at the bounds when there is no metric: a covariance
    that is not finite (a fit too short for its error model), a zero std, or an estimate
    that is not finite."""
    var = np.diag(cov) if np.all(np.isfinite(cov)) else np.zeros(len(theta))
    if not (np.all(var > 0) and np.all(np.isfinite(theta))):
        return np.maximum(theta, lower)
    std = np.sqrt(var)
    corr = cov / np.outer(std, std)
    vals, vecs = np.linalg.eigh(0.5 * (corr + corr.T))
    vals = np.maximum(vals, vals.max() * 1e-12)
    white = (vecs / np.sqrt(vals)).T / std[None, :]  # cov^-1/2
    sol = lsq_linear(white, white @ theta, bounds=(lower, np.full_like(lower, np.inf)),
                     method="bvls")  # fmt: skip
    return np.maximum(sol.x, lower)  # on the bound exactly where it holds


def mark_not_converged(results, ls) -> list[str]:
    """Set ``converged`` False on results whose in-sample fit is much worse than LS's."""
    out = []
    ref = results["ls"].d_stacked if "ls" in results else None
    if ref is None:
        return out
    for m, r in results.items():
        if m == "ls":
            continue
        if r.d_stacked > max(NOT_CONVERGED_RATIO * ref, ref + 0.01):
            r.converged = False
            out.append(
                f"{m.upper()}: not converged: in-sample error {100 * r.d_stacked:.1f} % against "
                f"LS's {100 * ref:.1f} % (its values are not an equal of LS's)"
                + (f"; why: {r.settings['why_not_converged']}"
                   if r.settings.get("why_not_converged") else "")
            )  # fmt: skip
    return out


def mass_matrix_columns(model, free, q) -> tuple[np.ndarray, np.ndarray]:
    """(M_fixed (K, n, n), M_k (K, n, n, b)) at the rows q (K, n): M(q) is linear in the
    base values, M = M_fixed + sum_k theta_k M_k, theta the values of the columns ``free``
    (M_fixed from the model's values of the others), each column of M the regressor at unit
    acceleration of one joint less the regressor at rest."""
    n = q.shape[1]
    zero = np.zeros_like(q)
    at_rest = model.base_regressor(q, zero, zero)
    cols = []
    for i in range(n):
        e = np.zeros_like(q)
        e[:, i] = 1.0
        cols.append(model.base_regressor(q, zero, e) - at_rest)
    per = np.stack(cols, axis=2)  # (K, n, n, B): row j, column i, base column
    fixed = model.base.values(model.params)
    fixed[free] = 0.0
    return per @ fixed, per[..., free]


def mass_matrix_along(model, free, theta, q, in_current_units=False) -> np.ndarray:
    """M(q) (K, n, n) at the rows q (K, n) from the identified base values ``theta``."""
    fixed, per = mass_matrix_columns(model, free, q)
    return fixed + per @ np.asarray(theta, dtype=float)


def impossible_values(model, free, names, ls, cond, in_current_units=False) -> list[str]:
    """Warnings for physically impossible LS estimates (module docstring)."""
    out = []
    for k, name in enumerate(names):
        if name.startswith(NONNEGATIVE_PREFIXES) and ls.theta_[k] < 0:
            what = "rotor inertia" if name.startswith("Ia") else "friction"
            out.append(
                f"{name} = {ls.theta_[k]:.4g} +- {ls.std_[k]:.2g}: negative {what} is physically "
                "impossible (try --method bls, a bounded fit that keeps it >= 0)"
            )
    if in_current_units or not len(cond.q):
        return out
    step = max(1, len(cond.q) // MAX_MASS_SAMPLES)
    q = cond.q[::step]
    M = mass_matrix_along(model, free, ls.theta_, q)
    eig = np.linalg.eigvalsh(0.5 * (M + np.swapaxes(M, 1, 2)))
    bad = int(np.sum(eig[:, 0] <= 0))
    if bad:
        out.append(
            f"the identified mass matrix is not positive definite at {bad} of {len(q)} sampled "
            f"rows (smallest eigenvalue {eig[:, 0].min():.3g}): the estimates are not physically "
            "consistent"
        )
    return out
