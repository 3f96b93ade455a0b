"""The estimators identification runs, registered by name (``identify --method``).

Each method is a class with a one-line ``summary`` (``--method``'s help) and
``fit(rows: FitRows) -> MethodFit``, registered with :func:`register`; the pipeline
(:func:`guardid.identify.pipeline.identify`) looks methods up here and has no list of its
own, so adding one is adding a registered class (in this module or any imported one)::

    @register("toy")
    class Toy(Method):
        summary = "zeros, for the example"

        def fit(self, rows):
            return MethodFit(theta=np.zeros(rows.A.shape[-1]))
"""

from __future__ import annotations

import copy
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from guardid.errors import GuardidError

# the estimators are imported where they are fitted: listing the methods (``--help``) needs
# none of them


@dataclass(frozen=True)
class FitRows:
    """What every estimator is fitted on: the equation rows and their context.

    ``A`` (M, n, b') base regressor of the identified columns, ``y`` (M, n) effort minus the
    known torque [N m | N | effort unit]; ``rows``: the :class:`~guardid.identify.rows.Rows`
    they come from (conditioned signals ``rows.cond``, options used); ``names`` (b',) and
    ``nominal`` (b',) [SI] the identified base parameters and their values in the
    description; ``dt`` [s] the rows' sample period; ``ls``: least squares on these rows
    (the pipeline's reference for its checks); ``runs``: the :class:`~guardid.identify.runs.Run`
    list; ``description``, ``model``, ``free`` (identified base columns); ``options``: the
    :class:`~guardid.identify.pipeline.IdentifyOptions`; ``effort_is_torque``: the runs'
    effort is measured joint torque (:attr:`Run.torque`).
    """

    A: np.ndarray
    y: np.ndarray
    rows: object
    names: tuple[str, ...]
    nominal: np.ndarray
    dt: float
    ls: object  # guardid.estimators.LeastSquares, fitted
    runs: list
    description: object
    model: object
    free: list[int]
    options: object
    effort_is_torque: bool = False


@dataclass
class MethodFit:
    """One estimator's outcome: ``theta`` (b',) and ``cov`` (b', b') or None [SI].

    ``std`` (b',) defaults to sqrt(diag(cov)) and ``rel_std_pct`` to 100 std / |theta| [%];
    ``history`` (K, b') the estimate after ``history_samples`` (K,) rows (online methods);
    ``settings``: what to record beside it; ``converged`` False: the estimate is not final;
    ``notes``: warnings for the user; ``extra``: further results by name (e.g.
    ``hopfield-eq``), reported after this one.
    """

    theta: np.ndarray
    cov: np.ndarray | None = None
    std: np.ndarray | None = None
    rel_std_pct: np.ndarray | None = None
    history: np.ndarray | None = None
    history_samples: np.ndarray | None = None
    settings: dict = field(default_factory=dict)
    converged: bool = True
    notes: list[str] = field(default_factory=list)
    extra: dict[str, MethodFit] = field(default_factory=dict)
    output_spread: np.ndarray | None = None  # MLP: its output's spread over the rows
    rows: object = None  # the Rows it was fitted on, when not FitRows.rows (iv, didim)

    def __post_init__(self):
        self.theta = np.asarray(self.theta, dtype=float)
        if self.std is None and self.cov is not None:
            self.std = np.sqrt(np.clip(np.diag(self.cov), 0.0, None))
        if self.rel_std_pct is None and self.std is not None:
            with np.errstate(divide="ignore", invalid="ignore"):
                self.rel_std_pct = 100.0 * self.std / np.abs(self.theta)

    @classmethod
    def of(cls, est, **kwargs) -> MethodFit:
        """From a fitted estimator's ``theta_``, ``cov_``, ``std_``, ``rel_std_``,
        ``history_`` and ``history_samples_`` (each optional but ``theta_``)."""
        return cls(
            theta=est.theta_,
            cov=getattr(est, "cov_", None),
            std=getattr(est, "std_", None),
            rel_std_pct=getattr(est, "rel_std_", None),
            history=getattr(est, "history_", None),
            history_samples=getattr(est, "history_samples_", None),
            output_spread=getattr(est, "output_spread_", None),
            **kwargs,
        )


class Method:
    """A registered estimator: ``fit(rows)`` -> :class:`MethodFit`. ``name`` is set by
    :func:`register`; ``summary`` is its ``--method`` help; ``check(methods, runs,
    description)`` (a plain function, optional) refuses unusable input before conditioning
    (methods sharing one check function are checked once); ``equation`` (optional): the
    equation form it fits in (``"acceleration"`` for iv and didim): when every method asked
    for names the same form and the options name none, the rows are made in it."""

    name: str = ""
    summary: str = ""
    check: Callable | None = None
    equation: str | None = None  # the equation form it fits in (None: the rows' own)

    def fit(self, rows: FitRows) -> MethodFit:
        raise NotImplementedError


_REGISTRY: dict[str, type[Method]] = {}


def register(name: str):
    """Class decorator: register a :class:`Method` under ``name`` (``--method NAME``)."""

    def add(cls):
        if name in _REGISTRY and _REGISTRY[name] is not cls:
            raise ValueError(f"method {name!r} is already registered ({_REGISTRY[name]})")
        cls.name = name
        _REGISTRY[name] = cls
        return cls

    return add


def method_names() -> tuple[str, ...]:
    """The registered methods' names, in registration order."""
    return tuple(_REGISTRY)


def methods_for(names) -> list[Method]:
    """Instances of the named methods; GuardidError naming the unknown ones."""
    unknown = [m for m in names if m not in _REGISTRY]
    if unknown:
        known = ", ".join(method_names())
        raise GuardidError(f"--method: unknown {', '.join(unknown)} (known: {known})")
    return [_REGISTRY[m]() for m in names]


def method_help() -> str:
    """``--method``'s help: every registered method and its summary."""
    return (
        "Comma-separated: "
        + "; ".join(
            f"{name} ({cls.summary})" if cls.summary else name for name, cls in _REGISTRY.items()
        )
        + "."
    )


# -- the built-in methods ----------------------------------------------------------------


def repeating_settings(est, groups) -> dict:
    """What params.yaml records of the rows' groups (:func:`guardid.identify.rows.period_groups`)
    for a least squares fit ``est``: their number, the std per joint of the residual
    part common to a group [unit of the effort rows] and the share of each parameter's
    variance that part makes [0-1]; {} when the rows were not grouped."""
    tau = getattr(est, "repeating_std_per_output_", None)
    if groups is None or tau is None:
        return {}
    from guardid.identify.rows import phase_group_count

    share = getattr(est, "repeating_share_", None)
    out = {"groups": phase_group_count(groups), "std_per_joint": [float(x) for x in tau]}
    if share is not None:
        out["variance_share"] = [round(float(x), 4) for x in share]
    return {"repeating_residual": out}


@register("ls")
class LS(Method):
    summary = "least squares"

    def fit(self, rows):
        groups = getattr(rows.rows, "period_groups", None)
        return MethodFit.of(rows.ls, settings=repeating_settings(rows.ls, groups))


@register("wls")
class WLS(Method):
    summary = "least squares weighted per joint by its residual's std"

    def fit(self, rows):
        from guardid.estimators import WeightedLeastSquares

        groups = rows.rows.period_groups
        wls = WeightedLeastSquares(**rows.rows.error_model()).fit(rows.A, rows.y)
        return MethodFit.of(wls, settings=repeating_settings(wls, groups))


@register("bls")
class BLS(Method):
    summary = "bounded: WLS with friction and rotor inertia kept >= 0"

    def fit(self, rows):
        from guardid.identify.trust import BoundedLeastSquares, lower_bounds

        bls = BoundedLeastSquares(lower_bounds(rows.names), **rows.rows.error_model())
        return MethodFit.of(bls.fit(rows.A, rows.y))


@register("rls")
class RLSMethod(Method):
    summary = "recursive least squares, forgetting factor --lam"

    def fit(self, rows):
        from guardid.estimators import RLS

        est = RLS(lam=rows.options.rls_lambda, p0=rls_p0(rows.A)).fit(rows.A, rows.y)
        return MethodFit.of(est)


@register("hopfield")
class HopfieldMethod(Method):
    summary = "Hopfield network, gain --beta, in a box of +-100 % of the nominal values"

    def fit(self, rows):
        hop = rows.options.hopfield
        start = rows.nominal if hop.nominal is None else np.asarray(hop.nominal, dtype=float)
        est = run_hopfield(rows.A, rows.y, start, hop.beta, rows.dt, hop.passes)
        online_end = np.array(est.theta_)
        extra = {}
        if hop.settle:  # labelled as what it is: the equilibrium, not the network's
            eq = copy.deepcopy(est).settle(rows.A, rows.y)
            settings = {"equilibrium_of": "hopfield", "beta": hop.beta}
            extra["hopfield-eq"] = MethodFit.of(eq, settings=settings)
        settings = {
            "beta": hop.beta,
            "passes": hop.passes,
            "online_end": online_end,
            "settled": hop.settle,
        }
        why = hopfield_limits(rows.A, start, rows.ls.theta_, hop.beta, rows.dt, hop.passes,
                              rows.names)  # fmt: skip
        if why:
            settings["why_not_converged"] = why
        return MethodFit.of(est, settings=settings, extra=extra)


@register("gradient")
class GradientMethod(Method):
    summary = "gradient descent from the nominal values, gain --eta"

    def fit(self, rows):
        from guardid.estimators import Gradient

        eta = rows.options.gradient_eta
        return MethodFit.of(Gradient(eta=eta, dt=rows.dt, theta0=rows.nominal).fit(rows.A, rows.y))


@register("mlp")
class MLPMethod(Method):
    summary = "seed 001's network on (q, q', q'')"

    def fit(self, rows):
        from guardid.estimators import MLP

        c = rows.rows.cond
        m = c.mask
        est = MLP().fit(rows.A, rows.y, X=np.hstack([c.q[m], c.qd[m], c.qdd[m]]))
        # converged: the training loss levelled off (guardid.estimators.mlp)
        notes = [] if est.converged_ else [_mlp_not_converged(est)]
        return MethodFit.of(est, converged=bool(est.converged_), notes=notes)


def _mlp_not_converged(est) -> str:
    """The warning for an MLP whose training stopped while its loss still fell."""
    from guardid.estimators.mlp import last_improvement, plateau_window

    if est.diverged_:
        return "MLP: not converged: training diverged (non-finite loss)"
    n = len(est.loss_history_)
    drop = 100.0 * last_improvement(est.loss_history_)
    return (
        f"MLP: not converged: its training loss still fell {drop:.1f} % over the last "
        f"{plateau_window(n)} of {n} epochs (its values are not final)"
    )


def _check_closed_loop(methods, runs, description) -> None:
    from guardid.closedloop import check_inputs

    check_inputs(methods, description, [r.setpoint for r in runs], [r.ticks for r in runs])


class _ClosedLoop(Method):
    """IV and DIDIM (:mod:`guardid.closedloop`): simulate the closed loop of each run."""

    check = staticmethod(_check_closed_loop)
    equation = "acceleration"

    def fit(self, rows):
        from guardid.closedloop import fit_closed_loop
        from guardid.closedloop.rows import start_of
        from guardid.identify.rows import closed_loop_rows

        first = rows.rows.acceleration_rows is None
        own = closed_loop_rows(rows)  # the acceleration form (module docstring there)
        runs = [(r.t, r.q, r.current) for r in rows.runs]
        per_run = [[getattr(r, k) for r in rows.runs] for k in ("ticks", "setpoint")]
        per_run.append([start_of(r, rows.description) for r in rows.runs])
        flags = (rows.options.in_current_units, rows.effort_is_torque)
        est, notes = fit_closed_loop(self.name, own.A, own.y, own, (runs, *per_run),
                                     rows.description, rows.model, rows.free, flags)  # fmt: skip
        if own is not rows.rows and first:  # said once for iv and didim
            notes = ["iv/didim: fitted in the acceleration form (their simulated closed loop is "
                     "conditioned like the measured run in that form); the other methods: "
                     "momentum form", *notes]  # fmt: skip
        settings = {"stopped": est.stopped} if getattr(est, "stopped", "") else {}
        return MethodFit.of(est, converged=bool(est.converged), notes=notes, settings=settings,
                            rows=None if own is rows.rows else own)  # fmt: skip


@register("iv")
class IV(_ClosedLoop):
    summary = (
        "IDIM-IV: instruments from a simulation of the closed loop with the log's setpoints, "
        "the robot's pid: and the estimate; needs a guardid log with sp_* columns and a "
        "robot with motors, encoders and pid:"
    )


@register("didim")
class DIDIM(_ClosedLoop):
    summary = "closed-loop output error on the simulated regressor; needs what iv needs"


# -- helpers ------------------------------------------------------------------------------


def run_hopfield(A, y, nominal, beta: float, dt: float, passes: int = 1):
    """Hopfield estimator from ``nominal`` (b,) in the box nominal +- :func:`hopfield_half_widths`.

    ``passes`` > 1 runs the log again from where the previous pass ended (same box, same
    beta [unit of y^2 times s] and sample period dt [s]); ``history_`` then spans all
    passes (sample counts continue across passes). Returns the fitted
    :class:`~guardid.estimators.Hopfield`.
    """
    from guardid.estimators import Hopfield

    nominal = np.asarray(nominal, dtype=float)
    half = hopfield_half_widths(nominal)
    bounds = (nominal - half, nominal + half)
    est = Hopfield(theta_n=nominal, bounds=bounds, beta=beta, dt=dt).fit(A, y)
    hist, counts = [est.history_], [est.history_samples_]
    for k in range(1, max(int(passes), 1)):
        est = Hopfield(theta_n=est.theta_, bounds=bounds, beta=beta, dt=dt).fit(A, y)
        hist.append(est.history_)
        counts.append(est.history_samples_ + k * A.shape[0])
    est.history_ = np.concatenate(hist)
    est.history_samples_ = np.concatenate(counts)
    return est


def rls_p0(A) -> float:
    """RLS initial covariance [(unit of theta / unit of y)^2]: 1e6 / mean(A^2), so that the
    prior's weight is ~1e-10 of one row's whatever the regressor's scale (RLS(lambda=1)
    then ends within ~1e-8 relative of LS)."""
    scale = float(np.mean(np.square(A)))
    return 1e10 / scale if scale > 0 else 1e10


REACH_TIME_CONSTANTS = 3.0
"""The Hopfield network's slowest direction must get at least this many of its time
constants over the log (e^-3: 5 % of its starting error left) to be called able to converge."""


def hopfield_limits(A, nominal, theta_ls, beta: float, dt: float, passes: int, names) -> str:
    """Why the Hopfield network cannot reach least squares' solution on these rows, or "":
    its slowest direction gets fewer than :data:`REACH_TIME_CONSTANTS` time constants over
    the log (near the box's centre the network is ds/dt = -(dt/beta) S A^T A S s per row, S
    the box's half-widths, so the log gives the direction of the smallest eigenvalue lam of
    S A^T A S a reach of passes x (dt / beta) x lam time constants; away from the centre it
    is slower still), or least squares' value of a parameter lies outside the network's box
    (nominal +- its half-width), which the network cannot leave. ``A`` (M, n, b) or (M, b)."""
    half = hopfield_half_widths(np.asarray(nominal, dtype=float))
    A = np.asarray(A)
    B = A.reshape(-1, A.shape[-1]) * half  # (rows x outputs, b)
    lam = float(np.linalg.eigvalsh(B.T @ B)[0])
    reach = max(int(passes), 1) * dt / beta * max(lam, 0.0)
    out = []
    if reach < REACH_TIME_CONSTANTS:
        out.append(
            f"over the log its slowest direction gets {reach:.2g} of its time constants "
            f"(at least {REACH_TIME_CONSTANTS:g} needed): a smaller --beta or a longer log"
        )
    lo, hi = np.asarray(nominal) - half, np.asarray(nominal) + half
    outside = [n for n, v, a, b in zip(names, theta_ls, lo, hi, strict=True) if not a <= v <= b]
    if outside:
        out.append(
            f"least squares puts {', '.join(outside)} outside its box (the robot "
            "description's value +-100 %): the description's values are far off"
        )
    return "; ".join(out)


def hopfield_half_widths(nominal: np.ndarray) -> np.ndarray:
    """The prior box of each base parameter: +-100 % of its nominal value, with a floor."""
    floor = 0.1 * float(np.median(np.abs(nominal[nominal != 0]))) if np.any(nominal) else 1.0
    return np.maximum(np.abs(nominal), floor)
