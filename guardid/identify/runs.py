"""Read a run for identification: a guardid log or, through a column mapping, a foreign
CSV/.mat log (:mod:`guardid.identify.foreign`), turned into arrays in SI units."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from guardid.errors import LogFormatError
from guardid.excitation.sines import common_period
from guardid.identify.current_zero import footer_zero
from guardid.log import read_log


@dataclass
class Run:
    """One run: ticks (N,) or None, t [s] (N,), q [rad], current, voltage [V] (N, n) or None.

    ``current`` is the effort: motor current [A] (period means, as in guardid logs), or joint
    torque [N m] when ``torque`` is True (foreign logs with tau<j> columns: instantaneous
    samples, used as they are). ``highest_harmonic_hz``: the excitation's highest frequency
    [Hz] named by a guardid log's header (None when unknown: foreign logs);
    ``excitation_period_s``: the period [s] after which its excitation repeats (None when
    unknown or not periodic); ``current_zero``, ``current_zero_before``: the footer's current
    sensors' zeros per joint name read at rest after and before the trajectory
    (:func:`guardid.identify.current_zero.footer_zero`; None: not read).
    """

    path: str
    robot: str | None
    ticks: np.ndarray | None
    t: np.ndarray
    q: np.ndarray
    current: np.ndarray
    voltage: np.ndarray | None
    torque: bool = False
    highest_harmonic_hz: float | None = None
    qd: np.ndarray | None = None  # measured joint velocities [rad/s | m/s] (foreign qd<j>)
    robot_name: str | None = None  # the robot named in a guardid log's header
    joint_names: tuple[str, ...] | None = None  # a guardid log's joints (column names)
    setpoint: np.ndarray | None = None  # a guardid log's sp_* columns [rad] (N, n)
    counts: np.ndarray | None = None  # a guardid log's counts_* columns (N, n) [counts]
    sample_period_s: float | None = None  # a guardid log's tick period [s]
    source: str | None = None  # the file a segment comes from (None: path is the file)
    excitation_period_s: float | None = None
    current_zero: dict | None = None  # a guardid log footer's current sensors' zero read at rest
    current_zero_before: dict | None = None  # and the one read before the trajectory


def trajectory_highest_harmonic(trajectory: dict | None) -> float | None:
    """Highest frequency [Hz] of a trajectory mapping (a log header's ``trajectory``).

    Fourier series: base_freq x harmonics; sums of sines / multisines: the largest
    ``frequencies`` entry. None when unknown (then the cut-off comes from the spectrum).
    """
    if not isinstance(trajectory, dict):
        return None
    try:
        if trajectory.get("kind") == "fourier":
            return float(trajectory["base_freq"]) * int(trajectory["harmonics"])
        freqs = trajectory.get("frequencies")
        if freqs is not None:
            return float(np.max(np.abs(np.asarray(freqs, dtype=float))))
    except (KeyError, TypeError, ValueError):
        return None
    return None


def trajectory_period(trajectory: dict | None) -> float | None:
    """The period [s] after which a trajectory mapping (a log header's ``trajectory``)
    repeats: 1 / base_freq for a Fourier series, the frequencies' common period for sums of
    sines and multisines; None when unknown or not periodic."""
    if not isinstance(trajectory, dict):
        return None
    try:
        if trajectory.get("kind") == "fourier":
            period = 1.0 / float(trajectory["base_freq"])
        else:
            freqs = trajectory.get("frequencies")
            if freqs is None:
                return None
            period = common_period(np.concatenate([np.ravel(f) for f in freqs]).astype(float))
    except (KeyError, TypeError, ValueError, ZeroDivisionError):
        return None
    return period if np.isfinite(period) and period > 0 else None


def run_from_arrays(
    t_s,
    q,
    effort,
    *,
    torque=False,
    voltage_v=None,
    ticks=None,
    setpoint=None,
    qd=None,
    highest_harmonic_hz=None,
    path="<arrays>",
    excitation_period_s=None,
) -> Run:
    """A :class:`Run` from arrays (notebooks, simulations): t_s (N,) [s], q (N, n) [rad | m],
    effort (N, n) motor current [A] (period means) or, with ``torque``, joint torque
    [N m | N]; optional voltage_v (N, n) [V], ticks (N,), setpoint (N, n) [rad], qd (N, n)
    measured velocities [rad/s | m/s], the excitation's highest harmonic [Hz] and the
    period [s] it repeats with (as a guardid log's header gives them: LS and WLS then count
    an error that repeats every period, :func:`guardid.identify.rows.period_groups`)."""
    return Run(
        path=str(path), robot=None, ticks=ticks, t=t_s, q=q, current=effort, voltage=voltage_v,
        torque=bool(torque), highest_harmonic_hz=highest_harmonic_hz, qd=qd, setpoint=setpoint,
        excitation_period_s=excitation_period_s,
    )  # fmt: skip


def load_run(path, sample_period_s: float | None = None, mapping=None, description=None) -> Run:
    """Load a run. Without ``mapping``: a guardid capture log, time from the tick column and
    the sample period [s]. With a :class:`~guardid.identify.foreign.ColumnMapping`: a foreign
    CSV or .mat log for ``description`` (the robot; its joint count is checked)."""
    if mapping is not None:
        if description is None:
            raise LogFormatError(f"{path}: a foreign log needs the robot (--robot)")
        return _load_foreign(path, mapping, description)
    if str(path).lower().endswith(".mat"):
        raise LogFormatError(f"{path}: a .mat file needs a column mapping (--columns)")
    try:
        data = read_log(path)  # the only read of the file: header, rows and footer
    except UnicodeDecodeError as exc:  # e.g. a gzip file named .csv
        raise LogFormatError(
            f"{path}: byte {exc.start}: not UTF-8 text (not a guardid log)"
        ) from None
    for col in ("tick",):
        if col not in data.columns:
            raise LogFormatError(
                f"{path}: column {col!r} missing (not a guardid log? map a foreign log's "
                "columns with --columns)"
            )
    _check_samples(path, data, data.columns["tick"])
    ticks = data.columns["tick"].astype(np.int64, copy=False)  # int64 already: no copy
    if len(ticks) < 10:
        raise LogFormatError(f"{path}: only {len(ticks)} rows")
    period = _sample_period(path, data.header, sample_period_s)
    for key in ("q", "i"):
        if not data.has_group(key):
            raise LogFormatError(f"{path}: no {key}_* columns (expected one per joint)")
    data.check_joint_columns()
    joints = data.joint_names
    if not joints:
        raise LogFormatError(
            f"{path}: no counts_* columns (expected counts_*, q_* and i_* columns for every joint)"
        )
    q = data.joint_array("q", joints)  # by name, in the order of the counts_* columns
    current = data.joint_array("i", joints)
    setpoint = data.joint_array("sp", joints) if data.has_group("sp") else None
    voltage = data.joint_array("v", joints) if data.has_group("v") else None  # optional
    counts = data.joint_array("counts", joints)
    return Run(
        path=str(path),
        robot=data.header.get("robot_source") or data.header.get("robot"),
        ticks=ticks,
        t=(ticks - ticks[0]) * period,
        sample_period_s=period,
        q=q,
        current=current,
        voltage=voltage,
        highest_harmonic_hz=trajectory_highest_harmonic(data.header.get("trajectory")),
        excitation_period_s=trajectory_period(data.header.get("trajectory")),
        robot_name=data.header.get("robot"),
        joint_names=tuple(joints),
        setpoint=setpoint,
        counts=counts,
        current_zero=footer_zero(path, data.footer),
        current_zero_before=footer_zero(path, data.footer, "current_zero_before"),
    )


def _check_samples(path, data, tick) -> None:
    """Refuse non-finite values in the columns identification uses, ticks that are not
    integers or do not increase (two logs appended, a restarted counter), naming the first
    bad data row (1 = the first row after the header)."""
    used = [c for c in data.columns if c == "tick" or c.split("_")[0] in ("q", "i", "v")]
    for name in used:
        bad = np.flatnonzero(~np.isfinite(data.columns[name]))
        if bad.size:
            raise LogFormatError(
                f"{path}: data row {bad[0] + 1}: column {name} is {data.columns[name][bad[0]]}"
            )
    bad = np.flatnonzero((tick != np.round(tick)) | (np.abs(tick) > 2**53))
    if bad.size:
        raise LogFormatError(f"{path}: data row {bad[0] + 1}: tick {tick[bad[0]]!r} is not a count")
    back = np.flatnonzero(np.diff(tick) <= 0)
    if back.size:
        k = int(back[0]) + 1
        raise LogFormatError(
            f"{path}: data row {k + 1}: tick {int(tick[k])} after {int(tick[k - 1])} (ticks "
            "must increase: two logs appended or a restarted counter?)"
        )


def _sample_period(path, header, given) -> float:
    """The sample period [s]: ``given``, else the header's sample_period_s, else 0.015."""
    value = given or header.get("sample_period_s", 0.015)
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not 0 < value < 1e3:
        raise LogFormatError(
            f"{path}: header: sample_period_s: expected seconds > 0, got {value!r}"
        )
    firmware = header.get("firmware")
    tick = firmware.get("tick_period") if isinstance(firmware, dict) else None
    if not given and isinstance(tick, (int, float)) and not isinstance(tick, bool):
        if abs(float(tick) - float(value)) > 0.5e-6 + 1e-9:  # INFO: whole microseconds
            raise LogFormatError(
                f"{path}: header: sample_period_s {value:g} s, but the firmware's tick_period "
                f"{tick:g} s (the header edited? each row is one tick)"
            )
    return float(value)


def _load_foreign(path, mapping, description) -> Run:
    from guardid.identify.foreign import read_foreign

    joints = getattr(description, "joints", None)
    n = len(joints) if joints is not None else len(description.joint_names)
    data = read_foreign(path, mapping, n, description.name)
    # ticks of the robot's sample period when the time stamps sit on that grid (1 % of a
    # period): then the motors' R and Ke can be estimated as for a guardid log
    period = float(description.sample_period)
    ticks = np.rint(data.t / period).astype(np.int64)
    on_grid = bool(np.all(np.abs(data.t - ticks * period) <= 0.01 * period))
    on_grid = on_grid and bool(np.all(np.diff(ticks) > 0))
    return Run(
        path=str(path),
        robot=getattr(description, "source", "") or description.name,
        ticks=ticks if on_grid else None,
        t=data.t,
        q=data.q,
        current=data.effort,
        voltage=data.voltage,
        torque=data.torque,
        qd=data.qd,
        sample_period_s=period if on_grid else None,
    )
