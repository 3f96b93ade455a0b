"""A status line for long work: rewritten in place on a terminal, silent elsewhere.

On a terminal (stderr is a TTY) :meth:`Status.show` rewrites one line at most every
:data:`MIN_INTERVAL_S`, and :meth:`Status.done` clears it and prints the closing line. Piped
or captured (scripts, CI, tests), nothing but the closing line is printed, so a one-line
error stays one line.
"""

from __future__ import annotations

import sys
import time

import click

MIN_INTERVAL_S = 0.1  #: the line is rewritten at most this often [s]

_open_line: list = []  # the stream whose last line is a status line not ended yet


def line_open(stream) -> None:
    """Note that ``stream``'s last line is a status line rewritten in place (no newline)."""
    _open_line[:] = [stream]


def forget_line() -> None:
    """Forget an open status line (a new command starts; its stream may be another)."""
    _open_line.clear()


def end_line() -> None:
    """End an open status line with a newline, so that what follows (an error, a warning,
    the closing summary) starts on a line of its own."""
    if _open_line:
        stream = _open_line.pop()
        try:
            stream.write("\n")
            stream.flush()
        except (OSError, ValueError):  # closed or broken: nothing to end
            pass


class Status:
    """One live status line on stderr; ``stages`` records (name, seconds) as they finish."""

    def __init__(self, stream=None, live: bool | None = None) -> None:
        self.stream = stream if stream is not None else sys.stderr
        self.live = self.stream.isatty() if live is None else live
        self.t0 = time.perf_counter()
        self._stage_t0 = self.t0
        self._stage: str | None = None
        self._last_show = 0.0
        self._width = 0
        self.stages: list[tuple[str, float]] = []

    def show(self, text: str, force: bool = False) -> None:
        """Put ``text`` on the status line (terminal only; throttled unless ``force``)."""
        if not self.live:
            return
        now = time.perf_counter()
        if not force and now - self._last_show < MIN_INTERVAL_S:
            return
        self._last_show = now
        pad = max(0, self._width - len(text))
        click.echo("\r" + text + " " * pad, file=self.stream, nl=False)
        self._width = len(text)
        line_open(self.stream)

    def stage(self, name: str) -> None:
        """Close the running stage (its time is kept) and start ``name``."""
        self._close_stage()
        self._stage = name
        self.show(f"{name} ...", force=True)

    def _close_stage(self) -> None:
        now = time.perf_counter()
        if self._stage is not None:
            self.stages.append((self._stage, now - self._stage_t0))
        self._stage, self._stage_t0 = None, now

    def elapsed_s(self) -> float:
        return time.perf_counter() - self.t0

    def clear(self) -> None:
        if self.live and self._width:
            click.echo("\r" + " " * self._width + "\r", file=self.stream, nl=False)
            self._width = 0
            _open_line.clear()

    def done(self, what: str) -> None:
        """Clear the line and print ``what`` with the time taken and each stage's share."""
        self._close_stage()
        self.clear()
        parts = ", ".join(f"{n} {s:.1f} s" for n, s in self.stages)
        tail = f" ({parts})" if parts else ""
        click.echo(f"{what} in {self.elapsed_s():.1f} s{tail}", file=self.stream)
