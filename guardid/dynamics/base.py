"""Base parameters by Gautier's numerical QR method.

The regressor is first re-expressed in the *proximal* (joint-axis) parametrisation: link j's
inertial parameters about a frame P_j whose z axis is joint j's axis and whose origin lies on
it (P_j = frame j-1 rotated by theta_j, translated by d_j for a prismatic joint). This is a
linear change of variables T of the standard (frame-j) parameters. QR of the proximal
regressor on random states, with columns ordered so that the physically meaningful
parameters come first, keeps those and groups the rest into them. The formulas are then
mapped back through T to the YAML's standard parameters.

Tolerance: a column is dependent when |R_ii| <= RANK_TOL * max|R_ii|, with RANK_TOL = 1e-8;
random states from numpy's default_rng(SEED) with SEED = 20240601, 200 samples per joint.
Grouping coefficients are rounded to 10 decimals.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

RANK_TOL = 1e-8
SEED = 20240601
DECIMALS = 10

# Kept first (natural base parameters) ... eliminated last.
_PRIORITY = (
    "ZZ",
    "XX",
    "XY",
    "XZ",
    "YZ",
    "MX",
    "MY",
    "Fv",
    "Fc",
    "Fo",
    "Fs",
    "Ia",
    "YY",
    "MZ",
    "M",
)


@dataclass(frozen=True)
class BaseParameters:
    """Base parameters: values = K @ params; base regressor = regressor @ B.

    names (b,), formulas (b,) in terms of the standard parameter names, K (b, p), B (p, b);
    regressor @ B @ K @ params == regressor @ params for every state.
    """

    names: tuple[str, ...]
    formulas: tuple[str, ...]
    K: np.ndarray
    B: np.ndarray

    def values(self, params: np.ndarray) -> np.ndarray:
        """Base parameter values (b,) from standard parameters (p,)."""
        return self.K @ params

    def regressor(self, full: np.ndarray) -> np.ndarray:
        """Base regressor (..., b) from the full regressor (..., p)."""
        return full @ self.B


def skew(v: np.ndarray) -> np.ndarray:
    """Matrix [v]x with [v]x u = v x u."""
    return np.array([[0.0, -v[2], v[1]], [v[2], 0.0, -v[0]], [-v[1], v[0], 0.0]])


def _to_proximal_link(phi: np.ndarray, rot: np.ndarray, r: np.ndarray) -> np.ndarray:
    """Standard parameters of one link in frame j -> in frame P_j (frame j = P_j*Trans(r)*rot)."""
    xx, xy, xz, yy, yz, zz, mx, my, mz, m = phi
    i_o = np.array([[xx, xy, xz], [xy, yy, yz], [xz, yz, zz]])
    h = rot @ np.array([mx, my, mz])
    s_r, s_h = skew(r), skew(h)
    i_p = rot @ i_o @ rot.T + m * s_r.T @ s_r + s_r.T @ s_h + s_h.T @ s_r
    h_p = h + m * r
    return np.array([i_p[0, 0], i_p[0, 1], i_p[0, 2], i_p[1, 1], i_p[1, 2], i_p[2, 2], *h_p, m])


def proximal_transform(chain, p: int) -> np.ndarray:
    """T (p, p): proximal parameters = T @ standard parameters (identity beyond 10n)."""
    t = np.eye(p)
    for j, joint in enumerate(chain.joints):
        dh = joint.dh
        ca, sa = np.cos(dh.alpha), np.sin(dh.alpha)
        rot = np.array([[1.0, 0.0, 0.0], [0.0, ca, -sa], [0.0, sa, ca]])
        r = np.array([dh.a, 0.0, dh.d if joint.type == "revolute" else 0.0])
        block = np.column_stack([_to_proximal_link(e, rot, r) for e in np.eye(10)])
        t[10 * j : 10 * j + 10, 10 * j : 10 * j + 10] = block
    return t


def _kind(name: str) -> str:
    return name.rstrip("0123456789")


def compute_base(model, known_zero: list[int]) -> BaseParameters:
    """Gautier's QR reduction of ``model``'s regressor (see module docstring)."""
    p = len(model.param_names)
    n = model.n_dof
    rng = np.random.default_rng(SEED)
    num = 200 * n
    q = rng.uniform(-np.pi, np.pi, (num, n))
    for j, joint in enumerate(model.description.joints):
        if joint.type == "prismatic":
            q[:, j] = rng.uniform(-1.0, 1.0, num)
    qd = rng.standard_normal((num, n))
    qdd = rng.standard_normal((num, n))
    mask = np.ones(p)
    mask[known_zero] = 0.0
    t = proximal_transform(model.description, p)
    t_inv = np.linalg.inv(t)
    w = np.diag(mask) @ t_inv  # proximal regressor = Y @ w
    y_prox = model.regressor(q, qd, qdd).reshape(num * n, p) @ w
    order = sorted(range(p), key=lambda i: (_PRIORITY.index(_kind(model.param_names[i])), i))
    _, r = np.linalg.qr(y_prox[:, order])
    diag = np.abs(np.diag(r))
    indep = diag > RANK_TOL * diag.max()
    kept = sorted(order[i] for i in range(p) if indep[i])
    dropped = [order[i] for i in range(p) if not indep[i]]
    beta, *_ = np.linalg.lstsq(y_prox[:, kept], y_prox[:, dropped], rcond=None)
    beta = np.round(beta, DECIMALS)
    k_prox = np.zeros((len(kept), p))
    k_prox[np.arange(len(kept)), kept] = 1.0
    k_prox[:, dropped] = beta
    k_std = np.round(k_prox @ t, DECIMALS) * mask
    names, formulas = [], []
    for row, idx in zip(k_std, kept, strict=True):
        formula = format_formula(row, model.param_names)
        own = model.param_names[idx]
        names.append(own if formula == own else own + "R")
        formulas.append(formula)
    return BaseParameters(tuple(names), tuple(formulas), k_std, w[:, kept])


def format_formula(row: np.ndarray, names) -> str:
    """'ZZ1 + 0.25*M2 - MX1' from coefficients (unit-coefficient terms first)."""
    terms = sorted(
        ((c, nm) for c, nm in zip(row, names, strict=True) if c != 0.0),
        key=lambda t: abs(t[0]) != 1.0,
    )
    out = ""
    for c, nm in terms:
        text = nm if abs(c) == 1.0 else f"{abs(c):.10g}*{nm}"
        if not out:
            out = text if c > 0 else f"-{text}"
        else:
            out += f" + {text}" if c > 0 else f" - {text}"
    return out or "0"
