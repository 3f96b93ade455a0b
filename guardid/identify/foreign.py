"""Foreign logs: other CSV layouts and MATLAB .mat files, read through a column mapping.

A *mapping* says which column (CSV) or variable (.mat) holds which signal, in SI units:

    time    sample times [s] (strictly increasing; may jitter)     -- or a sample period [s]
    q<j>    position of joint j (1-based) [rad, or m for a prismatic joint]
    tau<j>  measured joint effort [N m, or N for a prismatic joint]  \\  one kind for all
    i<j>    motor current [A] (turned into torque with the drive     /  joints
            gain N * eta * kt of the robot YAML; taken as the mean over the sample period
            ending at the time stamp, as in guardid's own logs)
    v<j>    motor voltage [V] (optional)
    qd<j>   measured joint velocity [rad/s, or m/s] (optional, every joint or none): used
            instead of the differentiated positions (filtered alike)

Each value is a column name, optionally times a factor that converts it to SI:
``pos1*0.001`` (mm -> m), ``angle*deg`` (deg -> rad, ``deg`` = pi/180), ``pos2*-1`` (sign).
On the command line: ``--columns time=time,q1=pos_meas1,tau1=tau_meas1`` (comma-separated
``KEY=COLUMN[*FACTOR]``), or ``--columns mapping.yaml``; later ``--columns`` entries override
earlier ones. The YAML file::

    columns: {time: time, q1: pos_meas1, q2: pos_meas2, tau1: tau_meas1, tau2: tau_meas2}
    sample_period: 0.002      # s, only without a time column
    mat_var: data             # .mat only: a 2-D array (N, k) holding the columns
    mat_columns: [time, pos1, pos2, tau1, tau2]   # names of mat_var's k columns

A .mat file either holds one vector variable per column (the mapping names variables), or
one 2-D array ``mat_var`` whose columns are named by ``mat_columns``, else by a string
variable ``<mat_var>_columns`` or ``columns`` in the file, else by their 1-based index
(``q1=2``). A CSV file whose mapping names columns only by 1-based numbers (``q1=2``) may
have no header row: when its first data line is all numbers, it is read as data. Every
problem is a one-line :class:`LogFormatError` (data) or
:class:`ConfigError` (mapping) naming the file and the column or variable.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import yaml

from guardid.errors import ConfigError, LogFormatError

KEY_RE = re.compile(r"^(time|q\d+|qd\d+|tau\d+|i\d+|v\d+)$")
KEYS_HELP = "time, q<j>, qd<j>, tau<j>, i<j>, v<j> (j = 1, 2, ...)"
NAMED_FACTORS = {"deg": math.pi / 180.0}  #: factor names allowed after '*'
MIN_ROWS = 10


@dataclass(frozen=True)
class ColumnRef:
    """One mapped signal: the column (or variable) ``name`` times ``scale`` gives SI units."""

    name: str
    scale: float = 1.0


@dataclass
class ColumnMapping:
    """Which column holds which signal (module docstring); ``origin`` names it in errors."""

    columns: dict[str, ColumnRef] = field(default_factory=dict)
    sample_period: float | None = None  # s
    mat_var: str | None = None
    mat_columns: tuple[str, ...] | None = None
    origin: str = "--columns"

    def joints(self, kind: str) -> list[int]:
        """Sorted 1-based joint numbers mapped for ``kind`` ('q', 'tau', 'i', 'v')."""
        pat = re.compile(rf"^{kind}(\d+)$")
        return sorted(int(m.group(1)) for k in self.columns if (m := pat.match(k)))


def parse_mapping(specs=(), sample_period=None, mat_var=None, mat_columns=None) -> ColumnMapping:
    """Build a mapping from ``--columns`` values (inline specs or YAML files) and options.

    ``specs``: sequence of ``"KEY=COLUMN[*FACTOR],..."`` strings or mapping YAML paths,
    applied in order; ``sample_period`` [s], ``mat_var`` and ``mat_columns`` (comma string or
    sequence) override the YAML's.
    """
    out = ColumnMapping()
    origins = []
    for spec in specs:
        spec = str(spec).strip()
        if spec.lower().endswith((".yaml", ".yml")) and not re.search(r"=", spec):
            _merge_yaml(out, Path(spec))
            origins.append(spec)
        else:
            for key, value in _split_inline(spec, "--columns"):
                out.columns[key] = _column_ref(key, value, "--columns")
            origins.append("--columns")
    out.origin = " + ".join(dict.fromkeys(origins)) or "--columns"
    if sample_period is not None:
        out.sample_period = _period(sample_period, "--sample-period")
    if mat_var is not None:
        out.mat_var = str(mat_var)
    if mat_columns is not None:
        out.mat_columns = _name_list(mat_columns, "--mat-columns")
    return out


def _split_inline(spec: str, where: str):
    for item in (s.strip() for s in spec.split(",")):
        if not item:
            continue
        if "=" not in item:
            raise ConfigError(f"{where}: {item!r}: expected KEY=COLUMN (keys: {KEYS_HELP})")
        key, value = (s.strip() for s in item.split("=", 1))
        yield key, value


def _column_ref(key: str, value, where: str) -> ColumnRef:
    """``value`` 'COLUMN' or 'COLUMN*FACTOR' for mapping key ``key``; ``where`` for errors."""
    if not KEY_RE.match(key):
        raise ConfigError(f"{where}: unknown key {key!r} (keys: {KEYS_HELP})")
    where = f"{where}: {key}"
    if isinstance(value, bool) or not isinstance(value, (str, int)):
        raise ConfigError(f"{where}: expected a column name, got {value!r}")
    text = str(value).strip()
    name, scale = text, 1.0
    if "*" in text:
        head, tail = (s.strip() for s in text.rsplit("*", 1))
        factor = NAMED_FACTORS.get(tail)
        if factor is None:
            try:
                factor = float(tail)
            except ValueError:
                raise ConfigError(
                    f"{where}: factor {tail!r} is not a number (or one of: "
                    f"{', '.join(NAMED_FACTORS)})"
                ) from None
        if not math.isfinite(factor) or factor == 0.0:
            raise ConfigError(f"{where}: factor {tail!r} must be finite and non-zero")
        name, scale = head, factor
    if not name:
        raise ConfigError(f"{where}: empty column name")
    return ColumnRef(name, scale)


def _period(value, where: str) -> float:
    try:
        p = float(value)
    except (TypeError, ValueError):
        raise ConfigError(f"{where}: {value!r} is not a number [s]") from None
    if not (math.isfinite(p) and p > 0):
        raise ConfigError(f"{where}: sample period must be positive [s], got {value!r}")
    return p


def _name_list(value, where: str) -> tuple[str, ...]:
    items = value.split(",") if isinstance(value, str) else value
    if not isinstance(items, (list, tuple)) or not items:
        raise ConfigError(f"{where}: expected a comma-separated list or a list of names")
    names = tuple(str(s).strip() for s in items)
    if any(not n for n in names):
        raise ConfigError(f"{where}: empty column name in the list")
    return names


def _merge_yaml(out: ColumnMapping, path: Path) -> None:
    try:
        data = yaml.safe_load(path.read_text(encoding="utf-8"))
    except OSError as exc:
        raise ConfigError(f"{path}: cannot read the column mapping: {exc.strerror}") from None
    except yaml.YAMLError as exc:
        raise ConfigError(f"{path}: invalid YAML: {str(exc).splitlines()[0]}") from None
    if not isinstance(data, dict):
        raise ConfigError(f"{path}: expected a mapping with 'columns'")
    unknown = sorted(set(data) - {"columns", "sample_period", "mat_var", "mat_columns"})
    if unknown:
        raise ConfigError(
            f"{path}: unknown key {unknown[0]!r} (known: columns, sample_period, mat_var, "
            "mat_columns)"
        )
    cols = data.get("columns", {})
    if isinstance(cols, str):
        items = list(_split_inline(cols, f"{path}: columns"))
    elif isinstance(cols, dict):
        items = [(str(k), v) for k, v in cols.items()]
    else:
        raise ConfigError(f"{path}: columns: expected a mapping KEY: COLUMN")
    for key, value in items:
        out.columns[key] = _column_ref(key, value, f"{path}: columns")
    if data.get("sample_period") is not None:
        out.sample_period = _period(data["sample_period"], f"{path}: sample_period")
    if data.get("mat_var") is not None:
        out.mat_var = str(data["mat_var"])
    if data.get("mat_columns") is not None:
        out.mat_columns = _name_list(data["mat_columns"], f"{path}: mat_columns")


def check_mapping(mapping: ColumnMapping, n_joints: int, robot: str, log) -> str:
    """Check the mapping against the robot's joint count; return the effort kind 'tau'|'i'.

    Raises a one-line :class:`ConfigError` naming the log and the mapping.
    """
    where = f"{log}: {mapping.origin}"
    want = list(range(1, n_joints + 1))
    names = ", ".join(f"q{j}" for j in want)
    q = mapping.joints("q")
    if q != want:
        extra = [j for j in q if j not in want]
        missing = [j for j in want if j not in q]
        what = f"maps q{extra[0]}" if extra else f"does not map q{missing[0]}"
        raise ConfigError(f"{where}: {what}, but robot {robot} has {n_joints} joint(s) ({names})")
    tau, cur = mapping.joints("tau"), mapping.joints("i")
    if tau and cur:
        raise ConfigError(f"{where}: maps both tau<j> and i<j>: map one effort kind only")
    kind, eff = ("tau", tau) if tau else ("i", cur)
    if eff != want:
        need = ", ".join(f"{kind}{j}" for j in want)
        if not eff:
            raise ConfigError(
                f"{where}: no effort columns: map tau<j> [N m] or i<j> [A] for every joint "
                f"(robot {robot}: {need})"
            )
        raise ConfigError(f"{where}: maps {', '.join(f'{kind}{j}' for j in eff)}, but robot "
                          f"{robot} has {n_joints} joint(s) ({need})")  # fmt: skip
    v = mapping.joints("v")
    if v and v != want:
        raise ConfigError(f"{where}: maps v{v[0]}..: map v<j> for every joint or for none")
    qd = mapping.joints("qd")
    if qd and qd != want:
        raise ConfigError(f"{where}: maps qd{qd[0]}..: map qd<j> for every joint or for none")
    has_time = "time" in mapping.columns
    if has_time and mapping.sample_period is not None:
        raise ConfigError(f"{where}: give either a time column or a sample period, not both")
    if not has_time and mapping.sample_period is None:
        raise ConfigError(f"{where}: no time: map time=<column> or give --sample-period [s]")
    return kind


@dataclass
class ForeignData:
    """Signals of a foreign log in SI units (``torque``: effort is torque, else current)."""

    t: np.ndarray
    q: np.ndarray
    effort: np.ndarray
    voltage: np.ndarray | None
    torque: bool
    qd: np.ndarray | None = None


def read_foreign(path, mapping: ColumnMapping, n_joints: int, robot: str) -> ForeignData:
    """Read a foreign CSV or .mat log (by suffix) through ``mapping`` for ``n_joints`` joints."""
    path = Path(path)
    kind = check_mapping(mapping, n_joints, robot, path)
    if not path.is_file():
        raise LogFormatError(f"{path}: cannot read: no such file")
    wanted = sorted({ref.name for ref in mapping.columns.values()})
    if path.suffix.lower() == ".mat":
        cols, rows = _read_mat(path, mapping, wanted)
    else:
        if mapping.mat_var is not None or mapping.mat_columns is not None:
            raise ConfigError(f"{path}: --mat-var/--mat-columns apply to .mat files only")
        cols, rows = _read_csv(path, wanted)
    n = len(rows)
    if n < MIN_ROWS:
        raise LogFormatError(f"{path}: only {n} data rows (need at least {MIN_ROWS})")

    def sig(key):
        ref = mapping.columns[key]
        return cols[ref.name] * ref.scale

    if "time" in mapping.columns:
        t = sig("time")
        steps = np.diff(t)
        bad = np.flatnonzero(~(steps > 0))
        if bad.size:
            k = int(bad[0]) + 1
            raise LogFormatError(
                f"{path}: column {mapping.columns['time'].name!r}: time does not increase at "
                f"{rows[k]} ({t[k]:.9g} s after {t[k - 1]:.9g} s)"
            )
    else:
        t = np.arange(n) * mapping.sample_period
    joints = range(1, n_joints + 1)
    q = np.column_stack([sig(f"q{j}") for j in joints])
    effort = np.column_stack([sig(f"{kind}{j}") for j in joints])
    voltage = (
        np.column_stack([sig(f"v{j}") for j in joints]) if mapping.joints("v") else None
    )  # fmt: skip
    qd = np.column_stack([sig(f"qd{j}") for j in joints]) if mapping.joints("qd") else None
    return ForeignData(t - t[0], q, effort, voltage, kind == "tau", qd)


def _read_csv(path: Path, wanted: list[str]):
    """Columns ``wanted`` of a delimited text file (header row first; '#' lines skipped).

    Returns ({name: (N,) float array}, [row labels 'line L' for error messages]).
    """
    try:
        text = path.read_text(encoding="utf-8-sig")
    except (OSError, UnicodeDecodeError) as exc:
        why = getattr(exc, "strerror", None) or "not a text file"
        raise LogFormatError(f"{path}: cannot read: {why}") from None
    lines = [
        (no, line)
        for no, line in enumerate(text.splitlines(), start=1)
        if line.strip() and not line.lstrip().startswith("#")
    ]
    if not lines:
        raise LogFormatError(f"{path}: no header row")
    head_no, head = lines[0]
    counts = {d: head.count(d) for d in (",", ";", "\t")}
    delim = max(counts, key=counts.get) if max(counts.values()) else None

    def split(line):
        return [s.strip().strip('"').strip("'").strip() for s in line.split(delim)]

    names = split(head)
    index = {}
    for c, name in enumerate(names):
        index.setdefault(name, c)
    numbered = all(n.isdigit() and int(n) >= 1 for n in wanted)
    if numbered and (_all_numbers(names) or not any(n in index for n in wanted)):
        if _all_numbers(names):  # headerless: the first line is data
            lines = [(None, "")] + lines
        index = {n: int(n) - 1 for n in wanted}
        width = len(names)
        for n in wanted:
            if int(n) > width:
                raise LogFormatError(f"{path}: column {n} not found (the file has {width} columns)")
    for name in wanted:
        if name not in index:
            shown = ", ".join(names[:12]) + (", ..." if len(names) > 12 else "")
            raise LogFormatError(f"{path}: column {name!r} not found (header: {shown})")
    rows = [f"line {no}" for no, _ in lines[1:]]
    if delim == ",":  # plain decimals: the log reader's compiled parser (same numbers)
        from guardid.log.numeric import parse_plain

        body = "".join(line + "\n" for _, line in lines[1:]).encode("utf-8", "replace")
        table = parse_plain(body, len(names)) if lines[1:] else None
        if table is not None:
            return {name: table[:, index[name]].copy() for name in wanted}, rows
    data = {name: np.empty(len(rows)) for name in wanted}
    for k, (no, line) in enumerate(lines[1:]):
        parts = split(line)
        for name in wanted:
            c = index[name]
            cell = parts[c] if c < len(parts) else ""
            try:
                value = float(cell)
            except ValueError:
                value = math.nan
            if not math.isfinite(value):
                raise LogFormatError(f"{path}: line {no}: column {name!r}: not a number ({cell!r})")
            data[name][k] = value
    return data, rows


def _all_numbers(cells) -> bool:
    """True if every cell parses as a float (a data line, not a header)."""
    try:
        [float(c) for c in cells]
    except ValueError:
        return False
    return bool(cells)


def _read_mat(path: Path, mapping: ColumnMapping, wanted: list[str]):
    """Columns ``wanted`` of a MATLAB file: vector variables, or columns of ``mat_var``."""
    from scipy.io import loadmat

    try:
        mat = loadmat(str(path))
    except Exception as exc:  # scipy raises several types for damaged or non-MAT files
        first = str(exc).splitlines()[0] if str(exc) else exc.__class__.__name__
        raise LogFormatError(f"{path}: not a readable MATLAB .mat file ({first})") from None
    variables = sorted(k for k in mat if not k.startswith("__"))
    shown = ", ".join(variables[:12]) + (", ..." if len(variables) > 12 else "")
    if mapping.mat_var is None:
        if mapping.mat_columns is not None:
            raise ConfigError(f"{path}: --mat-columns needs --mat-var (the 2-D array)")
        data = {}
        for name in wanted:
            if name not in mat:
                raise LogFormatError(f"{path}: variable {name!r} not found (variables: {shown})")
            arr = _numeric(path, f"variable {name!r}", mat[name])
            if arr.ndim > 2 or (arr.ndim == 2 and min(arr.shape) != 1):
                raise LogFormatError(
                    f"{path}: variable {name!r}: expected a vector, got shape {arr.shape} "
                    "(for a 2-D array use --mat-var)"
                )
            data[name] = arr.reshape(-1)
        lengths = {name: len(v) for name, v in data.items()}
        if len(set(lengths.values())) > 1:
            desc = ", ".join(f"{k} {v}" for k, v in lengths.items())
            raise LogFormatError(f"{path}: variables differ in length ({desc})")
    else:
        var = mapping.mat_var
        if var not in mat:
            raise LogFormatError(f"{path}: variable {var!r} not found (variables: {shown})")
        arr = _numeric(path, f"variable {var!r}", mat[var])
        if arr.ndim != 2:
            raise LogFormatError(f"{path}: variable {var!r}: expected a 2-D array ({arr.ndim}-D)")
        names = mapping.mat_columns or _mat_names(path, mat, var)
        if names is not None and arr.shape[1] != len(names) and arr.shape[0] == len(names):
            arr = arr.T  # signals stored as rows
        if names is None:
            names = tuple(str(c + 1) for c in range(arr.shape[1]))
        if arr.shape[1] != len(names):
            raise LogFormatError(
                f"{path}: variable {var!r}: {arr.shape[1]} columns but {len(names)} column "
                f"names ({', '.join(names[:8])}{', ...' if len(names) > 8 else ''})"
            )
        data = {}
        for name in wanted:
            if name not in names:
                raise LogFormatError(
                    f"{path}: variable {var!r}: column {name!r} not found "
                    f"(columns: {', '.join(names[:12])}{', ...' if len(names) > 12 else ''})"
                )
            data[name] = arr[:, names.index(name)]
    for name, v in data.items():
        bad = np.flatnonzero(~np.isfinite(v))
        if bad.size:
            where = f"variable {mapping.mat_var!r}: column" if mapping.mat_var else "variable"
            raise LogFormatError(
                f"{path}: {where} {name!r}: row {int(bad[0]) + 1}: not a number ({v[bad[0]]})"
            )
    n = len(next(iter(data.values()))) if data else 0
    return data, [f"row {k + 1}" for k in range(n)]


def _numeric(path: Path, what: str, value) -> np.ndarray:
    arr = np.asarray(value)
    if arr.dtype.kind not in "biuf":
        raise LogFormatError(f"{path}: {what}: not numeric (MATLAB class {arr.dtype.kind!r})")
    return np.atleast_1d(arr.astype(float))


def _mat_names(path: Path, mat: dict, var: str) -> tuple[str, ...] | None:
    """Column names stored in the file (``<var>_columns`` or ``columns``), if any."""
    for key in (f"{var}_columns", "columns"):
        if key not in mat:
            continue
        raw = np.asarray(mat[key])
        if raw.dtype.kind in "US":
            names = [str(s).strip() for s in raw.reshape(-1)]
        elif raw.dtype.kind == "O":
            names = [str(np.asarray(s).reshape(-1)[0]).strip() for s in raw.reshape(-1)]
        else:
            raise LogFormatError(f"{path}: variable {key!r}: expected strings (column names)")
        return tuple(names)
    return None
