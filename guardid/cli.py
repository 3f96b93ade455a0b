"""The ``guardid`` command line.

Each sub-command lives beside the stage it drives; this module only gathers them (imported
when they run, see :data:`guardid.commands.COMMANDS`) and turns
:class:`guardid.errors.GuardidError` into a one-line message and a non-zero exit code.
"""

from __future__ import annotations

import importlib
import sys

import click

from guardid import __version__
from guardid.commands import COMMANDS
from guardid.errors import report_errors


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

    def invoke(self, ctx: click.Context):
        try:
            return report_errors(super().invoke, ctx)
        except click.UsageError as exc:  # a sub-command's bad option: one line too
            where = exc.ctx.command_path if exc.ctx is not None else "guardid"
            message = " ".join(exc.format_message().split())
            sys.stderr.write(f"guardid: error: {message} (see '{where} --help')\n")
            sys.exit(exc.exit_code)


@click.group(cls=_LazyGroup)
@click.version_option(__version__, prog_name="guardid")
def main() -> None:
    """Bridge and identification toolkit for the guard pan/tilt robot."""
