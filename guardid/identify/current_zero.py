"""The current sensors' zero: how far the std can trust it, and the zero a capture read.

A current sensor that reads ``z`` [A] more than flows adds the constant torque
``N eta Kt z`` to the joint's effort: in the regression that is the joint's friction-offset
column ``Fo`` times ``N eta Kt z``. Over the tilt's short travel its gravity is nearly a
constant torque and a pan's Coulomb and viscous friction share the rest, so the
estimates move by ``G z`` (``G`` (b', n): :func:`zero_sensitivity`), and a fraction of an
ADC step is more than a std on a minute's log (docs/IDENTIFY.md 'The current sensors' zero').

Two things follow from ``G``:

* the *tolerance*: per joint the zero error [A] that moves some parameter by one of its std
  (the verdict method's). The std say nothing of a zero error; they hold while each sensor's
  zero is known to well within it. Reported for every motor-current log (not for a joint
  without friction in the momentum form, which has no offset column).
* a guardid log whose footer has ``current_zero`` (``capture --zero-rest``: the sensors read
  at rest with the motors at 0 V) gives the zero itself, ``mean +- std_error``. ``subtract``
  (default) takes it off the joint's currents, ``ignore`` leaves them (for a zero known
  exactly some other way). A subtracted zero's own error moves the estimates by ``G``
  times it: every covariance gains ``G S G^T`` (S the zeros' variances; each log's zero is
  its own error, shared by its segments). Every read zero is taken off, not only one
  beyond its noise: a zero left in because it was within, say, 4 of its std errors could
  move a parameter by about 4 tolerances unseen. A zero beyond ZERO_SIGNIFICANCE std
  errors from 0 is also a warning: the sensor is off, and zeroing it would spare the
  widening.
* a footer with both ``current_zero_before`` and ``current_zero`` (each joint's with
  ``t_s``, the readings' mean time on the log's clock) gives the zero's drift over the run
  (a Hall sensor warming up): the zero taken off is the straight line through the two, at
  each row's time. Each reading's error then moves the estimates by the effect of its own
  share of the line (1 at its rest, 0 at the other's): the friction-offset column times
  that share at each row (the filters' delay, a tenth of a second, is small against the
  run). Two zeros further apart than ZERO_SIGNIFICANCE of their std errors is a warning:
  the line is counted, a zero that moves otherwise is not.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from guardid.errors import LogFormatError

ZERO_SIGNIFICANCE = 4.0
"""A zero beyond this many of its std errors from 0 is a warning [-] (an honest sensor's
reads beyond it in about 6e-5 of joints)."""
MODES = ("subtract", "ignore")
KEYS = ("current_zero_before", "current_zero")  #: the footer's zeros, before and after the run
COUNTED = "every std counting its error"
NOT_COUNTED = (
    "its error NOT counted in the std (no friction-offset column to carry it: a joint "
    "without friction in the momentum form; the std hold only if the read zero is exact)"
)
TELEMETRY_CURRENT_A = 1e-3  #: the telemetry's current unit [A]: a reading's resolution at least


@dataclass(frozen=True)
class SensorZero:
    """One joint's zero as a capture read it: ``mean_a`` [A], ``std_error_a`` [A] (the
    mean's std, :func:`sensor_zeros`), ``rows`` read, ``t_s`` the readings' mean time on
    the log's clock [s] (None: not known)."""

    mean_a: float
    std_error_a: float
    rows: int
    t_s: float | None = None

    @property
    def significance(self) -> float:
        """|mean| in std errors [-]."""
        return abs(self.mean_a) / self.std_error_a if self.std_error_a > 0 else math.inf


def footer_zero(path, footer: dict | None, key: str = "current_zero") -> dict | None:
    """The footer's ``key`` (``current_zero``, ``current_zero_before``) checked: ``{joint:
    {mean_a, std_a, rows[, readings_ma][, t_s]}}``, ``{not_measured: why}``, or None when
    there is none. One line naming the log and the field when it is malformed (a joint
    the robot lacks is said by :func:`subtract_zeros`)."""
    zero = (footer or {}).get(key)
    if zero is None:
        return None
    if isinstance(zero, dict) and "not_measured" in zero:
        return {"not_measured": str(zero["not_measured"])}
    where = f"{path}: footer: {key}"
    if not isinstance(zero, dict):
        raise LogFormatError(f"{where}: expected a mapping of joints, got {zero!r}")
    for joint, entry in zero.items():
        if not isinstance(entry, dict):
            raise LogFormatError(f"{where}: {joint}: expected mean_a, std_a and rows")
        for key in ("mean_a", "std_a", "rows"):
            value = entry.get(key)
            if isinstance(value, bool) or not isinstance(value, (int, float)):
                raise LogFormatError(f"{where}: {joint}: {key}: expected a number, got {value!r}")
            if not math.isfinite(value) or (key != "mean_a" and value < 0):
                raise LogFormatError(f"{where}: {joint}: {key}: {value!r} is not usable")
        t_s = entry.get("t_s")
        if t_s is not None and (isinstance(t_s, bool) or not isinstance(t_s, (int, float))
                                or not math.isfinite(t_s)):  # fmt: skip
            raise LogFormatError(f"{where}: {joint}: t_s: expected a time [s], got {t_s!r}")
        if not _whole(entry["rows"]) or entry["rows"] < 2:
            raise LogFormatError(f"{where}: {joint}: rows: {entry['rows']!r} (a count, at least 2)")
        hist = entry.get("readings_ma")
        if hist is not None and not (
            isinstance(hist, list)
            and all(isinstance(p, list) and len(p) == 2 and all(map(_whole, p)) and p[1] >= 1
                    for p in hist)
            and sum(p[1] for p in hist) == entry["rows"]
        ):  # fmt: skip
            raise LogFormatError(
                f"{where}: {joint}: readings_ma: expected [whole mA, count] pairs, the counts "
                f"summing to rows ({entry['rows']!r})"
            )
    # what identify works out itself (zero_on_levels) is not taken from the file
    return {j: {k: v for k, v in e.items() if k != "on_levels"} for j, e in zero.items()}


def _whole(x) -> bool:
    return isinstance(x, int) and not isinstance(x, bool)


def zero_on_levels(entry: dict, sensor, unit_a: float) -> dict:
    """A footer zero's entry with its readings (``readings_ma``: [mA, count] pairs) put on the
    ADC's levels as the joint's logged current was
    (:func:`~guardid.conditioning.units.readings_on_levels`): mean and std of the levels,
    ``on_levels`` True. The entry as it is when it has no readings or one is no level's."""
    from guardid.conditioning.units import readings_on_levels

    hist = entry.get("readings_ma")
    if not hist:
        return entry
    values = np.array([float(v) * 1e-3 for v, _ in hist])
    counts = np.array([float(c) for _, c in hist])
    levels = readings_on_levels(values, sensor.range, sensor.adc_bits, unit_a)
    if levels is None:
        return entry
    n = counts.sum()
    mean = float(np.sum(counts * levels) / n)
    std = float(np.sqrt(np.sum(counts * (levels - mean) ** 2) / (n - 1)))
    return {**entry, "mean_a": mean, "std_a": std, "on_levels": True}


def sensor_zeros(run, description, key: str = "current_zero") -> list[SensorZero | None]:
    """Per joint of ``description`` the zero ``run``'s footer gives (``key``: the one read
    after the run, ``current_zero_before`` the one before; None: none). Its std
    error: the readings' std (at least the description's sensor noise: a few readings' std
    can be far too small) over sqrt(rows); plus the ADC step's rounding (step^2 / 12) when
    the readings are too quiet to dither it (their std below half a step), and the
    telemetry unit's (unit^2 / 12) when they were not put back on the ADC's levels
    (:func:`zero_on_levels`)."""
    zero = getattr(run, key, None) or {}
    if "not_measured" in zero:
        zero = {}
    out: list[SensorZero | None] = []
    for joint in description.joints:
        entry = zero.get(joint.name)
        if entry is None or joint.drive is None:
            out.append(None)
            continue
        step, read, rows = TELEMETRY_CURRENT_A, float(entry["std_a"]), int(entry["rows"])
        std = read
        if joint.current_sensor is not None:
            cs = joint.current_sensor
            step = max(step, 2.0 * cs.range / 2**cs.adc_bits)
            std = max(read, float(cs.noise))
        var = std**2 / rows
        if read < step / 2:  # too quiet to dither the resolution: its rounding stays
            var += step**2 / 12.0
        if not entry.get("on_levels"):
            # the telemetry's rounding to whole units, not undone: it follows the level, so
            # the rest's few levels and the run's many carry different mean errors
            var += TELEMETRY_CURRENT_A**2 / 12.0
        t_s = entry.get("t_s")
        out.append(SensorZero(float(entry["mean_a"]), math.sqrt(var), rows,
                              None if t_s is None else float(t_s)))  # fmt: skip
    return out


@dataclass(frozen=True)
class Share:
    """A zero's share of the zero taken off at each time: 1 at ``t_at`` [s] (its rest), 0 at
    ``t_other`` [s] (the other zero's), a straight line through both (the log's clock)."""

    t_at: float
    t_other: float

    def of(self, t_s) -> np.ndarray:
        """The share [-] at times ``t_s`` [s]."""
        return (np.asarray(t_s, dtype=float) - self.t_other) / (self.t_at - self.t_other)


@dataclass(frozen=True)
class ZeroRead:
    """One zero read of a joint: ``zero``; ``when`` ('before' or 'after' the run);
    ``share`` (:class:`Share`) when it is one end of a line between two, None when it is
    taken off as a constant."""

    zero: SensorZero
    when: str
    share: Share | None = None

    def at(self, t_s) -> np.ndarray | float:
        """The zero's part [A] of what is taken off at times ``t_s`` [s]."""
        return self.zero.mean_a if self.share is None else self.zero.mean_a * self.share.of(t_s)


def zeros_read(run, description) -> list[tuple[ZeroRead, ...]]:
    """Per joint the zeros ``run``'s footer gives (:func:`sensor_zeros`): both ends of a line
    when the zero was read before and after the run with their times, else the one read
    (a constant; of two without times, the one after), else none. One line naming the log,
    the field and the joint (:class:`LogFormatError`) when two zeros' times cannot be
    theirs: one without a time, or a time inside the run's rows."""
    after = sensor_zeros(run, description)
    before = sensor_zeros(run, description, "current_zero_before")
    t = np.asarray(run.t, dtype=float)
    out = []
    for joint, a, b in zip(description.joints, after, before, strict=True):
        if a is not None and b is not None:
            _check_times(run, joint.name, a.t_s, b.t_s, t)
        if a is not None and b is not None and a.t_s is not None:
            out.append((ZeroRead(b, "before", Share(b.t_s, a.t_s)),
                        ZeroRead(a, "after", Share(a.t_s, b.t_s))))  # fmt: skip
        elif a is not None:
            out.append((ZeroRead(a, "after"),))
        elif b is not None:
            out.append((ZeroRead(b, "before"),))
        else:
            out.append(())
    return out


def _check_times(run, joint: str, after_s, before_s, t) -> None:
    """Both zeros' times, or neither; the one before at or before the run's first row, the
    one after at or after its last (LogFormatError naming the field)."""
    where = f"{run.source or run.path}: footer"
    if (after_s is None) != (before_s is None):
        key = "current_zero" if after_s is None else "current_zero_before"
        raise LogFormatError(f"{where}: {key}: {joint}: t_s: missing where the other rest's "
                             "zero has one")  # fmt: skip
    if after_s is None or not t.size:
        return
    if before_s > t[0]:
        raise LogFormatError(f"{where}: current_zero_before: {joint}: t_s: {before_s!r} is not "
                             f"before the run's first row ({t[0]:g} s)")  # fmt: skip
    if after_s < t[-1]:
        raise LogFormatError(f"{where}: current_zero: {joint}: t_s: {after_s!r} is not after "
                             f"the run's last row ({t[-1]:g} s)")  # fmt: skip


@dataclass(frozen=True)
class Subtracted:
    """A zero taken off one log's joint: which ``source`` log, ``joint`` index, the zero,
    ``when`` it was read, its ``share`` of the line between two (None: a constant)."""

    source: str
    joint: int
    zero: SensorZero
    when: str = "after"
    share: Share | None = None


@dataclass(frozen=True)
class ZerosRead:
    """What the logs' footers gave: ``taken`` the zeros subtracted (one per log and joint,
    the segments of a log sharing it); ``lines`` per log what its zero was and what was
    done; ``warnings`` per joint whose zero lies beyond ZERO_SIGNIFICANCE std errors."""

    taken: tuple[Subtracted, ...] = ()
    lines: tuple[str, ...] = ()
    warnings: tuple[str, ...] = ()


def subtract_zeros(runs, description, mode: str) -> tuple[list, ZerosRead]:
    """(runs, read): each run's currents less the zeros its footer gives (``mode``
    ``subtract``: a constant, or at each row the line between the zeros read before and
    after the run, :func:`zeros_read`; ``ignore``: the runs as they are), and what was read
    and done."""
    if mode not in MODES:
        raise ValueError(f"current zero: mode {mode!r} is not one of {', '.join(MODES)}")
    out, taken, lines, warnings, seen = [], [], [], [], set()
    n = len(description.joints)
    for run in runs:
        reads = [()] * n if run.torque else zeros_read(run, description)
        source = run.source or run.path
        if source not in seen:  # a log's segments share its footer
            seen.add(source)
            footers = {k: getattr(run, k, None) or {} for k in KEYS}
            for key, other in zip(KEYS, reversed(KEYS), strict=True):
                read_other = bool(footers[other]) and "not_measured" not in footers[other]
                warnings += _footer_warnings(source, footers[key], description, key,
                                             read_other, mode)  # fmt: skip
            if any(reads):
                lines.append(_zero_line(source, description, reads, mode))
                warnings += zero_warnings(source, description, reads, mode)
                warnings += drift_warnings(source, description, reads)
                if mode == "subtract":
                    taken += [Subtracted(source, j, r.zero, r.when, r.share)
                              for j, rs in enumerate(reads) for r in rs]  # fmt: skip
        if mode == "subtract" and any(reads):
            shift = np.zeros((len(run.t), n))
            for j, rs in enumerate(reads):
                for r in rs:
                    shift[:, j] += r.at(run.t)
            run = replace(run, current=np.asarray(run.current, dtype=float) - shift)
        out.append(run)
    return out, ZerosRead(tuple(taken), tuple(lines), tuple(warnings))


def _footer_warnings(source, footer: dict, description, key: str = "current_zero",
                     other_read: bool = False, mode: str = "subtract") -> list[str]:  # fmt: skip
    """A zero the capture could not read (``other_read``: the other rest's was read; what
    was done with it as ``mode`` says), and footer joints the robot does not have."""
    out = []
    unknown = sorted(set(footer) - {"not_measured"} - {j.name for j in description.joints})
    if unknown:
        out.append(f"{source}: footer: {key}: {', '.join(unknown)}: no such joint in "
                   "the robot; not used")  # fmt: skip
    if "not_measured" in footer:
        when, other = ("before", "after") if key == "current_zero_before" else ("after", "before")
        if other_read and mode == "subtract":
            out.append(f"{source}: the current sensors' zero was not read {when} the run "
                       f"({footer['not_measured']}): the one read {other} it is taken off as "
                       "a constant; a zero that drifts during the run is not followed")  # fmt: skip
        elif other_read:
            out.append(f"{source}: the current sensors' zero was not read {when} the run "
                       f"({footer['not_measured']}); the one read {other} it is left in "
                       "(--current-zero ignore)")  # fmt: skip
        else:
            out.append(f"{source}: the current sensors' zero was not read "
                       f"({footer['not_measured']}): the std hold only while it is known to "
                       "well within the tolerance the report gives")  # fmt: skip
    return out


def zero_warnings(source, description, reads, mode: str = "subtract") -> list[str]:
    """One line per joint whose zero (:func:`zeros_read`; of two, the one nearer 0: a drift
    alone is said by :func:`drift_warnings`) lies beyond ZERO_SIGNIFICANCE std errors from 0
    (what was done with it as ``mode`` says)."""
    done = ("here it was taken off, the std widened for its error" if mode == "subtract"
            else "here it was left in: the estimates carry it")  # fmt: skip
    out = []
    for joint, rs in zip(description.joints, reads, strict=True):
        z = min((r.zero for r in rs), key=lambda z: z.significance, default=None)
        if z is not None and z.significance > ZERO_SIGNIFICANCE:
            out.append(f"{source}: the {joint.name} current sensor reads {1e3 * z.mean_a:+.2f} "
                       f"+- {1e3 * z.std_error_a:.2f} mA at rest ({z.significance:.0f} std "
                       f"errors from 0): its zero is off; zero the sensor ({done})")  # fmt: skip
    return out


def drift_warnings(source, description, reads) -> list[str]:
    """One line per joint whose zeros read before and after the run lie further apart than
    ZERO_SIGNIFICANCE of their std errors: the sensor's zero moved during the run."""
    out = []
    for joint, rs in zip(description.joints, reads, strict=True):
        if len(rs) != 2:
            continue
        b, a = rs[0].zero, rs[1].zero
        moved, err = a.mean_a - b.mean_a, math.hypot(a.std_error_a, b.std_error_a)
        if abs(moved) > ZERO_SIGNIFICANCE * err:
            out.append(
                f"{source}: the {joint.name} current sensor's zero moved by "
                f"{1e3 * moved:+.2f} mA between the rests before and after the run "
                f"({abs(moved) / err:.0f} std errors; {1e3 * moved / (a.t_s - b.t_s):+.3g} "
                "mA/s): taken off as a straight line between them; the std count a zero "
                "that moves in a straight line, not one that moves otherwise"
            )
    return out


def _zero_line(source, description, reads, mode) -> str:
    parts = []
    for joint, rs in zip(description.joints, reads, strict=True):
        values = [f"{1e3 * r.zero.mean_a:+.2f} +- {1e3 * r.zero.std_error_a:.2f} mA"
                  + (f" {r.when}" if len(rs) > 1 else "") for r in rs]  # fmt: skip
        if values:
            parts.append(f"{joint.name} {', '.join(values)}")
    line = any(len(rs) > 1 for rs in reads)
    how = " as a straight line from before the run to after it" if line else ""
    done = (f"subtracted{how}, {COUNTED}" if mode == "subtract"
            else "left in (--current-zero ignore)")  # fmt: skip
    joined = ("; " if line else ", ").join(parts)
    return f"{source}: current sensors' zero read at rest: {joined}: {done}"


def zero_sensitivity(fit_rows, description, taken=()):
    """(per log, per zero): per log (its source path) the (b', n) change of the estimates
    per ampere of each driven joint's zero taken off as a constant (0 for the others); and
    for each of ``taken`` (:class:`Subtracted`) the (b',) change per ampere of its error
    (its log's column for a constant; the effect of its share of the line for one end of a
    line, :class:`Share`, at each row's time; None when its log has no rows here). WLS
    fitted on the rows, and how its estimate moves with the effort shifted by the joint's
    friction-offset column times N eta Kt over the log's rows
    (:meth:`~guardid.estimators.LeastSquares.effect_of`). WLS stands for every method (each
    is LS-like or judged against it). In the acceleration form a constant effort stays that
    constant through the low-pass (the log's ends aside); in current units the effort's own
    unit. None when it cannot be made: measured torque, the momentum form without offset
    columns (a joint without friction), or a line's share without the rows' times."""
    from guardid.estimators import WeightedLeastSquares
    from guardid.identify.equation import drive_gain

    rows = fit_rows.rows
    if fit_rows.effort_is_torque:
        return None
    gain = np.ones(len(description.joints))
    if not fit_rows.options.in_current_units:
        gain = drive_gain(description)
    if rows.options.equation == "momentum":
        O = rows.offset_columns  # the filtered constant, per unit torque
        if O is None:
            return None
    else:  # the acceleration form: a constant effort stays that constant through its low-pass
        O = np.zeros((*fit_rows.y.shape, len(gain)))
        used = np.any(fit_rows.A != 0, axis=2) | (fit_rows.y != 0)
        for j in range(len(gain)):
            O[:, j, j] = used[:, j]
    shared = [k for k, s in enumerate(taken) if s.share is not None]
    t_rows = getattr(rows, "row_t", None)
    if shared and t_rows is None:
        return None
    A = fit_rows.A
    wls = WeightedLeastSquares(**rows.error_model()).fit(A, fit_rows.y)
    driven = [j for j, joint in enumerate(description.joints) if joint.drive is not None]
    out: dict[str, np.ndarray] = {}
    lines: dict[int, np.ndarray] = {}
    start = 0
    for m, run in zip(rows.run_rows, fit_rows.runs, strict=True):
        source = run.source or run.path
        G = out.setdefault(source, np.zeros((A.shape[2], len(gain))))
        if m:
            block = slice(start, start + m)
            mine = [k for k in shared if taken[k].source == source]
            D = [O[block][:, :, driven] * gain[driven]]  # per ampere of a constant zero
            for k in mine:  # per ampere of a line's end: its share at each row
                j = taken[k].joint
                D.append((O[block][:, :, j] * gain[j] * taken[k].share.of(t_rows[block])[:, None]
                          )[:, :, None])  # fmt: skip
            effect = wls.effect_of(A[block], np.concatenate(D, axis=2))
            G[:, driven] += effect[:, : len(driven)]
            for i, k in enumerate(mine):
                lines[k] = lines.get(k, 0.0) + effect[:, len(driven) + i]
        start += m
    per_zero = [
        lines.get(k) if s.share is not None
        else (out[s.source][:, s.joint] if s.source in out else None)
        for k, s in enumerate(taken)
    ]  # fmt: skip
    return out, per_zero


def tolerance_a(G: np.ndarray, std: np.ndarray) -> np.ndarray:
    """Per joint the zero error [A] that moves some parameter by one of its ``std``, given
    the estimates' change per ampere ``G`` (b', n) (inf: none moves; parameters without a
    finite positive std do not count)."""
    std = np.asarray(std, dtype=float)
    ok = np.isfinite(std) & (std > 0)
    worst = (np.abs(G[ok]) / std[ok, None]).max(axis=0, initial=0.0)
    with np.errstate(divide="ignore"):
        return np.where(worst > 0, 1.0 / worst, np.inf)


def zero_covariance(per_zero, taken) -> np.ndarray:
    """(b', b') the estimates' covariance from the subtracted zeros' own errors (each zero's
    error its own, independent of the others'); ``per_zero`` each one's (b',) change per
    ampere (:func:`zero_sensitivity`; None: its log has no rows)."""
    b = next(len(g) for g in per_zero if g is not None)
    C = np.zeros((b, b))
    for g, s in zip(per_zero, taken, strict=True):
        if g is not None:
            C += np.outer(g, g) * s.zero.std_error_a**2
    return C


@dataclass(frozen=True)
class ZeroOutcome:
    """What the zero stage found: ``mode``; ``sensitivity`` (b', n) the estimates' change
    per ampere of each joint's zero, every log's together (None: not made here);
    ``tolerance_a`` (n,) :func:`tolerance_a` of the verdict method's std (None: not made);
    ``method`` that method; ``subtracted``: the zeros taken off; ``lines``: what the
    report says of it (the zeros read and kept; how well a zero must be known);
    ``effects``: per subtracted zero the (b',) change of the estimates per ampere of its
    error (:func:`zero_sensitivity`; None: not made)."""

    mode: str
    sensitivity: np.ndarray | None = None
    tolerance_a: np.ndarray | None = None
    method: str | None = None
    subtracted: tuple[Subtracted, ...] = ()
    lines: tuple[str, ...] = ()
    effects: tuple = ()

    def to_dict(self, description) -> dict:
        """params.yaml's ``current_zero``."""
        out: dict = {"mode": self.mode, "method": self.method}
        names = [j.name for j in description.joints]
        if self.tolerance_a is not None:
            pairs = zip(names, self.tolerance_a, strict=True)
            out["tolerance_a"] = {n: float(t) for n, t in pairs if np.isfinite(t)}
        out["subtracted"] = [
            {"log": s.source, "joint": names[s.joint], "read": s.when, "mean_a": s.zero.mean_a,
             "std_error_a": s.zero.std_error_a, "rows": s.zero.rows,
             **({} if s.zero.t_s is None else {"t_s": s.zero.t_s}),
             "as": "a constant" if s.share is None else "one end of a straight line"}
            for s in self.subtracted
        ]  # fmt: skip
        return out


def zero_stage(fit_rows, results, taken, description, mode, lines=()) -> ZeroOutcome:
    """The stage after the fits: every result's std (and covariance) widened by the
    subtracted zeros' own errors (``taken``, :func:`subtract_zeros`); the outcome, its
    ``lines`` those given and one on how well the zeros must be known for the verdict
    method's std to hold."""
    from guardid.identify.untrusted import reference_method

    taken, lines = tuple(taken), tuple(lines)
    effects = zero_sensitivity(fit_rows, description, taken)
    if effects is None:
        lines = tuple(line.replace(COUNTED, NOT_COUNTED) for line in lines)
        return ZeroOutcome(mode, subtracted=taken, lines=lines)
    sensitivity, per_zero = effects
    if any(g is not None for g in per_zero):
        C = zero_covariance(per_zero, taken)
        for r in results.values():
            if r.std is None:
                continue
            r.std = np.sqrt(r.std**2 + np.clip(np.diag(C), 0.0, None))
            r.cov = None if r.cov is None else r.cov + C
            with np.errstate(divide="ignore", invalid="ignore"):
                r.rel_std_pct = 100.0 * r.std / np.abs(r.theta)
    G = sum(sensitivity.values())
    ref = reference_method(results)
    if ref is None or results[ref].std is None:
        return ZeroOutcome(mode, G, subtracted=taken, lines=lines, effects=tuple(per_zero))
    tol = tolerance_a(G, results[ref].std)
    parts = [f"{j.name} {1e3 * t:.2g} mA" for j, t in zip(description.joints, tol, strict=True)
             if j.drive is not None and np.isfinite(t)]  # fmt: skip
    if parts:
        lines += (
            f"current sensors' zero: {ref}'s std hold while each sensor's zero is known to "
            f"well within {', '.join(parts)} (a zero off by that much moves a parameter by "
            "one std; capture --zero-rest reads it, docs/IDENTIFY.md)",
        )
    return ZeroOutcome(mode, G, tol, ref, taken, lines, tuple(per_zero))
