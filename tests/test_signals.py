"""Every command ends on SIGINT, SIGTERM or SIGHUP with one line and exit 128 + signal
number (130, 143, 129), never click's ``Aborted!`` or a traceback, and leaves nothing behind.

The moment is controlled, never timed: the command's input is a FIFO, so the command blocks
reading it; the test's open of the FIFO's other end returns once the command has opened it
(it is then loading its input, before any output exists), and the signal is sent then.
In-process cases send the signal from inside the work (a patched step) with ``os.kill``.
"""

from __future__ import annotations

import errno
import os
import signal
import subprocess
import sys
import time

import pytest
from badinput_tools import invoke, short_capture
from capturetools import gentle_trajectory

GUARD_S = 120.0  # failure guards only, never the assertion
SIGNALS = (signal.SIGINT, signal.SIGTERM, signal.SIGHUP)


def _open_writer(fifo, proc) -> int:
    """The FIFO's write end, opened once ``proc`` has opened it for reading."""
    deadline = time.monotonic() + GUARD_S  # failure guard only
    while time.monotonic() < deadline:
        try:
            return os.open(fifo, os.O_WRONLY | os.O_NONBLOCK)
        except OSError as exc:
            if exc.errno != errno.ENXIO:  # ENXIO: no reader yet
                raise
        if proc.poll() is not None:
            raise AssertionError(f"ended before reading its input: {proc.communicate()}")
        time.sleep(0.01)
    raise AssertionError("the command never opened its input")


def _signal_while_reading(tmp_path, argv, fifo, signum, feed: bytes = b""):
    """Run ``guardid ARGV``; send ``signum`` while it reads ``fifo``, then write ``feed``
    and close the FIFO. Returns (exit code, stdout, stderr)."""
    os.mkfifo(fifo)
    proc = subprocess.Popen(
        [sys.executable, "-m", "guardid", *map(str, argv)],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, cwd=tmp_path,
    )  # fmt: skip
    fd = _open_writer(fifo, proc)
    try:
        proc.send_signal(signum)
        if feed:
            os.set_blocking(fd, True)
            try:
                os.write(fd, feed)
            except BrokenPipeError:
                pass  # the reader is gone already: it stopped at once
    finally:
        os.close(fd)
    out, err = proc.communicate(timeout=GUARD_S)
    return proc.returncode, out, err


def _files(d) -> set[str]:
    return {p.name for p in d.iterdir()}


@pytest.mark.parametrize("signum", SIGNALS, ids=lambda s: signal.Signals(s).name)
def test_capture_stopped_before_the_log_exists(tmp_path, signum):
    """Signalled while it loads its trajectory: one line, 128 + n, no log."""
    text = gentle_trajectory(tmp_path / "t.yaml").read_bytes()
    fifo, log = tmp_path / "traj.yaml", tmp_path / "run.csv"
    before = _files(tmp_path)
    code, out, err = _signal_while_reading(
        tmp_path, ["capture", "--trajectory", fifo, "-o", log], fifo, signum, text
    )
    name = signal.Signals(signum).name
    assert code == 128 + signum, err
    assert err.splitlines() == [
        f"guardid: interrupted ({name}) before the capture started: nothing written"
    ], err
    assert out == ""
    assert _files(tmp_path) == before | {"traj.yaml"}  # no log, no temporary file


@pytest.mark.parametrize("signum", SIGNALS, ids=lambda s: signal.Signals(s).name)
def test_identify_stopped_while_reading(tmp_path, signum):
    """identify (was: exit 1 on SIGINT) while it reads its log: one line, 128 + n, and
    its -o neither created nor left as a temporary file."""
    fifo = tmp_path / "run.csv"
    before = _files(tmp_path)
    code, out, err = _signal_while_reading(
        tmp_path, ["identify", fifo, "-o", tmp_path / "p.yaml"], fifo, signum
    )
    assert code == 128 + signum, err
    assert err.splitlines() == [f"guardid: interrupted ({signal.Signals(signum).name})"], err
    assert "Aborted" not in out + err and "Traceback" not in err
    assert _files(tmp_path) == before | {"run.csv"}


def test_validate_stopped_while_reading(tmp_path):
    fifo = tmp_path / "p.yaml"
    log = tmp_path / "run.csv"
    log.write_text("tick\n")
    code, _, err = _signal_while_reading(
        tmp_path, ["validate", log, "--params", fifo], fifo, signal.SIGINT
    )
    assert code == 130, err
    assert err.splitlines() == ["guardid: interrupted (SIGINT)"], err


def _kill_self_at(monkeypatch, target, attr, signum, at_call: int = 1):
    """Patch ``target.attr`` to send ``signum`` to this process on its ``at_call``-th call."""
    original = getattr(target, attr)
    calls = []

    def patched(*args, **kwargs):
        calls.append(1)
        if len(calls) == at_call:
            os.kill(os.getpid(), signum)
        return original(*args, **kwargs)

    monkeypatch.setattr(target, attr, patched)
    return calls


@pytest.fixture(scope="module")
def a_run(tmp_path_factory):
    return short_capture(tmp_path_factory.mktemp("signals"), seconds=10)


def test_identify_signalled_while_writing_leaves_the_old_file(tmp_path, a_run, monkeypatch):
    """SIGINT half-way through writing params.yaml (--force, an old file there): exit 130,
    one line, the old file as it was, no temporary file."""
    from guardid.commands import outputs

    out = tmp_path / "params.yaml"
    out.write_text("the old parameters\n")
    real_open = open

    class HalfWay:
        def __init__(self, *args, **kwargs):
            self.f = real_open(*args, **kwargs)

        def __enter__(self):
            return self

        def __exit__(self, *exc):
            self.f.close()

        def write(self, text):
            self.f.write(text[: len(text) // 2])
            self.f.flush()
            os.kill(os.getpid(), signal.SIGINT)
            self.f.write(text[len(text) // 2 :])

        def flush(self):
            self.f.flush()

    monkeypatch.setattr(outputs, "open", HalfWay, raising=False)
    res = invoke("identify", a_run, "--method", "ls", "--force", "-o", out)
    assert res.exit_code == 130, res.stderr
    assert res.stderr.splitlines()[-1] == "guardid: interrupted (SIGINT)"
    assert "Aborted" not in res.output
    assert out.read_text() == "the old parameters\n"
    assert _files(tmp_path) == {"params.yaml"}


@pytest.mark.parametrize("signum", SIGNALS, ids=lambda s: signal.Signals(s).name)
def test_simulate_signalled_mid_run(tmp_path, monkeypatch, signum):
    from guardid.plant import Plant

    _kill_self_at(monkeypatch, Plant, "step", signum, at_call=50)
    res = invoke("simulate", "--duration", "5", "-o", tmp_path / "s.csv")
    assert res.exit_code == 128 + signum, res.stderr
    assert res.stderr.splitlines() == [f"guardid: interrupted ({signal.Signals(signum).name})"]
    assert _files(tmp_path) == set()


def test_excite_signalled_while_optimising(tmp_path, monkeypatch):
    """Ctrl-C in the optimiser (was: a traceback or Aborted!): one line, 130, no file."""
    import scipy.optimize  # guardid.excitation.optimise imports minimize when it runs

    _kill_self_at(monkeypatch, scipy.optimize, "minimize", signal.SIGINT)
    res = invoke("excite", "--starts", "1", "-o", tmp_path / "t.yaml")
    assert res.exit_code == 130, res.stderr
    assert res.stderr.splitlines() == ["guardid: interrupted (SIGINT)"]
    assert _files(tmp_path) == set()


@pytest.mark.parametrize("signum", SIGNALS, ids=lambda s: signal.Signals(s).name)
def test_capture_signalled_while_its_module_loads(tmp_path, monkeypatch, signum):
    """The first instant of a command, before the capture's own handlers: the CLI's handler
    ends it with one line and 128 + n (was: Aborted!, exit 1; SIGTERM: no word)."""
    import importlib

    import guardid.cli

    real = importlib.import_module

    def import_module(name, *args):
        if name == "guardid.commands.capture":
            os.kill(os.getpid(), signum)
        return real(name, *args)

    monkeypatch.setattr(guardid.cli.importlib, "import_module", import_module)
    traj = gentle_trajectory(tmp_path / "t.yaml")
    res = invoke("capture", "--trajectory", traj, "-o", tmp_path / "r.csv")
    assert res.exit_code == 128 + signum, res.stderr
    assert res.stderr.splitlines() == [f"guardid: interrupted ({signal.Signals(signum).name})"]
    assert _files(tmp_path) == {"t.yaml"}


def test_a_signal_after_the_command_is_the_callers_again(tmp_path):
    """The handlers are the CLI's only while a command runs: afterwards the process's own
    (here pytest's default SIGINT handler) are back."""
    before = {s: signal.getsignal(s) for s in SIGNALS}
    res = invoke("excite", "--no-optimise", "-o", tmp_path / "t.yaml")
    assert res.exit_code == 0, res.stderr
    assert {s: signal.getsignal(s) for s in SIGNALS} == before
