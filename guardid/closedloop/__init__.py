"""Closed-loop consistent identification: IDIM-IV and DIDIM (``identify --method iv,didim``).

Data from the guard robot come from a closed loop: the PID feeds the measurement noise
back into the motion, so the regressor built from the measured positions is correlated
with the torque's error and least squares is biased. Both methods here replace the
measured motion's regressor (IV: as instruments; DIDIM: as the model's output) by that of
a noise-free simulation of the same closed loop with the current estimate
(:mod:`~guardid.closedloop.simulate`: the firmware emulator's PID and limits, the plant's
motors and friction, the estimate's rigid body), conditioned like the measured rows
(:mod:`~guardid.closedloop.rows`), and iterate (:mod:`~guardid.closedloop.fit`).
"""

from __future__ import annotations

from guardid._lazy import lazy_attributes

_LAZY = {  # loaded on first use: the table and params.yaml need only STD_NOT_HONEST, and
    # the simulation's modules (plant, firmware emulator, protocol) cost identify 0.2 s
    "MAX_ITER": "fit",
    "ClosedLoopEstimate": "fit",
    "closed_loop_fit": "fit",
    "ClosedLoopRuns": "rows",
    "check_inputs": "rows",
    "physical_check": "rows",
    "regressor_builder": "rows",
}


__getattr__ = lazy_attributes(__name__, _LAZY)


STD_NOT_HONEST = {
    "didim": "its std is not honest: s^2 (Z^T Z)^-1 neglects how the simulated motion moves "
    "with the estimate; Monte Carlo, 40 seeds of the schroeder excitation (11000-11039, 60 s): "
    "truth within 3 std in 99.0 % of pairs, but the spread over seeds up to 1.48 x the std "
    "(ZZ1R); on a robot no default was tuned on, 1.38 x (ZZ2R) and a bias of 0.60 std; IV's "
    "std held on both (spread 0.68-1.07 x the std, biases <= 0.36 std)"
}
"""Closed-loop methods whose reported std fails the Monte Carlo (docs/RESULTS.md, issue 27):
the table labels their column, params.yaml marks ``std_honest: false``, and a warning says why."""


def fit_closed_loop(method, A, y, rows, inputs, description, model, free, flags):
    """(estimate, warnings) of ``method`` ('iv' | 'didim') on the measured rows A (M, n, b'),
    y (M, n) of :class:`~guardid.identify.rows.Rows` ``rows``; ``inputs`` = (runs, ticks,
    setpoints, starts), one entry per run (``starts``: :func:`~guardid.closedloop.rows.start_of`
    of each run); starts from WLS.

    Never raises for a simulation that diverges or a parameter set that cannot be simulated:
    the estimate is then marked not converged and one warning names the method, the run
    and the time (``est.stopped``)."""
    from guardid.closedloop.fit import MAX_ITER, closed_loop_fit
    from guardid.closedloop.rows import ClosedLoopRuns, physical_check, regressor_builder
    from guardid.estimators import WeightedLeastSquares

    data = ClosedLoopRuns(*inputs)
    regressor_of = regressor_builder(data, description, model, free, rows, flags)
    start = WeightedLeastSquares().fit(A, y).theta_
    problem = physical_check(data, description, model, free)
    est = closed_loop_fit(method, A, y, start, regressor_of, problem)
    notes = [f"{method}: {STD_NOT_HONEST[method]}"] if method in STD_NOT_HONEST else []
    if est.stopped:
        shown = "the last solution" if est.iterations else "the WLS start"
        notes.append(
            f"{method}: stopped: {est.stopped}; {method.upper()} not converged, its column "
            f"is {shown}, not a closed-loop estimate to trust"
        )
    elif not est.converged:
        notes.append(
            f"{method}: not converged after {MAX_ITER} closed-loop simulations (last step "
            f"{est.moves[-1]:.2g} std): its estimate and std are not final"
            + (f" ({est.shortened} steps shortened to stay physical)" if est.shortened else "")
        )
    return est, notes


__all__ = [
    "STD_NOT_HONEST",
    "ClosedLoopEstimate",
    "check_inputs",
    "closed_loop_fit",
    "fit_closed_loop",
]
