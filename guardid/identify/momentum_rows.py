"""Identification path, momentum form: every run's rows.

Takes the runs (t [s] (N,), q (N, n) [rad | m], effort (N, n) [A | N m | N][, measured qd])
and the options, equation form resolved (:func:`guardid.identify.equation.resolve_equation`);
gives :class:`~guardid.identify.equation.FormRows`: per run the rows of the filtered
momentum equation (:func:`guardid.conditioning.momentum.condition_momentum`: one causal
filter on both sides, nothing differentiated twice) on their usable rows, the cut-off [Hz]
(2 x the excitation's highest harmonic, else x the positions' band, at least 2 Hz), and the
encoder rounding's noise in the columns that LS and WLS remove (:func:`quantisation_noise_of`).
Rows closer than that default spacing (``options.decimate``, e.g. 1: every tick) share their
noise: LS and WLS then count it (the residuals' autocovariance over
:func:`mom.correlation_ticks`).
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from guardid.conditioning import momentum as mom
from guardid.conditioning.units import counts_per_joint_rev
from guardid.estimators import ColumnNoise
from guardid.identify.cutoff import CutoffChoice, motion_bandwidth
from guardid.identify.equation import (
    FormRows,
    effort_gain,
    position_limits,
    smooth_friction_joints,
)


def momentum_rows(runs, description, options, why, model, free, in_current_units,
                  effort_is_torque, highest_harmonic_hz) -> FormRows:  # fmt: skip
    """The rows of :func:`guardid.identify.rows.stacked_rows` in the momentum form (module
    docstring; :mod:`guardid.conditioning.momentum`); ``why`` (why this form): the forms'
    common signature, not repeated in this form's notes; ``model``, ``free``: the
    description's model and its identified columns."""
    t0 = np.asarray(runs[0][0], dtype=float)
    fs = 1.0 / float(np.median(np.diff(t0)))
    cutoff = options.cutoff_hz
    if cutoff is None:
        band = motion_bandwidth(runs, highest_harmonic_hz)
        cutoff = mom.momentum_cutoff(fs, band, bool(highest_harmonic_hz))
        src = "the excitation's highest harmonic" if highest_harmonic_hz else "the positions' "
        src += "" if highest_harmonic_hz else "99.5 % energy bandwidth"
        factor = mom.HARMONIC_FACTOR if highest_harmonic_hz else mom.SPECTRUM_FACTOR
        reason = (f"cut-off {cutoff:g} Hz of the momentum form's filter: {factor:g} x {src} "
                  f"({band:.3g} Hz), at least {mom.MIN_CUTOFF_HZ:g} Hz")  # fmt: skip
    else:
        reason = f"cut-off {cutoff:g} Hz of the momentum form's filter, set by the caller"
    used = replace(options, cutoff_hz=float(cutoff), friction_filter=False)
    gain = effort_gain(description, in_current_units, effort_is_torque)
    limits = position_limits(description)
    thr = options.stiction_threshold
    if thr is None:  # smooth friction holds through zero velocity
        thr = np.where(smooth_friction_joints(description), 0.0, np.nan)
    flat = (not effort_is_torque) if options.flat_is_stuck is None else options.flat_is_stuck
    spaced = mom.decimation(fs, float(cutoff))  # rows about independent
    lag = mom.correlation_ticks(fs, float(cutoff))
    spacing, ticks = options.decimate, sum(len(r[0]) for r in runs)
    if spacing is None:
        spacing = mom.row_spacing(ticks, fs, float(cutoff))
    elif spacing == 0:
        spacing = spaced
    fixed = [i for i in range(len(model.base.names)) if i not in free]
    base = model.base.values(model.params)
    offsets = offset_columns(model)

    def mean_ticks(spacing):
        """Rows between every tick and the spaced ones: the mean of their spacing's ticks."""
        return spacing if 1 < spacing < spaced else 1

    def rows_every(spacing):
        """(conds, As, ys, noises, Os): every run's usable rows, one every ``spacing``
        ticks, and their friction-offset columns (:func:`offset_columns`)."""
        conds, As, ys, noises, Os = [], [], [], [], []
        for run in runs:
            t, q, effort, *rest = run
            cond, A_all, y = mom.condition_momentum(
                t, q, effort, model, gain=gain, cutoff_hz=cutoff, order=used.order,
                decimate=spacing, effort_is_torque=effort_is_torque, stiction_threshold=thr,
                flat_is_stuck=flat, position_limits=limits,
                velocity=rest[0] if rest else None, mean_ticks=mean_ticks(spacing),
            )  # fmt: skip
            if fixed and not in_current_units:
                y = y - A_all[:, :, fixed] @ base[fixed]
            m = cond.mask
            noises.append(quantisation_noise_of(cond, rest, description, options, model, free,
                                                base if fixed and not in_current_units else None,
                                                gain))  # fmt: skip
            conds.append(cond)
            # one copy of the kept rows' identified columns; A_all freed before the next run
            As.append(A_all[np.ix_(np.flatnonzero(m), np.arange(A_all.shape[1]), free)])
            ys.append(y[m])
            if offsets is not None:
                Os.append(A_all[np.ix_(np.flatnonzero(m), np.arange(A_all.shape[1]), offsets)])
            del A_all
        return conds, As, ys, noises, Os

    conds, As, ys, noises, Os = rows_every(spacing)
    spacing_note = []
    if options.decimate is None and 1 < spacing < spaced:
        spacing_note = [f"rows every {spacing} ticks, each the mean of its {spacing} ticks: at "
                        f"most {mom.MAX_ROWS} rows of a log of {ticks} ticks (identify's "
                        "memory; docs/IDENTIFY.md)"]  # fmt: skip
    # the window with the mean's ticks, as the fit's check (identify.pipeline._fit_rows)
    need = mom.ticks_needed(len(free), lag + mean_ticks(spacing) - 1)
    usable = spacing * sum(len(a) for a in As)
    if options.decimate is None and spacing < spaced and usable < need:
        spacing_note = [f"rows every {spaced} ticks (1 / (2 x cut-off)): {usable} usable "
                        f"ticks are too few for closer rows' std ({len(free)} parameters "
                        f"over a window of {lag + mean_ticks(spacing)} ticks need {need}; "
                        "docs/IDENTIFY.md)"]  # fmt: skip
        spacing = spaced
        conds, As, ys, noises, Os = rows_every(spacing)
    noise, note = _noise_of_runs(noises)
    used = replace(used, quantisation=noise is not None)
    choice = CutoffChoice(float(cutoff), reason.split(": ", 1)[-1], [float(cutoff)])
    used = replace(used, decimate=int(spacing))  # resolved: validate reuses it
    # rows closer than the default spacing share their noise through the filter (and the
    # mean over the spacing's ticks, which widens its impulse response)
    lag = lag + mean_ticks(spacing) - 1 if spacing < spaced else 0
    return FormRows(conds, As, ys, used, choice if options.cutoff_hz is None else None,
                    [reason], [note, *spacing_note], noise, keep_runs=True,
                    lag_ticks=lag, offset_columns=Os if offsets is not None else None)  # fmt: skip


def offset_columns(model) -> list[int] | None:
    """Indices in ``model``'s base columns of each joint's friction offset ``Fo<j>``, in
    joint order (whether identified or not: a constant torque on the joint, which is also
    what a current sensor's zero offset adds, :mod:`guardid.identify.current_zero`); None
    when a joint has none (no friction model)."""
    names = list(model.base.names)
    wanted = [f"Fo{j + 1}" for j in range(len(model.description.joints))]
    return [names.index(w) for w in wanted] if all(w in names for w in wanted) else None


def quantisation_noise_of(cond, rest, description, options, model, free, base, gain):
    """(S (n, b', b'), c (n, b')) of one run's momentum rows (:func:`mom.quantisation_noise`
    on the identified columns; ``base`` (b,) the description's base values when the fixed
    columns' part was taken off y, else None), or a string saying why there is none:
    ``options.quantisation`` False (True, as None: where the log allows), measured
    velocities, a joint without an encoder, or positions off the encoder's grid (not whole
    counts: the rounding is not that one)."""
    if options.quantisation is False:
        return "off (--no-quantisation-compensation)"
    why = ""
    if rest:
        why = "the log's measured velocities are used"
    elif any(j.encoder is None for j in description.joints):
        why = "a joint without an encoder in the robot description"
    else:
        res = 2.0 * np.pi / counts_per_joint_rev(description)
        off = ~mom.on_grid(cond.momentum.q, res)
        if off.any():
            names = ", ".join(description.joints[j].name for j in np.flatnonzero(off))
            why = f"positions of {names} off the encoder's grid"
    if why:
        return why
    damping = mom.electrical_damping(description, gain)
    S, c = mom.quantisation_noise(cond.momentum, model, res, damping)
    fixed = [i for i in range(S.shape[1]) if i not in free]
    cross = c[:, free]
    if base is not None and fixed:  # y less the fixed columns: their noise is in y
        cross = cross - S[:, free][:, :, fixed] @ base[fixed]
    return S[:, free][:, :, free], cross


def _noise_of_runs(noises):
    """(ColumnNoise summed over the runs or None, a note for the conditioning notes)."""
    why = [n for n in noises if isinstance(n, str)]
    if why:
        return None, f"encoder quantisation not compensated: {why[0]}"
    S = sum(n[0] for n in noises)
    c = sum(n[1] for n in noises)
    what = ("encoder quantisation compensated (bias-compensated LS and WLS): the rounding's "
            f"noise in the columns estimated from {mom.QUANTISATION_DRAWS} draws on at most "
            f"{mom.QUANTISATION_WINDOWS} windows of {mom.QUANTISATION_WINDOW_TICKS} ticks per "
            "run")  # fmt: skip
    return ColumnNoise(S, c, what), what


def momentum_rows_of(rows, run: int, q, model, free) -> np.ndarray:
    """(M_run, n, b') run ``run``'s usable rows of the momentum form recomputed from other
    positions ``q`` (N, n) on the same ticks (e.g. its closed loop simulated, for
    instruments): the measured run's cuts, filter and kept rows, velocities from ``q``.
    ``rows``: the momentum form's :class:`~guardid.identify.rows.Rows`."""
    cond = rows.runs[run]
    A_all = mom.rows_like(cond.momentum, model, np.asarray(q, dtype=float))
    return A_all[cond.mask][:, :, free]
