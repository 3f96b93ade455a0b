"""The ``guardid`` command line.

Each sub-command lives beside the stage it drives; this module only gathers them
and turns :class:`guardid.errors.GuardidError` into a one-line message and a
non-zero exit code.
"""

from __future__ import annotations

import sys

import click

from guardid import __version__
from guardid.errors import report_errors


class _Group(click.Group):
    def invoke(self, ctx: click.Context):
        try:
            return report_errors(super().invoke, ctx)
        except click.UsageError as exc:  # a sub-command's bad option: one line too
            where = exc.ctx.command_path if exc.ctx is not None else "guardid"
            message = " ".join(exc.format_message().split())
            sys.stderr.write(f"guardid: error: {message} (see '{where} --help')\n")
            sys.exit(exc.exit_code)


@click.group(cls=_Group)
@click.version_option(__version__, prog_name="guardid")
def main() -> None:
    """Bridge and identification toolkit for the guard pan/tilt robot."""


def _register() -> None:
    from guardid.commands import COMMANDS

    for command in COMMANDS:
        main.add_command(command)


_register()
