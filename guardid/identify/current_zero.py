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
COUNTED = "every std counting its error"
NOT_COUNTED = (
    "its error NOT counted in the std (no friction-offset column to carry it: a joint "
    "without friction in the momentum form; the std hold only if the read zero is exact)"
)
TELEMETRY_CURRENT_A = 1e-3  #: the telemetry's current unit [A]: a reading's resolution at least


@dataclass(frozen=True)
class SensorZero:
    """One joint's zero as a capture read it: ``mean_a`` [A], ``std_error_a`` [A] (the
    mean's std, :func:`sensor_zeros`), ``rows`` read."""

    mean_a: float
    std_error_a: float
    rows: int

    @property
    def significance(self) -> float:
        """|mean| in std errors [-]."""
        return abs(self.mean_a) / self.std_error_a if self.std_error_a > 0 else math.inf


def footer_zero(path, footer: dict | None) -> dict | None:
    """The footer's ``current_zero`` checked: ``{joint: {mean_a, std_a, rows[,
    readings_ma]}}``, ``{not_measured: why}``, or None when there is none. One line naming
    the log and the field when it is malformed (a joint the robot lacks is said by
    :func:`subtract_zeros`)."""
    zero = (footer or {}).get("current_zero")
    if zero is None:
        return None
    if isinstance(zero, dict) and "not_measured" in zero:
        return {"not_measured": str(zero["not_measured"])}
    where = f"{path}: footer: current_zero"
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


def sensor_zeros(run, description) -> list[SensorZero | None]:
    """Per joint of ``description`` the zero ``run``'s footer gives (None: none). Its std
    error: the readings' std (at least the description's sensor noise: a few readings' std
    can be far too small) over sqrt(rows); plus the ADC step's rounding (step^2 / 12) when
    the readings are too quiet to dither it (their std below half a step), and the
    telemetry unit's (unit^2 / 12) when they were not put back on the ADC's levels
    (:func:`zero_on_levels`)."""
    zero = getattr(run, "current_zero", None) or {}
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
        out.append(SensorZero(float(entry["mean_a"]), math.sqrt(var), rows))
    return out


@dataclass(frozen=True)
class Subtracted:
    """A zero taken off one log's joint: which ``source`` log, ``joint`` index, the zero."""

    source: str
    joint: int
    zero: SensorZero


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
    ``subtract``; ``ignore``: the runs as they are), and what was read and done."""
    if mode not in MODES:
        raise ValueError(f"current zero: mode {mode!r} is not one of {', '.join(MODES)}")
    out, taken, lines, warnings, seen = [], [], [], [], set()
    for run in runs:
        zeros = [None] * len(description.joints) if run.torque else sensor_zeros(run, description)
        source = run.source or run.path
        if source not in seen:  # a log's segments share its footer
            seen.add(source)
            warnings += _footer_warnings(source, getattr(run, "current_zero", None) or {},
                                         description)  # fmt: skip
            if any(zeros):
                lines.append(_zero_line(source, description, zeros, mode))
                warnings += zero_warnings(source, description, zeros, mode)
                if mode == "subtract":
                    taken += [Subtracted(source, j, z) for j, z in enumerate(zeros) if z]
        if mode == "subtract" and any(zeros):
            shift = np.array([0.0 if z is None else z.mean_a for z in zeros])
            run = replace(run, current=np.asarray(run.current, dtype=float) - shift)
        out.append(run)
    return out, ZerosRead(tuple(taken), tuple(lines), tuple(warnings))


def _footer_warnings(source, footer: dict, description) -> list[str]:
    """A zero the capture could not read, and footer joints the robot does not have."""
    out = []
    unknown = sorted(set(footer) - {"not_measured"} - {j.name for j in description.joints})
    if unknown:
        out.append(f"{source}: footer: current_zero: {', '.join(unknown)}: no such joint in "
                   "the robot; not used")  # fmt: skip
    if "not_measured" in footer:
        out.append(f"{source}: the current sensors' zero was not read "
                   f"({footer['not_measured']}): the std hold only while it is known to well "
                   "within the tolerance the report gives")  # fmt: skip
    return out


def zero_warnings(source, description, zeros, mode: str = "subtract") -> list[str]:
    """One line per joint whose zero (:func:`sensor_zeros`) lies beyond ZERO_SIGNIFICANCE
    std errors from 0 (what was done with it as ``mode`` says)."""
    done = ("here it was taken off, the std widened for its error" if mode == "subtract"
            else "here it was left in: the estimates carry it")  # fmt: skip
    return [
        f"{source}: the {joint.name} current sensor reads {1e3 * z.mean_a:+.2f} +- "
        f"{1e3 * z.std_error_a:.2f} mA at rest ({z.significance:.0f} std errors from 0): its "
        f"zero is off; zero the sensor ({done})"
        for joint, z in zip(description.joints, zeros, strict=True)
        if z is not None and z.significance > ZERO_SIGNIFICANCE
    ]


def _zero_line(source, description, zeros, mode) -> str:
    pairs = zip(description.joints, zeros, strict=True)
    parts = [f"{j.name} {1e3 * z.mean_a:+.2f} +- {1e3 * z.std_error_a:.2f} mA"
             for j, z in pairs if z is not None]  # fmt: skip
    done = f"subtracted, {COUNTED}" if mode == "subtract" else "left in (--current-zero ignore)"
    return f"{source}: current sensors' zero read at rest: {', '.join(parts)}: {done}"


def zero_sensitivity(fit_rows, description) -> dict[str, np.ndarray] | None:
    """Per log (its source path) the (b', n) change of the estimates per ampere of each
    driven joint's zero (0 for the others): WLS fitted on the rows, and how its estimate
    moves with the effort shifted by the joint's friction-offset column times N eta Kt over
    the log's rows (:meth:`~guardid.estimators.LeastSquares.effect_of`). WLS stands for
    every method (each is LS-like or judged against it). In the acceleration form a
    constant effort stays that constant through the low-pass (the log's ends aside); in
    current units the effort's own unit. None when it cannot be made: measured torque, or
    the momentum form without offset columns (a joint without friction)."""
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
    A = fit_rows.A
    wls = WeightedLeastSquares(**rows.error_model()).fit(A, fit_rows.y)
    driven = [j for j, joint in enumerate(description.joints) if joint.drive is not None]
    out: dict[str, np.ndarray] = {}
    start = 0
    for m, run in zip(rows.run_rows, fit_rows.runs, strict=True):
        G = out.setdefault(run.source or run.path, np.zeros((A.shape[2], len(gain))))
        if m:
            D = O[start : start + m][:, :, driven] * gain[driven]  # per ampere
            G[:, driven] += wls.effect_of(A[start : start + m], D)
        start += m
    return out


def tolerance_a(G: np.ndarray, std: np.ndarray) -> np.ndarray:
    """Per joint the zero error [A] that moves some parameter by one of its ``std``, given
    the estimates' change per ampere ``G`` (b', n) (inf: none moves; parameters without a
    finite positive std do not count)."""
    std = np.asarray(std, dtype=float)
    ok = np.isfinite(std) & (std > 0)
    worst = (np.abs(G[ok]) / std[ok, None]).max(axis=0, initial=0.0)
    with np.errstate(divide="ignore"):
        return np.where(worst > 0, 1.0 / worst, np.inf)


def zero_covariance(sensitivity: dict[str, np.ndarray], taken) -> np.ndarray:
    """(b', b') the estimates' covariance from the subtracted zeros' own errors (each log's
    zero error its own, independent of the others')."""
    b = next(iter(sensitivity.values())).shape[0]
    C = np.zeros((b, b))
    for s in taken:
        g = sensitivity[s.source][:, s.joint] if s.source in sensitivity else np.zeros(b)
        C += np.outer(g, g) * s.zero.std_error_a**2
    return C


@dataclass(frozen=True)
class ZeroOutcome:
    """What the zero stage found: ``mode``; ``sensitivity`` (b', n) the estimates' change
    per ampere of each joint's zero, every log's together (None: not made here);
    ``tolerance_a`` (n,) :func:`tolerance_a` of the verdict method's std (None: not made);
    ``method`` that method; ``subtracted``: the zeros taken off; ``lines``: what the
    report says of it (the zeros read and kept; how well a zero must be known)."""

    mode: str
    sensitivity: np.ndarray | None = None
    tolerance_a: np.ndarray | None = None
    method: str | None = None
    subtracted: tuple[Subtracted, ...] = ()
    lines: tuple[str, ...] = ()

    def to_dict(self, description) -> dict:
        """params.yaml's ``current_zero``."""
        out: dict = {"mode": self.mode, "method": self.method}
        names = [j.name for j in description.joints]
        if self.tolerance_a is not None:
            pairs = zip(names, self.tolerance_a, strict=True)
            out["tolerance_a"] = {n: float(t) for n, t in pairs if np.isfinite(t)}
        out["subtracted"] = [
            {"log": s.source, "joint": names[s.joint], "mean_a": s.zero.mean_a,
             "std_error_a": s.zero.std_error_a, "rows": s.zero.rows}
            for s in self.subtracted
        ]  # fmt: skip
        return out


def zero_stage(fit_rows, results, taken, description, mode, lines=()) -> ZeroOutcome:
    """The stage after the fits: every result's std (and covariance) widened by the
    subtracted zeros' own errors (``taken``, :func:`subtract_zeros`); the outcome, its
    ``lines`` those given and one on how well the zeros must be known for the verdict
    method's std to hold."""
    from guardid.identify.untrusted import reference_method

    sensitivity = zero_sensitivity(fit_rows, description)
    taken, lines = tuple(taken), tuple(lines)
    if sensitivity is None:
        lines = tuple(line.replace(COUNTED, NOT_COUNTED) for line in lines)
        return ZeroOutcome(mode, subtracted=taken, lines=lines)
    if taken:
        C = zero_covariance(sensitivity, taken)
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
        return ZeroOutcome(mode, G, subtracted=taken, lines=lines)
    tol = tolerance_a(G, results[ref].std)
    parts = [f"{j.name} {1e3 * t:.2g} mA" for j, t in zip(description.joints, tol, strict=True)
             if j.drive is not None and np.isfinite(t)]  # fmt: skip
    if parts:
        lines += (
            f"current sensors' zero: {ref}'s std hold while each sensor's zero is known to "
            f"well within {', '.join(parts)} (a zero off by that much moves a parameter by "
            "one std; capture --zero-rest reads it, docs/IDENTIFY.md)",
        )
    return ZeroOutcome(mode, G, tol, ref, taken, lines)
