"""Identification path, the rows step as a whole: runs -> one form's rows -> stacked rows.

runs (t [s] (N,), q (N, n), effort (N, n)[, qd]) -> the equation form
(:mod:`guardid.identify.equation`) -> each run conditioned on its own under the same
:class:`ConditioningOptions` in that form (:mod:`guardid.identify.momentum_rows`, or
:mod:`guardid.identify.acceleration_rows` with its cut-off and parallel filter chosen once
for all runs) -> :func:`stacked_rows`: the runs' rows stacked into one :class:`Rows`
(A (M, n, b'), y (M, n) [N m | N | effort unit], the joined conditioned signals, the
options used, doubts), which the estimators fit (:mod:`guardid.identify.methods`). Also
the acceleration form's rows for IV and DIDIM beside momentum-form rows
(:func:`closed_loop_rows`) and a model's predicted effort on either form's rows
(:func:`predicted_effort`).
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np

from guardid.conditioning import momentum as mom
from guardid.conditioning.options import ConditioningOptions
from guardid.dynamics import build_model
from guardid.errors import GuardidError
from guardid.estimators import ColumnNoise
from guardid.identify.acceleration_rows import acceleration_rows
from guardid.identify.cutoff import CutoffChoice
from guardid.identify.equation import free_columns, resolve_equation
from guardid.identify.momentum_rows import momentum_rows
from guardid.identify.prepare import run_signals

MOST_ROWS_DROPPED = 0.25
"""Warn when fewer than this fraction of the conditioned samples are usable [-] (a robot with
stick/slip loses more than half of them to the stiction guard as a matter of course: the
guard robot's optimised excitation keeps 38 %)."""
POWER_BEYOND_CUTOFF = 0.1
"""Warn when the low-pass removes more than this fraction of the effort's power [-]."""


@dataclass
class Rows:
    """Stacked identification rows and how they were made.

    ``cond``: the runs' conditioned signals joined; ``A`` (M, n, b') base regressor of the
    identified columns; ``y`` (M, n) effort minus the known torque [N m | N | effort unit];
    ``options``: the options used, cut-off resolved; ``choice``: the cut-off's
    cross-validation (None when given); ``warnings``: doubts about the conditioning;
    ``runs``: per run its own conditioned signals (the momentum form: what
    :func:`~guardid.identify.momentum_rows.momentum_rows_of` needs); ``acceleration_rows``:
    the same runs in the acceleration form, made once when a method fits only in it (iv,
    didim: :func:`closed_loop_rows`), else None;
    ``column_noise``: the encoder rounding's noise in the identified columns of ``A`` and
    in ``y`` (the momentum form,
    :func:`~guardid.identify.momentum_rows.quantisation_noise_of`), which LS and WLS
    remove, else None. ``period_groups``: :func:`period_groups`; ``row_ticks`` (M,): each
    row's tick (:func:`row_ticks`) and ``lag_ticks``: how near rows share their noise (LS
    and WLS count it in their std; 0: not counted, ``row_ticks`` None).
    ``offset_columns`` (M, n, n): the rows' friction-offset column of each joint [torque
    units per N m], or None (:attr:`~guardid.identify.equation.FormRows.offset_columns`);
    ``run_rows``: how many of the rows each run gave, in order; ``row_t`` (M,): each row's
    time on its own run's clock [s] (not the joined, shifted ``cond.t``).
    """

    cond: object
    A: np.ndarray
    y: np.ndarray
    options: ConditioningOptions
    choice: CutoffChoice | None = None
    warnings: list[str] = field(default_factory=list)
    runs: list = field(default_factory=list)
    acceleration_rows: Rows | None = None
    column_noise: ColumnNoise | None = None
    period_groups: np.ndarray | None = None
    row_ticks: np.ndarray | None = None
    lag_ticks: int = 0
    offset_columns: np.ndarray | None = None
    run_rows: tuple[int, ...] = ()
    row_t: np.ndarray | None = None

    def __iter__(self):  # (cond, A, y), as before
        return iter((self.cond, self.A, self.y))

    def error_model(self) -> dict:
        """What LS and WLS are told of these rows' errors (the keywords of
        :class:`~guardid.estimators.LeastSquares`): the columns' rounding noise, the
        period groups, and the ticks and window of the noise neighbours share."""
        return {"column_noise": self.column_noise, "row_groups": self.period_groups,
                "row_ticks": self.row_ticks, "lag_ticks": self.lag_ticks}  # fmt: skip


def identification_rows(
    t_s,
    q_rad,
    effort,
    description,
    options: ConditioningOptions | None = None,
    *,
    in_current_units: bool = False,
    effort_is_torque: bool = False,
    highest_harmonic_hz: float | None = None,
):
    """(conditioned, A (M, n, b'), y (M, n)) of one run: :func:`stacked_rows` on it alone."""
    return tuple(
        stacked_rows(
            [(t_s, q_rad, effort)],
            description,
            options,
            in_current_units=in_current_units,
            effort_is_torque=effort_is_torque,
            highest_harmonic_hz=highest_harmonic_hz,
        )  # fmt: skip
    )


def stacked_rows(
    runs,
    description,
    options: ConditioningOptions | None = None,
    *,
    in_current_units: bool = False,
    effort_is_torque: bool = False,
    highest_harmonic_hz: float | None = None,
    periods_s=None,
) -> Rows:
    """Rows of several runs (t [s] (N,), q (N, n), effort (N, n)), each conditioned on its
    own under the same ``options`` and stacked (times shifted so that they keep increasing).

    ``options.cutoff_hz`` None: in the momentum form 2 x ``highest_harmonic_hz`` [Hz] (the
    excitation's highest harmonic from a guardid log header; else 2 x the positions'
    bandwidth), at least 2 Hz (:func:`guardid.conditioning.momentum.momentum_cutoff`); in the
    acceleration form chosen by cross-validation over the runs
    (:func:`guardid.identify.cutoff.choose_cutoff_cv`, informed by ``highest_harmonic_hz``).
    The form: ``options.equation``, or
    :func:`~guardid.identify.equation.resolve_equation`'s default.
    ``effort_is_torque``: the effort is measured joint torque (gain 1, instantaneous
    samples); ``in_current_units``: no current-to-torque gain (y in the effort's unit).
    ``periods_s``: per run the period [s] its excitation repeats with (None: unknown), for
    :func:`period_groups`.
    """
    options = options or ConditioningOptions()
    runs = list(runs)
    model = build_model(description)
    free = free_columns(model, description)
    options, why = resolve_equation(options, runs, model, effort_is_torque)
    if options.equation == "acceleration" and options.decimate == 0:
        options = replace(options, decimate=None)  # its default spacing is 1 / (2 fc)
    form_rows = momentum_rows if options.equation == "momentum" else acceleration_rows
    form = form_rows(runs, description, options, why, model, free, in_current_units,
                     effort_is_torque, highest_harmonic_hz)  # fmt: skip
    A, y = _stacked(form.A, form.y, free)
    joined = _join(form.conds)
    joined.notes[:0] = form.first_notes
    joined.notes.extend(form.last_notes)
    groups = period_groups(form.conds, periods_s or [None] * len(form.conds))
    if groups is not None and len(groups) != len(A):
        groups = None  # rows and conditioned samples do not line up: no grouping
    if groups is not None:
        joined.notes.append(f"rows grouped by their phase in the excitation's period "
                            f"({phase_group_count(groups)} groups; LS and WLS count in their "
                            "std an error that repeats every period)")  # fmt: skip
    doubts = _doubts(form.conds, form.choice)
    ticks = row_ticks(form.conds, form.lag_ticks) if form.lag_ticks > 0 else None
    if ticks is not None and (len(ticks) != len(A) or np.unique(ticks).size != ticks.size):
        ticks = None  # rows and conditioned samples do not line up, or two share a tick
        doubts.append("the rows' ticks do not line up with the log's time stamps: LS and WLS "
                      "take the rows' errors as independent, and their std is too small; "
                      "use --spaced-rows")  # fmt: skip
    if ticks is not None:
        joined.notes.append(f"rows within {form.lag_ticks} ticks of each other share "
                            "their noise through the filter (LS and WLS count it)")  # fmt: skip
    return Rows(joined, A, y, form.options, form.choice, doubts,
                form.conds if form.keep_runs else [], column_noise=form.column_noise,
                period_groups=groups, row_ticks=ticks,
                lag_ticks=form.lag_ticks if ticks is not None else 0,
                offset_columns=_joined(form.offset_columns),
                run_rows=tuple(len(a) for a in form.A), row_t=_row_times(form))  # fmt: skip


def _row_times(form) -> np.ndarray | None:
    """(M,) each stacked row's time on its run's clock [s] (None when the conditioned
    samples do not line up with the rows)."""
    times = [np.asarray(c.t, dtype=float)[c.mask] for c in form.conds]
    if [len(t) for t in times] != [len(a) for a in form.A]:
        return None
    return np.concatenate(times)


def row_ticks(conds, lag_ticks: int) -> np.ndarray:
    """(M,) the tick of each stacked usable row of ``conds`` (one conditioned run each,
    ticks ``cond.t`` on a grid of its median step), the runs more than ``lag_ticks`` ticks
    apart so that no two runs' rows count as neighbours."""
    out, start = [], 0
    for cond in conds:
        t = np.asarray(cond.t, dtype=float)
        dt = float(cond.momentum.dt) if getattr(cond, "momentum", None) is not None else (
            float(np.median(np.diff(t))) if t.size > 1 else 1.0)  # fmt: skip
        tick = mom.tick_count(t, dt)
        out.append(tick[cond.mask] + start)
        start += int(tick[-1]) + int(lag_ticks) + 1 if tick.size else 0
        step = max(int(getattr(cond, "decimation", 1)), 1)
        start = -(-start // step) * step  # a whole number of row spacings: rows every m-th
        # tick of every run lie on one grid of step m (the covariance's sums)
    return np.concatenate(out)


def period_groups(conds, periods_s) -> np.ndarray | None:
    """(M,) group labels of the stacked rows of ``conds`` (one conditioned run each): the
    rows of a run whose excitation repeats with period ``periods_s[k]`` [s] and that spans
    at least two periods are grouped by their phase in it, in bins one row spacing wide
    centred on the first row's phase (so that a group holds the rows of the same phase,
    about one per period); other rows are a group each. None when no run is grouped. The
    least squares covariance counts an error common to a group
    (:class:`~guardid.estimators.LeastSquares`, ``row_groups``): what follows the motion,
    as the encoder's rounding through the closed loop, comes back every period and does
    not average out over the log."""
    labels, start, grouped = [], 0, False
    for cond, period in zip(conds, periods_s, strict=True):
        t = np.asarray(cond.t)[cond.mask]
        label = np.arange(t.size)
        if period and t.size > 2 and t[-1] - t[0] >= 2.0 * period:
            spacing = float(np.median(np.diff(t)))
            bins = max(int(round(period / spacing)), 1)
            # bins centred on the first row's phase and its multiples of period / bins: rows
            # that repeat at exactly the same phase (a period a whole number of row
            # spacings) sit in a bin's middle, not on an edge where rounding would scatter
            # them over two groups
            label = np.rint(np.mod(t - t[0], period) / period * bins).astype(int) % bins
            grouped = True
        labels.append(label + start)
        start += int(label.max()) + 1 if label.size else 0
    return np.concatenate(labels) if grouped else None


def phase_group_count(groups) -> int:
    """The groups of :func:`period_groups`' labels that hold two rows or more (the phases;
    the rows of a run not grouped are a group each and are not counted)."""
    return int(np.count_nonzero(np.unique(groups, return_counts=True)[1] > 1))


def _joined(blocks):
    """The runs' blocks stacked (None stays None)."""
    if blocks is None:
        return None
    return blocks[0] if len(blocks) == 1 else np.concatenate(blocks)


def _stacked(As, ys, free):
    """The runs' rows stacked; one-line error when too few for the parameters."""
    A, y = (As[0], ys[0]) if len(As) == 1 else (np.concatenate(As), np.concatenate(ys))
    if len(A) <= len(free):
        raise GuardidError(
            f"only {len(A)} usable rows after conditioning (need more than {len(free)}): "
            "the run is too short or the joints hardly move"
        )
    return A, y


def closed_loop_rows(rows):
    """The rows IV and DIDIM fit: they condition their simulated closed loop like the
    measured run, row for row, in the acceleration form (the momentum form's per-joint cuts
    follow the measured run's stops; lining a simulated run up with them is not wired yet).
    ``rows.rows`` when already in that form; else the runs conditioned again in it, once per
    call of :func:`~guardid.identify.pipeline.identify` (kept on ``rows.rows``). ``rows``:
    the :class:`~guardid.identify.methods.FitRows` the methods are given."""
    if rows.rows.options.equation == "acceleration":
        return rows.rows
    cached = rows.rows.acceleration_rows
    if cached is None:
        options = rows.options.conditioning or ConditioningOptions()
        # the acceleration form at its own spacing: its std is white (never every tick)
        options = replace(options, equation="acceleration", order=None, decimate=None)
        cached = stacked_rows(
            [run_signals(r, rows.runs) for r in rows.runs], rows.description, options,
            in_current_units=rows.options.in_current_units,
            effort_is_torque=rows.effort_is_torque,
            highest_harmonic_hz=rows.runs[0].highest_harmonic_hz,
        )  # fmt: skip
        rows.rows.acceleration_rows = cached
    return cached


def predicted_effort(cond, model, theta) -> np.ndarray:
    """(M, n) the effort that ``model`` with base parameters ``theta`` (b,) predicts on the
    usable rows of ``cond`` (either equation form; zero on a joint's cut rows)."""
    m = cond.mask
    if getattr(cond, "equation", "acceleration") == "momentum":
        return mom.regressor_rows(cond.momentum, model)[m] @ theta
    q, qd, qdd = cond.q[m], cond.qd[m], cond.qdd[m]
    return model.base_regressor(q, qd, qdd) @ theta + model.known_torque(q, qd, qdd)


def _join(conds):
    if len(conds) == 1:
        return replace(conds[0], notes=[n for n in conds[0].notes if not n.startswith("cut-off")])
    ts, start = [], 0.0
    for c in conds:
        ts.append(c.t - c.t[0] + start)
        start = ts[-1][-1] + float(np.median(np.diff(c.t)))
    notes = [n for n in conds[0].notes if not n.startswith("cut-off")]
    notes.append(f"{len(conds)} runs conditioned separately, rows stacked")
    dropped = {k: sum(c.dropped.get(k, 0) for c in conds) for k in conds[0].dropped}
    raw = None
    if all(c.tau_raw is not None for c in conds):
        raw = np.concatenate([c.tau_raw for c in conds])
    jm = None
    if all(c.joint_mask is not None for c in conds):
        jm = np.concatenate([c.joint_mask for c in conds])
    return replace(
        conds[0],
        t=np.concatenate(ts),
        **{f: np.concatenate([getattr(c, f) for c in conds])
           for f in ("q", "qd", "qdd", "tau", "mask", "stiction")},
        tau_raw=raw, dropped=dropped, notes=notes, joint_mask=jm, momentum=None,
    )  # fmt: skip


def rows_summary(cond) -> str:
    """'rows: M of N conditioned samples used; dropped: ...' for the report, then the
    parallel filter's notes (how it was chosen, the decimation after it) or the momentum
    form's row spacing's (why not every tick), one a line."""
    n, used = len(cond.mask), int(cond.mask.sum())
    why = ", ".join(f"{v} {k}" for k, v in cond.dropped.items() if v)
    dec = f" (after decimation by {cond.decimation})" if cond.decimation > 1 else ""
    parallel = [note for note in cond.notes if note.startswith("parallel filter")]
    jm = getattr(cond, "joint_mask", None)
    if jm is not None:  # the momentum form: a joint's rows are cut on their own
        zeroed = int((~jm[cond.mask]).sum())
        spacing = [note for note in cond.notes if note.startswith("rows every")]
        return (f"rows: {used} of {n} conditioned samples{dec} used, {zeroed} joint rows of "
                f"them zeroed (that joint's equation cut)"
                + (f"; joint rows cut: {why}" if why else "")
                + "".join("\n" + note for note in spacing))  # fmt: skip
    return (
        f"rows: {used} of {n} conditioned samples{dec} used"
        + (f"; dropped {why}" if why else "")
        + "".join("\n" + note for note in parallel)
    )


def _doubts(conds, choice) -> list[str]:
    """Warnings about the conditioning: most rows dropped, effort power beyond the cut-off,
    a cross-validation minimum at the edge of the candidates."""
    out = []
    n = sum(len(c.mask) for c in conds)
    used = sum(int(c.mask.sum()) for c in conds)
    if n and used < MOST_ROWS_DROPPED * n:
        out.append(
            f"only {used} of {n} conditioned samples usable ({100 * used / n:.0f} %): the fit "
            "rests on a small part of the data (see the dropped rows above)"
        )
    if all(c.tau_raw is not None for c in conds):
        raw = np.concatenate([c.tau_raw - c.tau_raw.mean(0) for c in conds])
        cut = np.concatenate([c.tau_raw - c.tau for c in conds])
        total = float(np.sum(raw**2))
        frac = float(np.sum(cut**2)) / total if total > 0 else 0.0
        if frac > POWER_BEYOND_CUTOFF:
            out.append(
                f"{100 * frac:.0f} % of the effort's power lies beyond the {conds[0].cutoff_hz:g} "
                "Hz cut-off (noise, or motion the model does not see): check the cut-off"
            )
    if choice is not None and len(choice.candidates) > 1:
        if choice.cutoff_hz in (choice.candidates[0], choice.candidates[-1]):
            out.append(
                f"the cut-off {choice.cutoff_hz:g} Hz is at the edge of the candidates "
                f"({choice.candidates[0]:g}-{choice.candidates[-1]:g} Hz): the best may lie beyond"
            )
    return out
