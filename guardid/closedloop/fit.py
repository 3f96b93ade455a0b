"""IDIM-IV and DIDIM (Gautier, Janot et al.): identification consistent on closed-loop data.

Both simulate the closed loop (:mod:`guardid.closedloop.simulate`) with the current
estimate, driven by the log's setpoints, and condition the simulated positions exactly as
the measured ones (same options, cut-off, decimation; the measured rows' mask), giving the
simulated regressor Z (M, n, b') on the measured rows. Rows are weighted per joint by
1 / sigma_j as guardid's WLS does (sigma_j from the previous iterate's residual).

* IDIM-IV: instruments Z; theta = (Z^T A)^-1 Z^T y; covariance
  s^2 (Z^T A)^-1 Z^T Z (A^T Z)^-1, s^2 = ||y - A theta||^2 / (M - p) (weighted rows).
* DIDIM: the output error y - Z(theta) theta; iterated least squares on the simulated
  regressor (Gauss-Newton with the Jacobian approximated by Z, which neglects how the
  simulated motion moves with theta: small for a loop that tracks its setpoints);
  covariance s^2 (Z^T Z)^-1 with s^2 = ||y - Z theta||^2 / (M - p).

Both start from the WLS estimate; the next simulation uses theta + DAMPING (F(theta) -
theta), F the solve on the last simulation; they stop when the step F(theta) - theta is
below :data:`TOL_STD` of every parameter's std (at most :data:`MAX_ITER` simulations).

Physical guard: a parameter set is simulated only when ``problem(theta)`` finds nothing
wrong with it (:func:`guardid.closedloop.rows.physical_check`: a mass matrix positive
definite where the motion goes, damping >= 0, a step the integrator takes stably); a
damped step that leaves that set is halved (at most :data:`MAX_HALVINGS` times), so the
iteration stays inside it. A simulation that still diverges, or a start outside the set,
stops the iteration: the estimate is then the last solution (or the start) and
``stopped`` says why, naming the run and the time.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from guardid.errors import GuardidError

MAX_ITER = 10  #: closed-loop simulations at most
MAX_HALVINGS = 8  #: halvings of a step that leaves the physical parameter sets
DAMPING = {"iv": 1.0, "didim": 0.5}
"""Fraction of the step taken before the next simulation [-]. DIDIM's undamped iterates
alternate (period 2, +-0.3-0.5 std on the tracking excitation: a loop that tracks a
heavier model harder); half steps settle them in 3-4 simulations."""
TOL_STD = {"iv": 0.1, "didim": 0.3}
"""Converged when no parameter's fixed-point step |F(theta) - theta| exceeds this many of
its std [-]. The simulated motion is piecewise in theta (the PID acts on whole encoder
counts and PWM steps, joints stick and slip), so the steps have a floor rather than
vanishing: IV's (instruments only) 0.01-0.07 std after the second simulation, DIDIM's
(the model's output itself) 0.1-0.3 std, on 60 s guard captures (measured)."""


@dataclass
class ClosedLoopEstimate:
    """What the pipeline reads: ``theta_`` (p,), ``std_`` (p,), ``rel_std_`` (p,) [%],
    ``cov_`` (p, p); ``iterations`` run, ``converged``, ``history_`` None."""

    theta_: np.ndarray
    cov_: np.ndarray
    iterations: int
    converged: bool
    moves: list = field(default_factory=list)  # max |step| / std per iteration [-]
    history_: None = None
    stopped: str = ""  # why the iteration stopped early ('' when it did not)
    shortened: int = 0  # steps halved to stay among physical parameter sets

    @property
    def std_(self) -> np.ndarray:
        return np.sqrt(np.clip(np.diag(self.cov_), 0.0, None))

    @property
    def rel_std_(self) -> np.ndarray:
        with np.errstate(divide="ignore", invalid="ignore"):
            return 100.0 * self.std_ / np.abs(self.theta_)


def joint_weights(A, y, theta) -> np.ndarray:
    """1 / sigma_j (n,) from the residual y - A theta, per joint (dof N - p_j, as WLS)."""
    N = A.shape[0]
    p_j = np.count_nonzero(np.any(A != 0, axis=0), axis=1)
    r = y - A @ theta
    sig = np.sqrt(np.sum(r**2, axis=0) / np.maximum(N - p_j, 1))
    sig = np.where(sig > 0, sig, max(float(sig.max()), 1e-300))
    return 1.0 / sig


def _stack(X, w):
    return (X * w[None, :, None]).reshape(-1, X.shape[2])


def iv_solve(A, y, Z, w):
    """(theta (p,), cov (p, p)) of the instrumental-variable estimate with instruments Z
    (M, n, p) on rows A (M, n, p), y (M, n) weighted per joint by ``w`` (n,)."""
    Aw, Zw = _stack(A, w), _stack(Z, w)
    yw = (y * w).reshape(-1)
    d = np.sqrt(np.sum(Aw * Aw, axis=0))
    d = np.where(d > 0, d, 1.0)  # column scaling: solve in well-scaled units
    G = Zw.T @ (Aw / d)
    try:
        theta = np.linalg.solve(G, Zw.T @ yw) / d
    except np.linalg.LinAlgError:
        raise GuardidError(
            "--method iv/didim: the simulated closed loop's regressor is singular (a column "
            "the simulated motion never excites): use ls or wls on this log"
        ) from None
    r = yw - Aw @ theta
    s2 = float(r @ r) / max(len(yw) - Aw.shape[1], 1)
    Ginv = np.linalg.inv(G) / d[:, None]  # (Z^T A)^-1 in the original units
    cov = s2 * Ginv @ (Zw.T @ Zw) @ Ginv.T
    return theta, cov


def ls_solve(Z, y, w):
    """(theta, cov) of weighted least squares of y on Z: cov s^2 (Z^T Z)^-1."""
    return iv_solve(Z, y, Z, w)


def closed_loop_fit(method: str, A, y, theta0, regressor_of, problem=None) -> ClosedLoopEstimate:
    """``method`` 'iv' or 'didim' from ``theta0`` (p,) (the WLS estimate).

    ``regressor_of(theta)`` -> Z (M, n, p): the simulated closed loop's regressor on the
    measured rows (GuardidError with ``time_s`` when the simulation diverged); A (M, n, p),
    y (M, n): the measured rows; ``problem(theta)`` -> None or why ``theta`` cannot be
    simulated (default: every set can).
    """
    problem = problem or (lambda theta: None)
    theta = np.asarray(theta0, dtype=float)
    w = joint_weights(A, y, theta)
    moves, converged, new, cov, stopped, shortened = [], False, None, None, "", 0
    why = problem(theta)
    if why is not None:
        stopped = f"the start (WLS) cannot be simulated: {why}"
    for k in range(MAX_ITER if why is None else 0):
        try:
            Z = regressor_of(theta)
        except GuardidError as exc:
            if getattr(exc, "run", None) is None:  # not a simulation's divergence
                raise
            stopped = f"closed-loop simulation {k + 1} (estimate {k}): {exc}"
            break
        if method == "iv":
            new, cov = iv_solve(A, y, Z, w)
            w = joint_weights(A, y, new)
        else:
            new, cov = ls_solve(Z, y, w)
            w = joint_weights(Z, y, new)
        std = np.sqrt(np.clip(np.diag(cov), 1e-300, None))
        moves.append(float(np.max(np.abs(new - theta) / std)))
        if moves[-1] < TOL_STD[method]:
            converged = True
            theta = new
            break
        step = DAMPING[method] * (new - theta)
        for _ in range(MAX_HALVINGS + 1):
            why = problem(theta + step)
            if why is None:
                break
            step = 0.5 * step
            shortened += 1
        if why is not None:
            stopped = (f"every step from estimate {k} towards solution {k + 1} (down to "
                       f"1/{2**MAX_HALVINGS} of it) cannot be simulated: {why}")  # fmt: skip
            break
        theta = theta + step
    if new is None:  # no closed-loop solution: the start, with its weighted-LS covariance
        cov = ls_solve(A, y, joint_weights(A, y, theta))[1]
    elif not converged:  # the last solution, the point its covariance describes
        theta = new
    return ClosedLoopEstimate(theta, cov, len(moves), converged, moves, stopped=stopped,
                              shortened=shortened)  # fmt: skip
