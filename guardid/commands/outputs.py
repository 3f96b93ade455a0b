"""The one rule for every file a command writes (``-o``, ``--urdf``, ``--mjcf``, ``--report``,
``--plot``, capture's ``.online.csv``):

* never one of the command's inputs (a log, a trajectory, a robot or params file);
* an existing file is refused unless ``--force``, in the same words everywhere
  (:data:`EXISTS`);
* checked before any work starts: its directory exists and a file can be created in it
  (:func:`check_output` creates and removes a probe file, which also catches a read-only
  file system, where permission bits say nothing for root);
* written to a temporary file beside it, fsynced, and renamed into place when complete
  (:func:`replacing`): an error (disk full) or a signal half-way leaves the old file, or
  none, never a cut or zero-byte one.

Capture logs keep their own writer (:class:`guardid.log.LogWriter`: rows streamed and kept
whatever ends the run); for them the rule is the first three points.
"""

from __future__ import annotations

import contextlib
import os
import stat
import tempfile
from collections.abc import Iterable, Iterator
from pathlib import Path

import click

from guardid.errors import ConfigError

EXISTS = "{option} {path}: already exists (give --force to replace it)"
"""The refusal of an existing output, for every command and option."""


def force_option(what: str = "existing output files", more: str = ""):
    """The ``--force`` option of a command that writes files, in the same words everywhere;
    ``more`` adds what else --force means for that command."""
    text = f"Replace {what} (never an input file){more}."
    return click.option("--force", is_flag=True, help=text)


def output_option(what: str):
    """A required ``-o/--output`` naming the file ``what`` (an existing one with --force)."""
    return click.option(
        "-o",
        "--output",
        required=True,
        type=click.Path(dir_okay=False),
        help=f"{what} to write (an existing file only with --force).",
    )


def same_file(a, b) -> bool:
    """True when paths ``a`` and ``b`` name the same file (hard or symbolic links
    included; for paths that do not exist yet, the same resolved path)."""
    pa, pb = Path(a), Path(b)
    try:
        return os.path.samefile(pa, pb)
    except OSError:  # one of them does not exist (yet)
        return pa.resolve() == pb.resolve()


def check_output(
    output,
    inputs: Iterable[tuple[str, object]] = (),
    option: str = "-o",
    force: bool = False,
) -> None:
    """ConfigError naming ``option`` and ``output`` when ``output`` is one of ``inputs``
    (pairs of the input's option name and path; None paths are skipped), exists without
    ``force``, is a directory, or cannot be created (missing or unwritable directory, a
    read-only file system). ``output`` None: nothing to check."""
    if output is None:
        return
    if str(output) == "":  # an empty $OUT: would be taken as "no output" and write nothing
        raise ConfigError(f"{option} '': an empty file name; give a file name")
    for name, path in inputs:
        if path is not None and same_file(output, path):
            raise ConfigError(
                f"{option} {output}: is also the input {name} {path}; choose another output file"
            )
    if os.path.isdir(output):
        raise ConfigError(f"{option} {output}: is a directory; give a file name")
    if os.path.lexists(output):
        if not force:
            raise ConfigError(EXISTS.format(option=option, path=output))
        if not _regular(output):  # a device or a pipe (/dev/null): written in place
            return
    _probe(Path(output), option)


def check_distinct(outputs: Iterable[tuple[str, object]]) -> None:
    """ConfigError when two of ``outputs`` (pairs of option name and path; None skipped)
    name the same file: one would overwrite the other."""
    named = [(option, path) for option, path in outputs if path is not None]
    for k, (option, path) in enumerate(named):
        for other, earlier in named[:k]:
            if same_file(path, earlier):
                raise ConfigError(f"{option} {path}: is also {other}; give each its own file")


def check_new_directory_files(directory, option: str, force: bool = False) -> None:
    """For an option naming a directory of outputs (``reproduce --plot DIR``): ConfigError
    when DIR is a file, holds files already (without ``force``), or cannot be written in.
    A missing DIR is created."""
    d = Path(directory)
    if d.exists() and not d.is_dir():
        raise ConfigError(f"{option} {d}: is not a directory")
    if d.is_dir() and any(d.iterdir()) and not force:
        raise ConfigError(
            f"{option} {d}: already exists and is not empty (give --force to replace its files)"
        )
    try:
        d.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise ConfigError(f"{option} {d}: cannot create: {_reason(exc)}") from None
    _probe(d / "probe", option, where=d)


def _regular(path) -> bool:
    try:
        return stat.S_ISREG(os.stat(path).st_mode)
    except OSError:
        return True  # a dangling link: created as a regular file


def _reason(exc: OSError) -> str:
    return exc.strerror or str(exc)


def _probe(output: Path, option: str, where=None) -> None:
    """Create and remove a file in ``output``'s directory: ConfigError when that fails."""
    parent = output.parent if where is None else Path(where)
    label = f"{option} {output if where is None else where}"
    if not parent.exists():
        raise ConfigError(f"{label}: directory {parent} does not exist")
    if not parent.is_dir():
        raise ConfigError(f"{label}: {parent} is not a directory")
    try:
        fd, name = tempfile.mkstemp(dir=parent, prefix=".guardid-probe-")
    except OSError as exc:
        raise ConfigError(f"{label}: cannot write in {parent}: {_reason(exc)}") from None
    os.close(fd)
    os.unlink(name)


def _umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask


@contextlib.contextmanager
def replacing(output, option: str = "-o") -> Iterator[Path]:
    """Yield a temporary path beside ``output`` (same suffix, so that writers choosing the
    format by it still do); when the block completes, fsync it and rename it onto
    ``output``. On any error or signal the temporary file is removed and ``output`` is left
    as it was; an OSError becomes one ConfigError line naming ``option`` and ``output``.
    An existing ``output`` that is not a regular file (``/dev/null``) is written in place.
    Check the output first with :func:`check_output`."""
    target = Path(os.path.realpath(output)) if os.path.islink(output) else Path(output)
    if os.path.lexists(target) and not _regular(target):
        try:
            yield target
        except OSError as exc:
            raise ConfigError(f"{option} {output}: cannot write: {_reason(exc)}") from None
        return
    try:
        mode = stat.S_IMODE(os.stat(target).st_mode)
    except OSError:
        mode = 0o666 & ~_umask()
    try:
        fd, name = tempfile.mkstemp(
            dir=target.parent, prefix=f".{target.stem}.", suffix=f".part{target.suffix}"
        )
        os.close(fd)
    except OSError as exc:
        raise ConfigError(f"{option} {output}: cannot write: {_reason(exc)}") from None
    tmp = Path(name)
    try:
        yield tmp
        _commit(tmp, target, mode)
    except OSError as exc:
        raise ConfigError(f"{option} {output}: cannot write: {_reason(exc)}") from None
    finally:
        with contextlib.suppress(OSError):
            tmp.unlink()


def _commit(tmp: Path, target: Path, mode: int) -> None:
    """fsync ``tmp``, give it ``mode``, rename it onto ``target``, fsync the directory."""
    fd = os.open(tmp, os.O_RDONLY)
    try:
        os.fsync(fd)
    finally:
        os.close(fd)
    os.chmod(tmp, mode)
    os.replace(tmp, target)
    with contextlib.suppress(OSError):  # not every file system syncs a directory
        dfd = os.open(target.parent, os.O_RDONLY)
        try:
            os.fsync(dfd)
        finally:
            os.close(dfd)


def write_text(output, text: str, option: str = "-o") -> None:
    """Write ``text`` (UTF-8) to ``output`` by :func:`replacing`."""
    write_texts([(output, text, option)])


def write_texts(items: Iterable[tuple[object, str, str]]) -> None:
    """Write several files, (output, text, option) each, all or none: each text goes to its
    temporary file and is fsynced before the next; only when all are written are they
    renamed into place (a URDF and its side YAML: never one without the other after a
    full disk, which would make a rerun refuse the one left)."""
    with contextlib.ExitStack() as stack:
        for output, text, option in items:
            tmp = stack.enter_context(replacing(output, option))
            with open(tmp, "w", encoding="utf-8") as fh:
                fh.write(text)
                fh.flush()
                if _regular(tmp):
                    os.fsync(fh.fileno())


def robot_file(robot) -> str | None:
    """``--robot``'s value when it names an existing file (not a shipped robot), else None."""
    return str(robot) if robot and Path(str(robot)).is_file() else None


def check_room(output, duration_s: float, sample_period_s: float, row_bytes: float) -> None:
    """ConfigError when a ``duration_s`` [s] log of one row per ``sample_period_s`` [s], each
    at most ``row_bytes`` [bytes], would not fit in the free space of ``output``'s file system
    (``--duration 1e9``: terabytes). Not for a device or a pipe given with --force (the log
    goes elsewhere)."""
    import shutil

    if os.path.exists(output) and not stat.S_ISREG(os.stat(output).st_mode):
        return
    folder = Path(output).parent
    try:
        free = shutil.disk_usage(folder).free
    except OSError:
        return  # checked by check_output already; nothing more to say
    need = duration_s / sample_period_s * row_bytes
    if need > free:
        raise ConfigError(
            f"--duration {duration_s:g} s: the log {output} would need about "
            f"{_size(need)}, {_size(free)} free in {folder}"
        )


def _size(n_bytes: float) -> str:
    unit = "B"
    for unit in ("B", "kB", "MB", "GB", "TB"):
        if n_bytes < 1000 or unit == "TB":
            break
        n_bytes /= 1000
    return f"{n_bytes:.3g} {unit}"
