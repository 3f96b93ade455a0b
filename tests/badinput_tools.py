"""Shared by the bad-input tests: a short real capture of the simulated guard robot, and
the check that a CLI run ended well or with one ``guardid: error:`` line."""

from __future__ import annotations

from contextlib import contextmanager
from pathlib import Path

from click.testing import CliRunner
from threadpoolctl import threadpool_limits

from guardid.cli import main

ERROR_PREFIX = "guardid: error: "


def _runner() -> CliRunner:
    try:
        return CliRunner(mix_stderr=False)  # click < 8.2
    except TypeError:
        return CliRunner()  # click >= 8.2 keeps stderr apart always


def invoke(*args):
    """Run ``guardid ARGS`` in-process; stdout and stderr apart."""
    return _runner().invoke(main, [str(a) for a in args])


@contextmanager
def one_blas_thread():
    """BLAS on one thread: the many small solves of these tests are several times slower
    (and their wall time erratic) with OpenBLAS threads on a busy machine."""
    with threadpool_limits(limits=1, user_api="blas"):
        yield


def short_capture(directory: Path, seconds: int = 10) -> Path:
    """A ``seconds`` s lock-step capture of sim://guard on the unoptimised default excitation
    (made in-process: about a second of CPU)."""
    traj = directory / "traj.yaml"
    res = invoke("excite", "--no-optimise", "-o", traj)
    assert res.exit_code == 0, res.output
    log = directory / "run.csv"
    res = invoke("capture", "--trajectory", traj, "--duration", seconds, "--quiet", "-o", log)
    assert res.exit_code == 0, res.output
    return log


def assert_ok_or_one_line(result, what: str = "") -> None:
    """Exit 0, or a non-zero exit with stderr exactly one ``guardid: error:`` line (after any
    one-line ``guardid: warning:`` notes, such as the reader's for a cut last row); never an
    exception escaping the command (which a terminal would show as a traceback)."""
    exc = result.exception
    if exc is not None and not isinstance(exc, SystemExit):
        raise AssertionError(f"{what}: {type(exc).__name__} escaped: {exc}") from exc
    if result.exit_code == 0:
        return
    lines = [x for x in result.stderr.splitlines() if not x.startswith("guardid: warning: ")]
    assert len(lines) == 1 and lines[0].startswith(ERROR_PREFIX), (what, result.stderr)
    assert "Traceback" not in result.stderr and "Traceback" not in result.stdout
