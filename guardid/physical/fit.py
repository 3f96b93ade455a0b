"""Physically consistent identification: the standard parameters that fit the rows best.

Unknowns (all SI): per link the ten log-Cholesky coordinates of its pseudo-inertia
(:mod:`guardid.physical.pseudo_inertia`: every value is a consistent link), per rotor its
reflected inertia Ia >= 0, per friction model Fv >= 0, Fc >= 0 and Fo (bounds). Known-zero
parameters of the robot YAML (``known_zero``) are held at zero through the coordinates that
produce them (t1..t3 for MX..MZ, s12, s13, s23 for XY, XZ, YZ); an offset declared absent
(``offset: null``) stays 0. The log-diagonal coordinates are bounded below
(:data:`MIN_FACTOR`), so every link's pseudo-inertia is strictly positive definite.

Cost (``scipy.optimize.least_squares``, trust-region reflective):

    ||A K phi - y||^2 / sigma^2  +  w^2 ||(phi - phi_yaml) / s||^2

A (M, n, b) and y (M, n) are identification's rows, K maps standard to identified base
parameters, sigma^2 is LS's residual variance, s each standard parameter's scale (per
link: its YAML inertia trace / 3, sqrt(mass x that), mass; per rotor or friction term: its
YAML value or the largest of its kind). The data decide every direction they see; the
prior ``phi_yaml`` (the robot YAML) decides the rest. Its weight is chosen from the data:
with lambda_min the smallest non-zero eigenvalue of the scaled information
G = (A K S)^T (A K S) / sigma^2,

    w^2 = BIAS_PER_STD x sqrt(lambda_min),

which moves an identifiable direction by at most BIAS_PER_STD of its standard deviation per
unit (100 %) of prior error, and pins the unseen directions with curvature w^2.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.linalg import qr
from scipy.optimize import least_squares

from guardid.dynamics import build_model
from guardid.errors import GuardidError
from guardid.estimators import d_tau
from guardid.identify.pipeline import identified_names
from guardid.physical.pseudo_inertia import (
    link_violations,
    log_cholesky_from_standard,
    standard_jacobian,
)

BIAS_PER_STD = 0.01
"""Largest shift of an identifiable direction, in its standard deviations, per 100 % prior error."""

MIN_FACTOR = 1e-3
"""Each diagonal entry of a link's Cholesky factor U (module docstring) stays above this
times the YAML link's: the pseudo-inertia stays strictly positive definite (mass >= 1e-6 of
the YAML's; a thin link keeps a sliver of thickness instead of reaching the boundary) [-]."""
TOL = 1e-10
"""Relative tolerance of the solver on the cost, the step and the gradient [-]."""
MAX_EVALUATIONS = 2000
"""Solver iterations at most (each one residual and one analytic Jacobian)."""

_PIN = {"MX": 7, "MY": 8, "MZ": 9, "XY": 4, "YZ": 5, "XZ": 6}
"""Log-Cholesky coordinate held at 0 for a known-zero standard parameter (module docstring)."""


@dataclass(frozen=True)
class ConsistentFit:
    """Outcome of :func:`fit_consistent` (all SI).

    names (p,) standard parameter names; standard (p,) the consistent standard set;
    prior (p,) the YAML's; base_names, base (b,) the identified base parameters it gives;
    prior_weight w^2 and lambda_min (scaled units, module docstring); d_tau on the rows;
    violations: what is not physically consistent (always [] unless the solver failed);
    message: the solver's status.
    """

    names: tuple[str, ...]
    standard: np.ndarray
    prior: np.ndarray
    base_names: tuple[str, ...]
    base: np.ndarray
    prior_weight: float
    lambda_min: float
    d_tau: float
    violations: tuple[str, ...]
    message: str

    def value(self, name: str) -> float:
        """One standard parameter by name, e.g. ``fit.value('M2')``."""
        return float(self.standard[self.names.index(name)])


def _pins(known_zero) -> list[int]:
    """Log-Cholesky coordinates to hold at 0 so that the known-zero parameters are exactly 0.

    MX, MY, MZ = e^2a (t1, t2, t3): always exact. -YZ = e^2a (s23 e^d3 + t2 t3): exact with
    MY or MZ also zero; -XZ = e^2a (s13 e^d3 + t1 t3): with MX or MZ; -XY = e^2a (s12 e^d2 +
    s13 s23 + t1 t2): with XZ or YZ held and MX or MY zero. Others are left to the prior
    (and checked after the fit)."""
    z = set(known_zero)
    pins = {_PIN[k] for k in ("MX", "MY", "MZ") if k in z}
    if "YZ" in z and z & {"MY", "MZ"}:
        pins.add(_PIN["YZ"])
    if "XZ" in z and z & {"MX", "MZ"}:
        pins.add(_PIN["XZ"])
    if "XY" in z and pins & {_PIN["XZ"], _PIN["YZ"]} and z & {"MX", "MY"}:
        pins.add(_PIN["XY"])
    return sorted(pins)


class _Layout:
    """Where each unknown lives: link coordinates, bounded extras, fixed entries."""

    def __init__(self, model, description):
        names = list(model.param_names)
        self.n_links = model.n_dof
        self.pinned = [_pins(link.known_zero) for link in description.links]
        self.free_link = [[i for i in range(10) if i not in pins] for pins in self.pinned]
        fixed = {
            names.index(f"Fo{j + 1}")
            for j, joint in enumerate(description.joints)
            if joint.friction is not None and not joint.friction.offset_modelled
        }
        self.extra = [i for i in range(10 * self.n_links, len(names)) if i not in fixed]
        self.extra_nonneg = [not names[i].startswith("Fo") for i in self.extra]
        self.regularised = [i for i in range(len(names)) if i not in fixed]

    def to_x(self, phi: np.ndarray) -> np.ndarray:
        parts = []
        for k in range(self.n_links):
            x = log_cholesky_from_standard(phi[10 * k : 10 * k + 10])
            parts.append(x[self.free_link[k]])
        extra = phi[self.extra].copy()
        nonneg = np.array(self.extra_nonneg, dtype=bool)
        extra[nonneg] = np.maximum(extra[nonneg], 0.0)
        parts.append(extra)
        return np.concatenate(parts)

    def to_phi(self, x: np.ndarray, phi0: np.ndarray) -> np.ndarray:
        return self.phi_and_jacobian(x, phi0)[0]

    def phi_and_jacobian(self, x: np.ndarray, phi0: np.ndarray):
        """(phi (p,), d phi / d x (p, len(x)))."""
        phi = phi0.copy()
        jac = np.zeros((len(phi0), len(x)))
        at = 0
        for k in range(self.n_links):
            full = np.zeros(10)
            cols = self.free_link[k]
            full[cols] = x[at : at + len(cols)]
            phi[10 * k : 10 * k + 10], dk = standard_jacobian(full)
            jac[10 * k : 10 * k + 10, at : at + len(cols)] = dk[:, cols]
            at += len(cols)
        phi[self.extra] = x[at:]
        jac[self.extra, at:] = np.eye(len(self.extra))
        return phi, jac

    def bounds(self, x0: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Lower bounds: log-diagonal coordinates (a, d1..d3) at most log(1 / MIN_FACTOR)
        below the prior's x0, so that J stays strictly positive definite; rotor inertias and
        friction coefficients >= 0."""
        lo = []
        for k in range(self.n_links):
            for i in self.free_link[k]:
                lo.append(-np.inf if i > 3 else None)
        lo = np.array(
            [x0[i] - np.log(1.0 / MIN_FACTOR) if v is None else v for i, v in enumerate(lo)]
        )
        extra = [0.0 if nn else -np.inf for nn in self.extra_nonneg]
        lo = np.concatenate([lo, extra])
        return lo, np.full(lo.size, np.inf)


def _scales(model, phi0: np.ndarray) -> np.ndarray:
    """Per-parameter scale s (p,) [unit of the parameter] (module docstring)."""
    s = np.ones(len(phi0))
    for k in range(model.n_dof):
        link = phi0[10 * k : 10 * k + 10]
        mass = max(float(link[9]), 1e-12)
        inertia = max((link[0] + link[3] + link[5]) / 3.0, 1e-12 * mass)
        s[10 * k : 10 * k + 6] = inertia
        s[10 * k + 6 : 10 * k + 9] = np.sqrt(mass * inertia)
        s[10 * k + 9] = mass
    names = model.param_names
    for i in range(10 * model.n_dof, len(phi0)):
        kind = names[i].rstrip("0123456789")
        same = [abs(phi0[k]) for k in range(len(phi0)) if names[k].rstrip("0123456789") == kind]
        s[i] = abs(phi0[i]) if phi0[i] != 0 else (max(same) or 1.0)
    return s


def fit_consistent(A, y, description, bias_per_std: float = BIAS_PER_STD) -> ConsistentFit:
    """Consistent standard parameters from identification rows (module docstring).

    A (M, n, b) and y (M, n) [N m | N] are :func:`guardid.identify.identification_rows`'
    (or ``stacked_rows``') output for ``description`` in torque units (not current units).
    """
    model = build_model(description)
    ident = identified_names(description)
    rows = [model.base.names.index(nm) for nm in ident]
    K = model.base.K[rows]
    A = np.asarray(A, dtype=float)
    y = np.asarray(y, dtype=float)
    b = K.shape[0]
    A2 = A.reshape(-1, b)
    y1 = y.reshape(-1)
    if A2.shape[0] <= b:
        raise GuardidError(f"--consistent: {A2.shape[0]} rows for {b} base parameters")
    raug = qr(np.column_stack([A2, y1]), mode="r", check_finite=False)[0]
    R, z = raug[:b, :b], raug[:b, b]
    rss = float(raug[b, b] ** 2) if raug.shape[0] > b else 0.0
    sigma = np.sqrt(max(rss / (A2.shape[0] - b), 1e-300))
    phi0 = model.params.copy()
    layout = _Layout(model, description)
    s = _scales(model, phi0)
    reg = np.array(layout.regularised)
    RKS = R @ K @ np.diag(s) / sigma
    ev = np.sort(np.linalg.eigvalsh(RKS.T @ RKS))[::-1]
    lam_min = float(ev[b - 1]) if ev[0] > 0 else 1.0
    w2 = bias_per_std * np.sqrt(lam_min)
    w = np.sqrt(w2)

    def residual(x):
        phi = layout.to_phi(x, phi0)
        data = (R @ (K @ phi) - z) / sigma
        return np.concatenate([data, w * (phi[reg] - phi0[reg]) / s[reg]])

    def jacobian(x):
        _, dphi = layout.phi_and_jacobian(x, phi0)
        return np.vstack([(R @ K @ dphi) / sigma, (w / s[reg])[:, None] * dphi[reg]])

    x0 = layout.to_x(phi0)
    lo, hi = layout.bounds(x0)
    x0 = np.clip(x0, lo, hi)
    with np.errstate(over="ignore", invalid="ignore"):  # wild trial steps are rejected
        sol = least_squares(
            residual, x0, jac=jacobian, bounds=(lo, hi), method="trf", x_scale="jac",
            ftol=TOL, xtol=TOL, gtol=TOL, max_nfev=MAX_EVALUATIONS,
        )  # fmt: skip
    phi = layout.to_phi(sol.x, phi0)
    violations = []
    for k, link in enumerate(description.links):
        violations += [f"link {link.name}: {v}" for v in link_violations(phi[10 * k : 10 * k + 10])]
    for k, link in enumerate(description.links):
        scale = np.abs(phi[10 * k : 10 * k + 10]).max()
        for name in link.known_zero:
            value = phi[model.param_names.index(f"{name}{k + 1}")]
            if abs(value) > 1e-9 * scale:
                violations.append(f"{name}{k + 1} = {value:.3g}, declared known_zero")
    for i in layout.extra:
        name = model.param_names[i]
        if not name.startswith("Fo") and phi[i] < 0:
            violations.append(f"{name} = {phi[i]:.4g} < 0")
    base = K @ phi
    return ConsistentFit(
        names=tuple(model.param_names),
        standard=phi,
        prior=phi0,
        base_names=tuple(ident),
        base=base,
        prior_weight=float(w2),
        lambda_min=lam_min,
        d_tau=float(d_tau(A, y, base)),
        violations=tuple(violations),
        message=str(sol.message),
    )
