"""The Python API for notebooks: the command line's jobs as functions (docs/API.md).

Thin wrappers over the same code the commands run, so that a notebook gets what
``guardid identify`` / ``validate`` / ``simulate`` print, as objects::

    import guardid

    r = guardid.identify_logs(["run.csv"], methods=("ls", "wls"))
    print(r.table)                    # the table `guardid identify` prints
    r.values("wls"), r.std("wls")     # {name: value [SI]}, {name: one std}
    r.to_pandas()                     # a DataFrame (pip install 'guardid[pandas]')

Each name is also reachable as ``guardid.<name>`` (imported on first use, so that
``import guardid`` stays cheap). Bad input raises :class:`guardid.errors.GuardidError`
subclasses with the same one-line message the command line prints.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from guardid.errors import ConfigError, UntrustedResult
from guardid.log import read_log
from guardid.robot import load_robot

__all__ = [
    "IdentifyResult",
    "ValidationResult",
    "identify_logs",
    "load_robot",
    "read_log",
    "simulate",
    "validate",
]

DEFAULT_METHODS = ("ls", "wls", "rls", "hopfield")  # as ``guardid identify``


def _paths(paths) -> list[str]:
    """One path or several: a list of str (a lone str or Path is one log)."""
    if isinstance(paths, str | Path):
        return [str(paths)]
    out = [str(p) for p in paths]
    if not out:
        raise ConfigError("no log given")
    return out


def _foreign(columns, sample_period_s) -> dict:
    """The commands' foreign-log options from ``columns`` (``"q1=a,tau1=b"``, a mapping
    {key: column}, a list of such strings, or a mapping YAML path) and ``sample_period_s``."""
    if columns is None:
        cols: tuple = ()
    elif isinstance(columns, Mapping):
        cols = (",".join(f"{k}={v}" for k, v in columns.items()),)
    elif isinstance(columns, str | Path):
        cols = (str(columns),)
    else:
        cols = tuple(str(c) for c in columns)
    return {"columns": cols, "sample_period": sample_period_s, "mat_var": None,
            "mat_columns": None}  # fmt: skip


def _methods(methods) -> tuple[str, ...]:
    if isinstance(methods, str):
        methods = methods.split(",")
    return tuple(m.strip() for m in methods if m.strip())


@dataclass(frozen=True)
class IdentifyResult:
    """What ``guardid identify`` finds, as data.

    ``identification``: the pipeline's :class:`guardid.identify.Identification` (every
    field: rows, warnings, motors, each method's :class:`MethodResult`); ``description``:
    the robot; ``logs``: the paths identified.
    """

    identification: object
    description: object
    logs: tuple[str, ...]
    methods: tuple[str, ...]

    @property
    def names(self) -> tuple[str, ...]:
        """The base parameters' names, in the table's order."""
        return tuple(self.identification.names)

    @property
    def nominal(self) -> dict[str, float]:
        """The robot description's value of each base parameter [SI]."""
        return dict(zip(self.names, map(float, self.identification.nominal), strict=True))

    @property
    def reference_method(self) -> str | None:
        """The method the verdict rests on (WLS when it ran, else LS, else one with std)."""
        from guardid.identify.untrusted import reference_method

        return reference_method(self.identification.results)

    def _method(self, method: str | None) -> str:
        m = method or self.reference_method or self.methods[0]
        if m not in self.identification.results:
            raise ConfigError(f"method {m!r} did not run (ran: {', '.join(self.methods)})")
        return m

    def values(self, method: str | None = None) -> dict[str, float]:
        """{name: estimate [SI]} of ``method`` (default :attr:`reference_method`)."""
        theta = self.identification.results[self._method(method)].theta
        return dict(zip(self.names, map(float, theta), strict=True))

    def std(self, method: str | None = None) -> dict[str, float] | None:
        """{name: one standard deviation [SI]} of ``method``, or None (it has none)."""
        std = self.identification.results[self._method(method)].std
        return None if std is None else dict(zip(self.names, map(float, std), strict=True))

    @property
    def table(self) -> str:
        """The table ``guardid identify`` prints (estimates +- std, conditioning, fit)."""
        from guardid.identify.report import table

        return table(self.identification, self.methods, self.description)

    @property
    def conditioning(self) -> dict:
        """How the rows were made: equation form, cut-off [Hz] and why, parallel filter
        [Hz], rows used (and why others were dropped), cond(A) of the used rows."""
        ident = self.identification
        c = ident.conditioning
        return {
            "equation": c.equation,
            "cutoff_hz": float(ident.cutoff_hz),
            "cutoff_reason": ident.cutoff_reason,
            "parallel_filter_hz": c.parallel_filter_hz,
            "rows": int(ident.rows),
            "rows_summary": ident.rows_summary,
            "cond": float(ident.cond),
        }

    @property
    def untrusted(self) -> list[str]:
        """Why the result cannot be trusted ([] when it can): returned with ``force=True``."""
        return list(self.identification.untrusted)

    @property
    def warnings(self) -> list[str]:
        """The warnings, led by each reason the result cannot be trusted (``force=True``)."""
        why = [f"cannot be trusted (force=True): {w}" for w in self.identification.untrusted]
        return why + list(self.identification.warnings)

    def __str__(self) -> str:
        return self.table

    def to_pandas(self):
        """A pandas DataFrame, one row per base parameter: ``nominal`` (the robot
        description's value), then per method its estimate and ``<method>_std``."""
        try:
            import pandas as pd
        except ImportError:
            raise ImportError("to_pandas needs pandas: pip install 'guardid[pandas]'") from None
        cols = {"nominal": list(self.nominal.values())}
        for m in self.methods:
            cols[m] = list(self.values(m).values())
            std = self.std(m)
            cols[f"{m}_std"] = list(std.values()) if std is not None else [np.nan] * len(cols[m])
        return pd.DataFrame(cols, index=pd.Index(self.names, name="parameter"))


def identify_logs(
    paths,
    robot=None,
    methods: Iterable[str] | str = DEFAULT_METHODS,
    *,
    columns=None,
    sample_period_s: float | None = None,
    cutoff_hz: float | None = None,
    parallel_filter_hz: float | None = None,
    equation: str | None = None,
    options=None,
    force: bool = False,
) -> IdentifyResult:
    """Identify the base parameters from one or more logs, as ``guardid identify`` does.

    ``paths``: a log or a list of logs (several: one fit, rows stacked). ``robot``: a shipped
    name, YAML or URDF path, a description from :func:`load_robot`, or None (the log's
    header names it). ``columns``: a foreign log's column mapping (``"time=t,q1=a,tau1=b"``
    or {key: column}; docs/FOREIGN_LOGS.md), ``sample_period_s`` [s] for one without time.
    ``cutoff_hz``, ``parallel_filter_hz`` [Hz] and ``equation`` (``"momentum"`` or
    ``"acceleration"``) as the options of the same names; None = chosen from the data.
    ``options``: an :class:`guardid.identify.IdentifyOptions` for everything else (its
    methods and conditioning are replaced by the arguments above when those are given).
    Raises :class:`guardid.errors.UntrustedResult` when the fit cannot be trusted (the
    command's exit 4) unless ``force``.
    """
    from dataclasses import replace

    from guardid.commands.identify import _load_all
    from guardid.conditioning.options import ConditioningOptions
    from guardid.identify import IdentifyOptions, identify
    from guardid.identify.checks import call_naming_logs, check_cutoff
    from guardid.identify.methods import methods_for

    logs = _paths(paths)
    methods = _methods(methods)
    methods_for(methods)  # an unknown name refused before any log is read
    runs, description = _load_all(logs, robot, _foreign(columns, sample_period_s))
    check_cutoff(cutoff_hz, runs)
    options = options or IdentifyOptions()
    conditioning = (options.conditioning or ConditioningOptions()).with_(
        cutoff_hz=cutoff_hz, parallel_filter_hz=parallel_filter_hz, equation=equation
    )
    options = replace(options, methods=methods, conditioning=conditioning)
    result = call_naming_logs(logs, identify, runs, description, options)
    if result.untrusted and not force:
        raise UntrustedResult(
            f"{logs[0]}: identification cannot be trusted: {'; '.join(result.untrusted)} "
            "(force=True returns it anyway)"
        )
    return IdentifyResult(result, description, tuple(logs), methods)


@dataclass(frozen=True)
class ValidationResult:
    """What ``guardid validate`` finds: ``text`` (what it prints) and ``scores``, one
    :class:`guardid.identify.validation.Score` per (parameter set, run): ``label``, ``run``,
    ``stacked`` (relative rms error over every joint [-]), per joint ``rms`` [N m | A] and
    ``relative`` [-]."""

    text: str
    scores: list = field(default_factory=list)

    def stacked(self) -> dict[tuple[str, str], float]:
        """{(set label, run): stacked relative rms error [-]}."""
        return {(s.label, s.run): float(s.stacked) for s in self.scores}

    def __str__(self) -> str:
        return self.text


def validate(
    paths,
    params,
    robot=None,
    *,
    columns=None,
    sample_period_s: float | None = None,
    cutoff_hz: float | None = None,
    parallel_filter_hz: float | None = None,
) -> ValidationResult:
    """Score parameter sets on runs, as ``guardid validate``: ``params`` is a params.yaml
    from identify or a reference values file, or a list of them (each method of each file
    is a set); every set is scored on the same rows, the first file's conditioning unless
    ``cutoff_hz`` / ``parallel_filter_hz`` [Hz] are given. ``robot``, ``columns`` and
    ``sample_period_s`` as in :func:`identify_logs` (default robot: the first params
    file's)."""
    from guardid.commands.identify import scored

    keep: dict = {}
    text = scored(_paths(paths), _paths(params), robot, cutoff_hz, parallel_filter_hz,
                  _foreign(columns, sample_period_s), keep)  # fmt: skip
    return ValidationResult(text, list(keep["scores"]))


def simulate(
    robot="guard", duration_s: float = 30.0, seed: int = 0, noise: bool = True
) -> dict[str, np.ndarray]:
    """A closed-loop run of the simulated robot, as ``guardid simulate`` (its sum-of-sines
    reference under a plain PID): {name: array} with ``t_s`` (N,) [s] and, each (N, n),
    ``q_true`` [rad], ``qd_true`` [rad/s], ``current_true`` [A] (period means), ``counts``,
    ``q_sensed`` [rad], ``voltage`` [V], ``current`` [A] (sensed), ``setpoint`` [rad]."""
    from guardid.commands.simulate import run

    if not (duration_s > 0 and np.isfinite(duration_s)):
        raise ConfigError(f"duration_s must be > 0 s, got {duration_s}")
    keys = ("q_true", "qd_true", "current_true", "counts", "q_sensed", "voltage", "current")
    cols: dict[str, list] = {k: [] for k in ("t_s", *keys, "setpoint")}
    for _, s, sp in run(str(robot), duration_s, seed, (), noise=noise):
        cols["t_s"].append(s.time)
        for k, x in zip(keys, (s.q, s.qd, s.current_true, s.counts, s.q_sensed, s.voltage,
                               s.current), strict=True):  # fmt: skip
            cols[k].append(list(x))
        cols["setpoint"].append(list(sp))
    return {k: np.asarray(v, dtype=np.int64 if k == "counts" else float) for k, v in cols.items()}
