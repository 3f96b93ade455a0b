"""Can an identification be trusted? Checks on the fitted regressor, from the data alone.

Every threshold follows from the data: machine precision times the regressor's size for the
rank, the fit's own noise for the excitation. A problem is one short phrase; ``guardid
identify`` joins them into its one-line refusal (``--force`` writes the parameters anyway).

* non-finite estimates (any method) or standard deviations (LS);
* a zero regressor column: the motion never excites that parameter;
* a rank-deficient regressor: after scaling every column to unit norm, a singular value at
  or below ``s_max * max(rows, columns) * eps`` (numpy's ``matrix_rank`` tolerance);
* the verdict's method (:func:`reference_method`) is a closed-loop
  one (IV, DIDIM) that did not converge (its simulation diverged, could not be run with a
  physical parameter set, or did not settle): the verdict would rest on an unfinished
  estimate. A closed-loop method beside WLS or LS does not make the result untrusted (it is
  marked not converged, with its warning).
* a nearly unexcited regressor: along the least-determined direction of the column-scaled
  parameters, the LS standard deviation ``sigma / s_min`` exceeds the size of the whole
  scaled estimate ``||diag(c) theta||`` (c the column norms, i.e. each parameter's torque
  over the run): the data cannot tell that combination of parameters from zero even at one
  standard deviation, compared with everything the fit explains;
* a mass matrix that is not positive definite beyond its own uncertainty
  (:func:`indefinite_mass_matrix`): at some sampled row of the run, the smallest eigenvalue
  of the identified M(q) lies more than :data:`IMPOSSIBLE_STD` of its std below zero. A
  real body's M(q) is positive definite everywhere, so noise puts an honest estimate there
  in about 0.13 % of cases at one pose; one joint's current recorded under the other's
  name put it there by 14 std (a 10 min capture of the variant robot, WLS: -4.1 +- 0.3
  kg m^2, where each motor's R came out near zero, not below it; the right columns give
  +0.62, 24 std above zero).
"""

from __future__ import annotations

import numpy as np

REFERENCE_METHODS = ("wls", "ls")
"""The method whose estimate and std a report's verdict uses: the first of these that ran.
WLS, because its std matches the spread of its estimates over seeds on the guard robot's
closed loop (``bench/bench_std_check.py``, 100 seeds: spread / std 0.84-1.11 on the
default and the tracking excitation, truth within 3 std in >= 99.7 % of pairs), where LS's
pooled noise level makes the pan parameters' std up to 1.35x too large and the tilt's up to
1.35x too small (its two joints' residuals differ by a factor of several). IV and DIDIM
are not in the list: they need a guardid log with setpoints and the robot's controller;
IV meets the same bars there (its biases up to 0.2 std smaller on the tracking
excitation), DIDIM's std is up to 1.4x too small on it."""
DOMINANT = 0.3
"""A parameter is named in a problem direction when its share of the unit direction vector
(scaled coordinates) is at least this [-] (1/sqrt(11): one of up to 11 equal parts)."""


def _names(direction: np.ndarray, names) -> str:
    weights = np.abs(direction)
    order = np.argsort(-weights)
    picked = [names[k] for k in order if weights[k] >= DOMINANT] or [names[order[0]]]
    return ", ".join(picked)


def regressor_problems(R: np.ndarray, rows: int, sigma: float, theta, names) -> list[str]:
    """Problems of an LS fit given by its triangular factor ``R`` (p, p) (A^T A = R^T R, A
    the stacked regressor with ``rows`` rows), the residual standard deviation ``sigma``
    [unit of y] and the estimate ``theta`` (p,) of the parameters ``names``."""
    R = np.asarray(R, dtype=float)
    theta = np.asarray(theta, dtype=float)
    p = R.shape[1]
    if not (np.all(np.isfinite(R)) and np.isfinite(sigma) and np.all(np.isfinite(theta))):
        return []  # reported as non-finite by trust_problems
    col = np.linalg.norm(R, axis=0)  # ||A_k||: Q is orthogonal
    eps = np.finfo(float).eps
    zero = col <= eps * max(float(col.max(initial=0.0)), np.finfo(float).tiny) * max(rows, p)
    if np.any(zero):
        which = ", ".join(n for n, z in zip(names, zero, strict=True) if z)
        return [f"{which}: regressor column zero (the motion never excites it)"]
    _, s, vt = np.linalg.svd(R / col, full_matrices=False)
    tol = s[0] * max(rows, p) * eps
    deficient = s <= tol
    if np.any(deficient):
        rank = int(np.sum(~deficient))
        which = _names(vt[-1], names)
        return [f"regressor rank {rank} of {p}: {which} cannot be told apart from the others"]
    worst_std = sigma / s[-1]
    size = float(np.linalg.norm(col * theta))
    if worst_std > size:
        pct = 100.0 * worst_std / size if size > 0 else np.inf
        return [
            f"regressor nearly unexcited: the least-determined combination of "
            f"{_names(vt[-1], names)} has a standard deviation of {pct:.0f} % of the "
            "whole estimate (scaled by each parameter's torque over the run)"
        ]
    return []


def reference_method(results) -> str | None:
    """Name of the method the verdict uses (:data:`REFERENCE_METHODS`, then any with std)."""
    for m in REFERENCE_METHODS:
        if m in results and results[m].std is not None:
            return m
    return next((m for m, r in results.items() if r.std is not None), None)


def indefinite_mass_matrix(model, free, theta, cov, q) -> list[str]:
    """The problem (one phrase, or none) of a mass matrix M(q) that is not positive definite
    beyond its uncertainty: at some row of ``q`` (K, n) [rad | m] its smallest eigenvalue
    lambda lies more than :data:`IMPOSSIBLE_STD` std below zero, M(q) built from the
    identified base values ``theta`` (b,) of the columns ``free`` of ``model`` with
    covariance ``cov`` (b, b). M is linear in theta, so to first order d lambda = v^T (sum_k
    d theta_k M_k) v, v lambda's unit eigenvector and M_k the change of M per unit of theta_k:
    std(lambda) = sqrt(g^T cov g), g_k = v^T M_k v. That assumes a simple eigenvalue; at a
    repeated one the std is off, but the refusal is conservative all the same: the smallest
    eigenvalue is concave in theta, so its tangent plane bounds it from above, and lambda <
    -3 std means no theta within 3 std of the estimate along g makes M(q) positive definite.
    The 0.13 % a 3-std threshold leaves an honest estimate is per row; over the rows of a
    run, whose eigenvalues are correlated, a truth exactly on the boundary was refused in
    0.4-0.6 % of simulated draws (outside review, 2026-11-29)."""
    from guardid.identify.trust import mass_matrix_columns

    q = np.asarray(q, dtype=float)
    theta = np.asarray(theta, dtype=float)
    if cov is None or not len(q) or not np.all(np.isfinite(theta)):
        return []
    fixed, per = mass_matrix_columns(model, free, q)
    m = fixed + per @ theta
    lam, vec = np.linalg.eigh(0.5 * (m + np.swapaxes(m, 1, 2)))
    v = vec[:, :, 0]  # (K, n) the smallest eigenvalue's eigenvector
    g = np.einsum("ki,kijb,kj->kb", v, per, v)  # (K, b) v^T M_k v
    std = np.sqrt(np.maximum(np.einsum("ka,ab,kb->k", g, np.asarray(cov, float), g), 0.0))
    low = lam[:, 0]
    bad = low < -IMPOSSIBLE_STD * std  # below zero, and by more than the std allows
    if not bad.any():
        return []
    worst = int(np.argmin(np.where(bad, low / np.maximum(std, np.finfo(float).tiny), np.inf)))
    where = ", ".join(f"{x:.3g}" for x in q[worst])
    return [
        f"the identified mass matrix M(q) is not positive definite: its smallest eigenvalue "
        f"is {low[worst]:.3g} +- {std[worst]:.2g} at q = ({where}), more than "
        f"{IMPOSSIBLE_STD:g} std below zero at {int(bad.sum())} of {len(q)} sampled rows (the "
        "effort columns swapped between joints, another robot's log, a run too short for "
        "its parameters, or a model that does not fit the robot?)"
    ]


def trust_problems(ls, names, results: dict, motors=()) -> list[str]:
    """Every reason not to trust an identification from its fit and motors, [] when there is
    none (the identify stage adds :func:`indefinite_mass_matrix`'s and the motors'
    disagreement with the description, ``electrical.motor_doubts``).

    ``ls``: the fitted :class:`guardid.estimators.LeastSquares` on the identification rows;
    ``results``: {method: MethodResult}; ``motors``: MotorEstimate list (R [ohm], Ke [V s/rad]
    with their standard deviations)."""
    problems = []
    for method, r in results.items():
        bad = [n for n, x in zip(names, np.asarray(r.theta, dtype=float), strict=True)
               if not np.isfinite(x)]  # fmt: skip
        if bad:
            problems.append(f"{method.upper()} estimate not finite for {', '.join(bad)}")
    ref = reference_method(results)
    if ref in ("iv", "didim") and not results[ref].converged:
        why = results[ref].settings.get("stopped") or "--force shows its warning"
        problems.append(
            f"{ref.upper()}, the verdict's method, did not converge ({why}); "
            "add wls to --method for a verdict that does not depend on it"
        )
    sigma = float(np.sqrt(max(float(getattr(ls, "sigma2_", np.nan)), 0.0)))
    regressor = regressor_problems(ls.R_, ls.n_rows_, sigma, ls.theta_, names)
    problems += regressor
    std = np.asarray(getattr(ls, "std_", np.full(len(names), np.nan)), dtype=float)
    if not regressor and not np.all(np.isfinite(std)):  # a singular regressor explains it
        bad = [n for n, x in zip(names, std, strict=True) if not np.isfinite(x)]
        problems.append(f"LS standard deviation not finite for {', '.join(bad)}")
    for m in motors:
        values = (m.resistance, m.resistance_std, m.ke, m.ke_std)
        if not all(np.isfinite(v) for v in values):
            problems.append(f"motor {m.joint}: R or Ke not determined (the joint hardly moves)")
            continue
        for what, x, s, unit in (("R", m.resistance, m.resistance_std, "ohm"),
                                 ("Ke", m.ke, m.ke_std, "V s/rad")):  # fmt: skip
            if x < -IMPOSSIBLE_STD * s:
                problems.append(
                    f"motor {m.joint}: {what} {x:.4g} +- {s:.2g} {unit}, below zero by more than "
                    f"{IMPOSSIBLE_STD:g} std (its voltage, current or angle column swapped or of "
                    "the wrong sign?)"
                )
    return problems


IMPOSSIBLE_STD = 3.0
"""A motor's resistance R or back-EMF constant Ke, or the smallest eigenvalue of the
identified mass matrix at a sampled row, more than this many of its own std below
zero makes the result untrusted [-]: noise puts an honest estimate there in about 0.13 % of
cases (the std's promise: truth within 3 std); a swapped or sign-flipped voltage, current
or angle column puts it there by several to hundreds (the electrical model is linear and
exact up to the sensors' noise). Friction is only warned about: a real robot's friction
departs from the model enough to put an estimate a few std below zero (the DFKI pendulum's
Fv1, 3.2 std, tests/test_foreign_logs.py)."""
