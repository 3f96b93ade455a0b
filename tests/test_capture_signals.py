"""Ctrl-C (SIGINT), SIGTERM and SIGHUP stop a capture in every phase: the robot is put idle
(seen on the robot's side) and the log, if the handshake had succeeded, gets its footer.

The signal is sent by the simulated robot itself at a seeded moment: when the k-th host
frame arrives (the handshake and set-up: HELLO, SET_WATCHDOG, SET_PID, SET_MODE, PING,
...) or at the k-th tick of motion. In lock-step pacing the robot runs inside the
capture's reads; in real-time pacing mostly on the port's clock thread, so the signal
lands wherever the capture happens to be. Assertions are on what the run recorded
(footer, exit code, commands the robot received), never on elapsed time.
"""

from __future__ import annotations

import os
import random
import signal
import subprocess
import sys
import time

import pytest
from capturetools import IDLE, footer_dict, gentle_trajectory, log_fields, parse_rows, witnessed
from click.testing import CliRunner

from guardid.capture.stop import StopRequest
from guardid.cli import main
from guardid.fakeport import register_device_factory
from guardid.log import LogWriter
from guardid.protocol import FrameParser

LOCKSTEP_SEEDS = range(12)
SIGNALS = (signal.SIGINT, signal.SIGTERM, signal.SIGHUP)
GUARD_S = 120.0  # failure guards only, never the assertion
SETUP = ("SET_WATCHDOG", "SET_PID", "PING")  # commands of the set-up before motion
REALTIME_SEEDS = range(6)


@pytest.fixture
def stray_signals():
    """Signals that reach the test process outside the capture's own handlers (must be
    none); keeps a stray SIGINT/SIGTERM from ending the test session."""
    seen = []
    old = {s: signal.signal(s, lambda n, f: seen.append(n)) for s in SIGNALS}
    yield seen
    for s, h in old.items():
        signal.signal(s, h)


def _moment(seed: int, realtime: bool):
    """(trigger, signal, --online or None): the phase cycles with the seed (handshake,
    set-up, motion, motion with the online estimators), the moment in it is drawn."""
    rng = random.Random(seed * 7919 + realtime)
    signum = SIGNALS[rng.randrange(len(SIGNALS))]
    last_tick = 60 if realtime else 400
    phase = seed % 4
    trigger = [
        ("frame", 0),  # HELLO: during the handshake
        ("frame", rng.randrange(1, 7)),  # SET_WATCHDOG .. first SETPOINTs
        ("tick", rng.randrange(1, last_tick)),
        ("tick", rng.randrange(1, last_tick)),
    ][phase]
    return trigger, signum, "rls,hopfield" if phase == 3 else None


@pytest.fixture
def watch(monkeypatch):
    """Counts the rows the log writer wrote, and notes the count when the capture's
    signal handler ran."""
    seen = {"rows": 0, "rows_at_signal": None}
    request, write_row = StopRequest.request, LogWriter.write_row

    def noted_request(self, *args):
        if seen["rows_at_signal"] is None:
            seen["rows_at_signal"] = seen["rows"]
        request(self, *args)

    def counted_write_row(self, *args):
        write_row(self, *args)
        seen["rows"] += 1

    monkeypatch.setattr(StopRequest, "request", noted_request)
    monkeypatch.setattr(LogWriter, "write_row", counted_write_row)
    return seen


def _run(tmp_path, seed: int, realtime: bool, stray, watch):
    trigger, signum, online = _moment(seed, realtime)
    traj = gentle_trajectory(tmp_path / "traj.yaml")
    log = tmp_path / "run.csv"
    port = f"sim://guard?seed={seed}" + ("&pacing=realtime" if realtime else "")
    args = ["capture", "--trajectory", str(traj), "--duration", "20", "--port", port,
            "-o", str(log), "--quiet"] + (["--online", online] if online else [])  # fmt: skip
    with witnessed(trigger, signum) as robots:
        result = CliRunner().invoke(main, args)
    (robot,) = robots
    what = f"seed {seed} {trigger} {signal.Signals(signum).name} online={online}"
    assert result.exception is None or isinstance(result.exception, SystemExit), what
    assert "Traceback" not in result.output, what
    assert robot.sent_at is not None, what  # the moment came
    assert stray == [], what
    assert result.exit_code == 128 + signum, (what, result.output)
    # the robot was put idle after the signal, and nothing moved it again
    assert robot.idled_after_signal(), (what, robot.commands[robot.sent_at :])
    assert robot.fw.mode == IDLE and not robot.fw.streaming, what
    # and the set-up went no further (setpoints and START_STREAM already queued in the
    # same step may follow)
    later = robot.commands[robot.sent_at :]
    assert not [c for c in later if c[0] in SETUP or c[0] == "SET_MODE" and c[1] != IDLE], what
    if not log.exists():  # stopped before the handshake succeeded: nothing written
        assert "before the capture started: nothing written" in result.output, what
        assert not any(c[0] == "SET_MODE" and c[1] != IDLE for c in robot.commands), what
        return
    footer = footer_dict(log)
    assert footer["ended"] == "interrupted", (what, footer)
    assert footer["signal"] == signal.Signals(signum).name, what
    rows = parse_rows(log, log_fields())
    assert footer["rows"] == len(rows), what
    # a clean link: the stop dropped no byte (no half-read frame)
    link = footer["link"]
    assert link["crc_errors"] == link["framing_errors"] == link["seq_gaps"] == 0, (what, link)
    assert len(rows) < 20 / 0.015, what  # it did stop
    ticks = [int(r[0]) for r in rows]
    assert ticks == sorted(set(ticks)), what
    # stopped within one tick's work: at most the row in hand when the handler ran
    assert watch["rows_at_signal"] is not None, what
    assert len(rows) - watch["rows_at_signal"] <= 1, (what, len(rows), watch)


@pytest.mark.parametrize("seed", LOCKSTEP_SEEDS)
def test_signal_stops_a_lockstep_capture(tmp_path, seed, stray_signals, watch):
    _run(tmp_path, seed, False, stray_signals, watch)


@pytest.mark.parametrize("seed", REALTIME_SEEDS)
def test_signal_stops_a_realtime_capture(tmp_path, seed, stray_signals, watch):
    _run(tmp_path, seed, True, stray_signals, watch)


def test_the_seeds_cover_every_phase():
    """The seeded moments include the handshake, the set-up, motion and --online."""
    moments = [_moment(s, False) for s in LOCKSTEP_SEEDS] + [
        _moment(s, True) for s in REALTIME_SEEDS
    ]
    assert any(t == ("frame", 0) for t, _, _ in moments)  # HELLO: the handshake
    assert any(t[0] == "frame" and t[1] > 0 for t, _, _ in moments)
    assert any(t[0] == "tick" and o for t, _, o in moments)  # moving, estimators running
    assert {s for _, s, _ in moments} == set(SIGNALS)


class SilentRobot:
    """A device that takes every command and never answers; sends ``signum`` to this
    process when the first host frame (HELLO) arrives."""

    tick_period_s = 0.015

    def __init__(self, signum: int) -> None:
        self.signum = signum
        self.parser = FrameParser()
        self.commands: list[str] = []

    def receive(self, data: bytes) -> None:
        for frame in self.parser.feed(data):
            self.commands.append(frame.msg.SPEC.name)
            if len(self.commands) == 1:
                os.kill(os.getpid(), self.signum)

    def advance(self) -> None:
        pass

    def take_output(self) -> bytes:
        return b""

    def wants_time(self) -> bool:
        return False

    def close(self) -> None:
        pass


@pytest.mark.parametrize("signum", SIGNALS)
def test_signal_stops_a_handshake_with_a_silent_robot(tmp_path, signum, stray_signals):
    """The capture waits for INFO (up to --timeout 30 s of simulated time); the signal
    ends the wait at once: the run reports the interruption, not the missing answer."""
    made = []
    old = register_device_factory(
        lambda robot, options: made.append(SilentRobot(signum)) or made[-1]
    )
    try:
        res = CliRunner().invoke(
            main, ["capture", "--trajectory", str(gentle_trajectory(tmp_path / "t.yaml")),
                   "--port", "sim://guard", "--timeout", "30", "-o", str(tmp_path / "r.csv")],
        )  # fmt: skip
    finally:
        register_device_factory(old)
    assert res.exit_code == 128 + signum, res.output
    assert "before the capture started: nothing written" in res.output
    assert "no answer" not in res.output and not (tmp_path / "r.csv").exists()
    assert stray_signals == []
    (robot,) = made
    assert robot.commands[0] == "HELLO" and "SET_MODE" in robot.commands[1:]  # idle, unanswered


def test_sigint_stops_a_capture_process_that_inherited_it_ignored(tmp_path):
    """The root cause of the flaky SIGINT test: a process started from a background job
    (a non-interactive shell's `cmd &`, and so pytest run that way and its children)
    inherits SIGINT ignored, and Python then installs no KeyboardInterrupt at all. The
    capture installs its own handlers, so the signal stops it whatever it inherited."""
    signum = signal.SIGINT
    log = tmp_path / "run.csv"
    traj = gentle_trajectory(tmp_path / "t.yaml")
    cmd = [sys.executable, "-m", "guardid", "capture", "--trajectory", str(traj),
           "--duration", "60", "--port", "sim://guard?pacing=realtime", "-o", str(log)]  # fmt: skip
    proc = subprocess.Popen(
        cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
        preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_IGN),
    )  # fmt: skip
    deadline = time.monotonic() + GUARD_S  # failure guard only
    while time.monotonic() < deadline and proc.poll() is None:
        if log.exists() and len(parse_rows(log, log_fields())) >= 20:
            break
        time.sleep(0.02)
    proc.send_signal(signum)
    out, err = proc.communicate(timeout=GUARD_S)
    assert proc.returncode == 128 + signum, err
    assert "Traceback" not in err
    footer = footer_dict(log)
    assert footer["ended"] == "interrupted" and footer["signal"] == signal.Signals(signum).name
    assert footer["rows"] == len(parse_rows(log, log_fields())) >= 20
    assert out.startswith("interrupted: ")


def _capture_process(tmp_path, log, *extra, **popen):
    traj = gentle_trajectory(tmp_path / "t.yaml")
    cmd = [sys.executable, "-m", "guardid", "capture", "--trajectory", str(traj), "--duration",
           "60", "--port", "sim://guard?pacing=realtime", "-o", str(log), *extra]  # fmt: skip
    return subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, **popen)


def _wait_for_rows(proc, log, rows: int) -> None:
    deadline = time.monotonic() + GUARD_S  # failure guard only
    while time.monotonic() < deadline and proc.poll() is None:
        if log.exists() and len(parse_rows(log, log_fields())) >= rows:
            return
        time.sleep(0.02)
    raise AssertionError(f"no {rows} rows in {log}: {proc.poll()}")


def test_sighup_ends_a_capture_process_like_sigterm(tmp_path):
    """A closed terminal or a dropped ssh session (SIGHUP): the log gets its footer with
    ``signal: SIGHUP``, the summary line is printed, exit 129 (128 + 1)."""
    log = tmp_path / "run.csv"
    proc = _capture_process(tmp_path, log)
    _wait_for_rows(proc, log, 20)
    proc.send_signal(signal.SIGHUP)
    out, err = proc.communicate(timeout=GUARD_S)
    assert proc.returncode == 128 + signal.SIGHUP, err
    assert "Traceback" not in err
    footer = footer_dict(log)
    assert footer["ended"] == "interrupted" and footer["signal"] == "SIGHUP"
    assert footer["rows"] == len(parse_rows(log, log_fields())) >= 20
    assert out.startswith("interrupted: ")


def test_nohup_leaves_sighup_ignored(tmp_path):
    """Under ``nohup`` (SIGHUP inherited ignored) a SIGHUP does not stop the capture; a
    SIGTERM afterwards does, with its own name in the footer."""
    log = tmp_path / "run.csv"
    proc = _capture_process(
        tmp_path, log, preexec_fn=lambda: signal.signal(signal.SIGHUP, signal.SIG_IGN)
    )
    _wait_for_rows(proc, log, 10)
    proc.send_signal(signal.SIGHUP)
    rows_then = len(parse_rows(log, log_fields()))
    _wait_for_rows(proc, log, rows_then + 20)  # still recording after the SIGHUP
    proc.send_signal(signal.SIGTERM)
    _, err = proc.communicate(timeout=GUARD_S)
    assert proc.returncode == 128 + signal.SIGTERM, err
    assert footer_dict(log)["signal"] == "SIGTERM"


def test_interrupted_long_capture_counts_lost_rows_of_the_ticks_reached(tmp_path):
    """Stopped during the set-up of a 100000 s capture, after the log exists: the summary
    says 0 rows, 0 lost (not the 6666667 ticks planned) and no rms figure (was 'nan'); the
    footer's ticks_expected is the ticks reached, 0."""
    traj = gentle_trajectory(tmp_path / "t.yaml")
    log = tmp_path / "run.csv"
    args = ["capture", "--trajectory", str(traj), "--duration", "100000", "-o", str(log),
            "--quiet"]  # fmt: skip
    with witnessed(("frame", 2), signal.SIGINT) as robots:
        res = CliRunner().invoke(main, args)
    (robot,) = robots
    assert res.exit_code == 130, res.output
    assert robot.fw.mode == IDLE
    assert log.exists(), res.output  # the signal came after the log was opened
    line = res.stdout.strip()
    assert line.startswith("interrupted: 0 rows in ") and "(0 lost)" in line, line
    assert "nan" not in line and "no rows" in line, line
    footer = footer_dict(log)
    assert footer["rows"] == 0 and footer["ticks_expected"] == 0, footer
