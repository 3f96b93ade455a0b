"""Results a user can trust: physically impossible estimates flagged, a bounded fit, and
estimators whose fit is much worse than least squares' marked as not converged.

* Impossible values: negative viscous, Coulomb or Stribeck friction (Fv, Fc, Fs), negative
  reflected rotor inertia (Ia), and a mass matrix M(q) that is not positive definite at
  some sample of the data. M(q) is rebuilt from the base parameters through the regressor:
  column i of M(q) = Y(q, 0, e_i) theta - Y(q, 0, 0) theta (gravity and offsets cancel).
* ``bls``: scipy's ``lsq_linear`` with lower bounds 0 on Fv, Fc, Fs and Ia (a bounded
  least-squares fit that keeps them feasible); its standard deviations are least squares'
  formula at the bounded solution (an approximation where a bound is active).
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
    """Least squares with ``lower`` bounds (b,) (scipy.optimize.lsq_linear, columns scaled).

    Attributes after ``fit``: ``theta_``, ``std_``, ``rel_std_`` [%], ``active_`` (bool (b,),
    a bound holds).
    """

    def __init__(self, lower):
        self.lower = np.asarray(lower, dtype=float)

    def fit(self, A, y):
        A3, y2 = as_blocks(A, y)
        M = A3.reshape(-1, A3.shape[2])
        v = y2.reshape(-1)
        scale = np.sqrt(np.sum(M**2, axis=0))
        scale[scale == 0] = 1.0
        lo = np.where(np.isfinite(self.lower), self.lower * scale, -np.inf)
        sol = lsq_linear(M / scale, v, bounds=(lo, np.full_like(lo, np.inf)), method="bvls")
        self.theta_ = sol.x / scale
        r = v - M @ self.theta_
        dof = max(len(v) - len(self.theta_), 1)
        cov = float(r @ r) / dof * np.linalg.pinv(M.T @ M)
        self.std_ = np.sqrt(np.clip(np.diag(cov), 0, None))
        self.rel_std_ = 100 * self.std_ / np.maximum(np.abs(self.theta_), 1e-300)
        self.active_ = np.isfinite(self.lower) & (self.theta_ <= self.lower + 1e-12 * scale.max())
        return self


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


def mass_matrix_along(model, free, theta, q, in_current_units=False) -> np.ndarray:
    """M(q) (K, n, n) at the rows q (K, n) from the identified base values ``theta``."""
    full = model.base.values(model.params)
    full[free] = theta
    n = q.shape[1]
    zero = np.zeros_like(q)
    g = model.base_regressor(q, zero, zero) @ full
    cols = []
    for i in range(n):
        e = np.zeros_like(q)
        e[:, i] = 1.0
        cols.append(model.base_regressor(q, zero, e) @ full - g)
    return np.stack(cols, axis=2)


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
