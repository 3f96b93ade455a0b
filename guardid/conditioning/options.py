"""One object for every conditioning choice: :class:`ConditioningOptions`.

``None`` in a field means "choose from the data" (see :mod:`guardid.identify.cutoff` for the
cut-off and :func:`guardid.identify.rows.stacked_rows` for the rest). A params
file records the options that were *used* (every automatic choice resolved to its value),
so that ``guardid validate`` can score any parameter set under exactly that conditioning.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, fields, replace

from guardid.conditioning.filters import DEFAULT_ORDER
from guardid.conditioning.momentum import EQUATIONS
from guardid.errors import ConfigError


@dataclass(frozen=True)
class ConditioningOptions:
    """How a log is turned into identification rows.

    cutoff_hz : zero-phase Butterworth cut-off on positions and efforts [Hz]; None = chosen
        from the data (cross-validated among candidates).
    decimate : keep every k-th conditioned sample (with a parallel filter: every k-th
        sample after it); None = in the momentum form every tick
        (:func:`guardid.conditioning.momentum.row_spacing`: every m-th beyond
        :data:`~guardid.conditioning.momentum.MAX_ROWS` ticks; a log with too few usable
        ticks for closer rows' std gets 0's spacing), in the acceleration form new Nyquist
        >= about the cut-off (the parallel filter's); 0 = about 1 / (2 cut-off) in either
        form (rows whose errors are about independent). A params file records the spacing
        used.
    stiction_threshold : rows with some |qd_j| below it are dropped [rad/s or m/s]; None =
        5 % of the peak speed for sign friction, 0 (keep every row) for smooth friction models.
    stiction_guard_s : also drop rows within this time of such a sample [s]; None = the span
        holding 95 % of the low-pass's impulse response for guardid logs (stick/slip; 1.04
        cut-off periods at order 4,
        :data:`guardid.identify.acceleration_run.STICTION_GUARD_SHARE`), 0 for
        measured-torque logs.
    flat_is_stuck : flag samples without an encoder count in the period (momentum form: in
        either period next to the sample); None = guardid logs.
    parallel_filter_hz : Gautier's parallel filter on the regressor and the torque [Hz];
        None = off.
    order : Butterworth order; None = by equation form: 4 for "acceleration" (applied forward
        and backward), 2 for "momentum" (causal, one filter on both sides).
    edge_s : rows within this time of either end are dropped [s]; None = 1 / cut-off.
    friction_filter : low-pass the regressor's Coulomb (and Stribeck) columns with the same
        filter as the effort (parallel filtering of the friction jump); None = chosen with
        the cut-off by cross-validation (when the cut-off is given: off).
    equation : the model equation the rows hold: "momentum" (the filtered momentum form,
        :mod:`guardid.conditioning.momentum`: per period impulse = momentum change + integral
        of the rest, nothing differentiated twice, one causal filter on both sides; the
        cut-off is that filter's) or "acceleration" (tau = Y(q, qd, qdd) theta on low-passed,
        twice-differentiated positions); None = momentum for motor-current logs on a uniform
        tick grid (guardid logs), acceleration otherwise (measured torque, uneven time
        stamps, a parallel or friction filter asked for, a model other than a serial chain).
        A params file written before this field existed is read as "acceleration".
    quantisation : in the momentum form, remove the encoder rounding's noise in the columns
        from LS's and WLS's normal equations (bias-compensated least squares,
        :func:`guardid.conditioning.momentum.quantisation_noise`): without it they carry a
        bias of the noise's size however long the log; None = when every joint has an
        encoder in the robot description and the log's positions lie on its grid (whole
        counts), True = the same (what a params file records when it was done: the options
        reused on another log compensate where that log allows), False = off.
    """

    cutoff_hz: float | None = None
    decimate: int | None = None
    stiction_threshold: float | None = None
    stiction_guard_s: float | None = None
    flat_is_stuck: bool | None = None
    parallel_filter_hz: float | None = None
    order: int | None = None
    edge_s: float | None = None
    friction_filter: bool | None = None
    equation: str | None = None
    quantisation: bool | None = None

    def __post_init__(self):
        if self.equation is not None and self.equation not in EQUATIONS:
            raise ConfigError(f"equation: expected one of {', '.join(EQUATIONS)}, got "
                              f"{self.equation!r}")  # fmt: skip

    def with_(self, **changes) -> ConditioningOptions:
        """A copy with ``changes`` applied (None values in ``changes`` are ignored)."""
        return replace(self, **{k: v for k, v in changes.items() if v is not None})

    def to_dict(self) -> dict:
        """Plain mapping for YAML (floats, ints, bools or None)."""
        out = asdict(self)
        for k, v in out.items():
            if isinstance(v, float):
                out[k] = float(v)
        return out

    @classmethod
    def from_dict(cls, data, where: str = "conditioning") -> ConditioningOptions:
        """Options from a mapping (e.g. a params file's ``conditioning``); unknown keys and
        wrong types are one-line :class:`ConfigError` naming ``where``.key."""
        if data is None:
            return cls()
        if not isinstance(data, dict):
            raise ConfigError(f"{where}: expected a mapping")
        known = {f.name: f for f in fields(cls)}
        out = {"equation": "acceleration", "order": DEFAULT_ORDER}  # files from before them
        for key, value in data.items():
            if key not in known:
                raise ConfigError(f"{where}.{key}: unknown (known: {', '.join(known)})")
            if value is None:
                out[key] = None
                continue
            if key == "equation":
                if value not in EQUATIONS:
                    raise ConfigError(f"{where}.{key}: expected one of {', '.join(EQUATIONS)}, "
                                      f"got {value!r}")  # fmt: skip
                out[key] = value
                continue
            if key in ("flat_is_stuck", "friction_filter", "quantisation"):
                if not isinstance(value, bool):
                    raise ConfigError(f"{where}.{key}: expected true or false, got {value!r}")
                out[key] = value
                continue
            if isinstance(value, bool) or not isinstance(value, (int, float)):
                raise ConfigError(f"{where}.{key}: expected a number, got {value!r}")
            out[key] = int(value) if key in ("decimate", "order") else float(value)
        return cls(**out)
