"""The ``guardid`` command line.

Each sub-command lives beside the stage it drives; this module only gathers them (imported
when they run, see :data:`guardid.commands.COMMANDS`) and turns
:class:`guardid.errors.GuardidError` into a one-line message and a non-zero exit code.

Signals, from the first instant of a command: SIGINT, SIGTERM and SIGHUP (a closed
terminal, a dropped ssh session) end any command with one line, ``guardid: interrupted
(SIGINT)``, and the shell's exit code 128 + the signal's number (130, 143, 129), never
click's ``Aborted!`` or a traceback. Files being written are temporary until complete
(:mod:`guardid.commands.outputs`), so an interrupted command leaves none behind. A capture
installs its own handlers once it starts (:mod:`guardid.capture.stop`): the robot is put
idle first and the log gets its footer.
"""

from __future__ import annotations

import contextlib
import importlib
import signal
import sys
import threading

import click

from guardid import __version__
from guardid.commands import COMMANDS
from guardid.errors import report_errors

STOP_SIGNALS = (signal.SIGINT, signal.SIGTERM, signal.SIGHUP)
"""Signals that end a command with one line and exit code 128 + signal number."""


BLAS_THREADS_VARS = ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS")
"""Set to 1 for a command unless given (:func:`_one_blas_thread`)."""


def _one_blas_thread() -> None:
    """One BLAS thread per process unless the environment says otherwise, set before numpy
    loads (the commands import it lazily): guardid's matrices are small (tens of columns),
    and ``identify`` replays the tracker in a forked process beside the fit, so a second
    BLAS thread in each only makes the two fight over the cores (issue 30: 0.85x the CPU of
    ``identify`` with one thread on a 2-core machine)."""
    import os

    for name in BLAS_THREADS_VARS:
        os.environ.setdefault(name, "1")


class Interrupted(BaseException):  # noqa: N818  (a request to stop, like KeyboardInterrupt)
    """Raised by the CLI's signal handlers; ``signum`` says which signal."""

    def __init__(self, signum: int) -> None:
        super().__init__(signal.Signals(signum).name)
        self.signum = signum


def _raise_interrupted(signum, _frame) -> None:
    raise Interrupted(signum)


@contextlib.contextmanager
def _signals_end_the_command():
    """Inside the block, SIGINT, SIGTERM and SIGHUP raise :class:`Interrupted` (main thread
    only; a signal its parent left ignored stays ignored, except SIGINT, which a process
    started in the background inherits ignored but a user still means)."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    old = {}
    for s in STOP_SIGNALS:
        previous = signal.getsignal(s)
        if previous is signal.SIG_IGN and s != signal.SIGINT:
            continue  # nohup: SIGHUP stays ignored
        old[s] = signal.signal(s, _raise_interrupted)
    try:
        yield
    finally:
        for s, handler in old.items():
            signal.signal(s, handler)


class _LazyGroup(click.Group):
    """A group whose commands are imported on first use; the listing uses their short help."""

    def list_commands(self, ctx):
        return [name for name, *_ in COMMANDS]

    def get_command(self, ctx, cmd_name):
        for name, module, attr, _ in COMMANDS:
            if name == cmd_name:
                return getattr(importlib.import_module(module), attr)
        return None

    def format_commands(self, ctx, formatter):
        limit = formatter.width - 6 - max(len(name) for name, *_ in COMMANDS)
        rows = [
            (name, click.utils.make_default_short_help(short, limit))
            for name, _, _, short in COMMANDS
        ]
        with formatter.section("Commands"):
            formatter.write_dl(rows)

    def main(self, *args, **kwargs):
        from guardid.commands._status import end_line, forget_line

        _one_blas_thread()
        forget_line()  # a line left open by an earlier run in this process is not ours
        with _signals_end_the_command():
            try:
                return super().main(*args, **kwargs)
            except Interrupted as exc:
                end_line()
                sys.stderr.write(f"guardid: interrupted ({exc})\n")
                sys.exit(128 + exc.signum)

    def invoke(self, ctx: click.Context):
        try:
            return report_errors(self._invoke_on_a_new_line, ctx)
        except click.UsageError as exc:  # a sub-command's bad option: one line too
            where = exc.ctx.command_path if exc.ctx is not None else "guardid"
            message = " ".join(exc.format_message().split())
            sys.stderr.write(f"guardid: error: {message} (see '{where} --help')\n")
            sys.exit(exc.exit_code)

    def _invoke_on_a_new_line(self, ctx: click.Context):
        """The sub-command; whatever ends it early starts on a new line, not on the
        progress line."""
        from guardid.commands._status import end_line

        try:
            return super().invoke(ctx)
        except BaseException:
            end_line()
            raise


@click.group(cls=_LazyGroup)
@click.version_option(__version__, prog_name="guardid")
def main() -> None:
    """Bridge and identification toolkit for the guard pan/tilt robot."""
