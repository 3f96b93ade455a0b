"""Fourier excitation optimised for the condition number (seed 001 eqs. 37-38).

The cost is cond(W) (eq. 38; plus ``sigma_weight / sigma_min(W)`` as in eq. 37 when asked)
of the base regressor W stacked over ``samples`` times along one period. W is the full base
regressor including the Coulomb column Fc*sign(qd), as identification uses it; the cost is
therefore piecewise smooth (it jumps when a sample's velocity changes sign), which the
finite-difference gradients of SLSQP tolerate because a jump needs a sign change inside
the ~1e-8 step. The decision variables are the free Fourier coefficients (rest at the start
pose eliminated, see :mod:`guardid.excitation.fourier`); the position (limited joints),
velocity and acceleration limits, shrunk by the safety margin, are linear inequalities on
them, sampled on a grid of ``constraint_samples`` times per period. The result is checked on a
1 ms grid and scaled down if needed. Random starts come from ``numpy.random.default_rng(seed)``,
each scaled onto the limits, so a run is deterministic.
"""

from __future__ import annotations

import time
import warnings
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from guardid.excitation.fourier import FourierTrajectory, design_matrices, rest_basis
from guardid.excitation.limits import SLOW_FRACTION, JointLimits, fit_to_limits


@dataclass
class ExcitationResult:
    """Optimised trajectory and its cond(W); the starting guess (first seeded start) and its.

    ``guess_conds`` lists cond(W) of every seeded starting guess (each one is optimised; the
    best optimum wins).
    """

    trajectory: FourierTrajectory
    cond: float
    start_trajectory: FourierTrajectory
    start_cond: float
    guess_conds: list[float]
    iterations: int  # SLSQP iterations summed over the starts
    starts: int
    seconds: float


class ConditionProblem:
    """cond(W) of a Fourier trajectory at rest at ``start``, as a function of free coefficients."""

    def __init__(
        self,
        model,
        limits: JointLimits,
        base_freq: float,
        harmonics: int,
        start,
        samples: int = 300,
        constraint_samples: int = 200,
        sigma_weight: float = 0.0,
    ):
        self.model = model
        self.limits = limits
        self.base_freq = float(base_freq)
        self.harmonics = int(harmonics)
        self.start = np.asarray(start, dtype=float).reshape(-1)
        self.n = self.start.size
        self.sigma_weight = sigma_weight
        period = 1.0 / self.base_freq
        basis = rest_basis(self.harmonics)
        # cond grid: mid-sample times, so no sample sits on the rest point qd = 0 at t = 0
        self.times = (np.arange(samples) + 0.5) * period / samples
        self._maps = [m @ basis for m in design_matrices(self.times, base_freq, harmonics)]
        tc = np.arange(constraint_samples) * period / constraint_samples
        self._cmaps = [m @ basis for m in design_matrices(tc, base_freq, harmonics)]
        self.n_free = basis.shape[1]
        self.G, self.h = self._constraints()

    @property
    def size(self) -> int:
        """Number of decision variables n * 2(H - 1)."""
        return self.n * self.n_free

    def states(self, z) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(q, qd, qdd), each (samples, n), on the cond grid."""
        zz = np.asarray(z, dtype=float).reshape(self.n, self.n_free)
        dq, dqd, dqdd = (m @ zz.T for m in self._maps)
        return self.start + dq, dqd, dqdd

    def cond(self, z, keep_slow: bool = True) -> float:
        """cond(W) [-]; without rows of joints slower than SLOW_FRACTION of the limit if asked."""
        q, qd, qdd = self.states(z)
        y = self.model.base_regressor(q, qd, qdd)
        if not keep_slow:
            y = y[np.abs(qd) >= SLOW_FRACTION * self.limits.vel]
        return _cond(y.reshape(-1, y.shape[-1]))[0]

    def cost(self, z) -> float:
        """ln(cond(W) + sigma_weight / sigma_min(W)) (the logarithm evens out the scale)."""
        q, qd, qdd = self.states(z)
        y = self.model.base_regressor(q, qd, qdd)
        c, s_min = _cond(y.reshape(-1, y.shape[-1]))
        extra = self.sigma_weight / s_min if self.sigma_weight else 0.0
        return float(np.log(c + extra)) if np.isfinite(c) else 1e3

    def _constraints(self) -> tuple[np.ndarray, np.ndarray]:
        """G, h with G z + h >= 0 for every sampled limit (two sides each)."""
        m_q, m_v, m_a = self._cmaps
        rows, rhs = [], []
        for j in range(self.n):
            cols = slice(j * self.n_free, (j + 1) * self.n_free)
            blocks = [
                (m_v, self.limits.vel[j], self.limits.vel[j]),
                (m_a, self.limits.acc[j], self.limits.acc[j]),
            ]
            if np.isfinite(self.limits.lo[j]):
                blocks.append(
                    (m_q, self.limits.hi[j] - self.start[j], self.start[j] - self.limits.lo[j])
                )
            for mat, upper, lower in blocks:
                for sign, bound in ((-1.0, upper), (1.0, lower)):
                    g = np.zeros((mat.shape[0], self.size))
                    g[:, cols] = sign * mat
                    rows.append(g)
                    rhs.append(np.full(mat.shape[0], bound))
        return np.vstack(rows), np.concatenate(rhs)

    def random_start(self, rng: np.random.Generator) -> np.ndarray:
        """Random free coefficients (1/l-weighted harmonics) scaled onto the limits."""
        h = self.harmonics
        weights = np.concatenate([1.0 / np.arange(1, h + 1)] * 2)
        coef = rng.standard_normal((self.n, 2 * h)) * weights
        z = coef @ rest_basis(h)  # project onto the rest subspace (basis is orthonormal)
        return self.fit(z.ravel())

    def fit(self, z) -> np.ndarray:
        """z scaled per joint so the sampled constraints just hold."""
        zz = np.asarray(z, dtype=float).reshape(self.n, self.n_free).copy()
        for j in range(self.n):
            g = self.G[:, j * self.n_free : (j + 1) * self.n_free]
            rows = np.any(g != 0, axis=1)
            used = -(g[rows] @ zz[j])
            room = self.h[rows]
            pos = used > 0
            if np.any(pos):
                zz[j] *= np.min(room[pos] / used[pos])
        return zz.ravel()

    def trajectory(self, z, joint_names=None) -> FourierTrajectory:
        """The FourierTrajectory of free coefficients z."""
        return FourierTrajectory.from_free(
            np.asarray(z).reshape(self.n, self.n_free),
            self.base_freq,
            self.harmonics,
            self.start,
            joint_names=joint_names,
        )


def optimise_fourier(
    model,
    desc,
    harmonics: int = 5,
    base_freq: float = 0.1,
    start=None,
    seed: int = 0,
    starts: int = 4,
    samples: int = 300,
    margin: float = 0.05,
    maxiter: int = 100,
    sigma_weight: float = 0.0,
    progress: Callable[[str], None] | None = None,
) -> ExcitationResult:
    """Fourier trajectory minimising cond(W) under the limits (see module docstring).

    ``start`` (n,) [rad] is the rest pose (zeros by default), ``margin`` the safety margin
    on the limits, ``starts`` the number of seeded random starting guesses (each is optimised;
    the first is reported as the starting guess), ``progress`` receives one line per SLSQP
    iteration.
    """
    t0 = time.perf_counter()
    limits = JointLimits.of(desc, margin)
    start = np.zeros(len(desc.joints)) if start is None else np.asarray(start, dtype=float)
    limits.check_pose(start)
    prob = ConditionProblem(
        model, limits, base_freq, harmonics, start, samples, sigma_weight=sigma_weight
    )
    rng = np.random.default_rng(seed)
    guesses = [prob.random_start(rng) for _ in range(starts)]
    start_conds = [prob.cond(z) for z in guesses]
    constraint = {"type": "ineq", "fun": lambda z: prob.G @ z + prob.h, "jac": lambda z: prob.G}
    best_z, best_cost, iterations = None, np.inf, 0
    for k, z0 in enumerate(guesses):
        count = [0]

        def report(z, k=k, count=count):
            count[0] += 1
            if progress is not None:
                progress(f"start {k + 1}/{starts} iteration {count[0]}: cond {prob.cond(z):.1f}")

        if progress is not None:
            progress(f"start {k + 1}/{starts} iteration 0: cond {start_conds[k]:.1f}")
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", RuntimeWarning)
            from scipy.optimize import minimize  # here: capture loads excitation without it

            res = minimize(
                prob.cost,
                z0,
                method="SLSQP",
                constraints=[constraint],
                callback=report,
                options={"maxiter": maxiter, "ftol": 1e-7},
            )
        iterations += int(res.nit)
        z = prob.fit(res.x) if np.any(prob.G @ res.x + prob.h < -1e-9) else res.x
        cost = prob.cost(z)
        if cost < best_cost:
            best_z, best_cost = z, cost
    names = [j.name for j in desc.joints]
    traj = fit_to_limits(prob.trajectory(best_z, names), limits)
    start_traj = prob.trajectory(guesses[0], names)
    cond = regressor_cond(model, traj, samples)
    return ExcitationResult(
        traj,
        cond,
        start_traj,
        start_conds[0],
        start_conds,
        iterations,
        starts,
        time.perf_counter() - t0,
    )


def regressor_cond(model, traj, samples: int = 300, slow_limits=None) -> float:
    """cond of the base regressor over ``samples`` mid-sample times of one period [-].

    With ``slow_limits`` (n,) [rad/s], rows of joints with |qd| below them are dropped
    (the stiction rows identification excludes).
    """
    t = (np.arange(samples) + 0.5) * traj.period / samples
    q, qd, qdd = traj.states(t)
    y = model.base_regressor(q, qd, qdd)
    if slow_limits is not None:
        y = y[np.abs(qd) >= np.asarray(slow_limits)]
    return _cond(y.reshape(-1, y.shape[-1]))[0]


def _cond(w: np.ndarray) -> tuple[float, float]:
    s = np.linalg.svd(w, compute_uv=False)
    if s.size < w.shape[-1] or s[-1] <= 0.0 or not np.isfinite(s[-1]):
        return np.inf, 0.0
    return float(s[0] / s[-1]), float(s[-1])
