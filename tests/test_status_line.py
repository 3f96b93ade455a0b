"""The live status line: rewritten in place on a terminal, silent when piped."""

from __future__ import annotations

import io

from guardid.commands import _status
from guardid.commands._status import Status


def test_terminal_line_is_rewritten_then_cleared(monkeypatch):
    monkeypatch.setattr(_status, "MIN_INTERVAL_S", 0.0)
    out = io.StringIO()
    s = Status(out, live=True)
    s.stage("reading")
    s.show("reading 50 %")
    s.stage("fitting")
    s.done("identified")
    text = out.getvalue()
    assert text.startswith("\rreading ...")
    assert "\rreading 50 %" in text
    # the closing line is alone on its line: the status line was blanked first
    body, last = text.rstrip("\n").rsplit("\r", 1)
    assert last.startswith("identified in ") and "reading " in last and "fitting " in last
    assert body.endswith(" " * len("fitting ..."))
    assert text.count("\n") == 1


def test_piped_output_is_only_the_closing_line():
    out = io.StringIO()
    s = Status(out, live=False)
    s.stage("reading")
    s.show("reading 50 %", force=True)
    s.done("identified")
    lines = out.getvalue().splitlines()
    assert len(lines) == 1 and lines[0].startswith("identified in ")
    assert "\r" not in out.getvalue()


def test_throttled_between_rewrites(monkeypatch):
    clock = iter([0.0, 0.0, 0.05, 0.2, 0.2])
    monkeypatch.setattr(_status.time, "perf_counter", lambda: next(clock))
    out = io.StringIO()
    s = Status(out, live=True)  # t0 = 0.0
    s.show("a")  # at 0.0: the last show was at 0.0 (never): not yet 0.1 s later
    s.show("b")  # at 0.05: throttled
    s.show("c")  # at 0.2: shown
    assert out.getvalue() == "\rc"
