"""Recorded data is never lost or overwritten (capture, identify, simulate outputs), and a
log write error (disk full) or any other error mid-capture idles the robot first and
keeps every completed row."""

from __future__ import annotations

import errno
import hashlib
import os
import subprocess
import sys
from pathlib import Path

import pytest
from capturetools import (
    IDLE,
    footer_lines,
    gentle_trajectory,
    log_fields,
    parse_rows,
    witnessed,
)
from click.testing import CliRunner

from guardid.cli import main
from guardid.commands.outputs import same_file
from guardid.log import LogWriter


def _digest(path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


def _capture(tmp_path, *extra, port="sim://guard", traj=None):
    traj = traj or gentle_trajectory(tmp_path / "traj.yaml")
    args = ["capture", "--trajectory", str(traj), "--duration", "1.5", "--port", port,
            "--quiet", *extra]  # fmt: skip
    return CliRunner().invoke(main, args)


def _one_line_error(res, *words):
    assert res.exit_code != 0, res.output
    assert res.exception is None or isinstance(res.exception, SystemExit), res.exception
    lines = [x for x in res.output.splitlines() if x.strip()]
    errors = [x for x in lines if x.startswith("guardid: error: ")]
    assert len(errors) == 1, res.output
    assert "Traceback" not in res.output
    for w in words:
        assert w in errors[0], (w, errors[0])
    return errors[0]


def _guard_yaml_copy(tmp_path):
    from guardid.robot import load_robot

    robot = tmp_path / "guard.yaml"
    robot.write_bytes(Path(load_robot("guard").source).read_bytes())
    return robot


# ------------------------------------------------------------------ existing outputs
def test_capture_refuses_an_existing_log_without_force(tmp_path):
    log = tmp_path / "run.csv"
    assert _capture(tmp_path, "-o", str(log)).exit_code == 0
    before = _digest(log)
    with witnessed() as robots:
        res = _capture(tmp_path, "-o", str(log))
    _one_line_error(res, "run.csv", "already exists", "--force")
    assert _digest(log) == before  # untouched
    assert robots == []  # refused before the port was even opened
    # --force replaces it with a new, complete log
    res = _capture(tmp_path, "-o", str(log), "--force")
    assert res.exit_code == 0, res.output
    assert "ended: complete" in "\n".join(footer_lines(log))


def test_failed_handshake_leaves_an_existing_log_alone(tmp_path, monkeypatch):
    """The 4000-row log is kept even with --force: nothing is written before the
    handshake succeeds (here the 'robot' only echoes, so no INFO ever comes)."""
    log = tmp_path / "run.csv"
    assert _capture(tmp_path, "-o", str(log)).exit_code == 0
    before = _digest(log)
    monkeypatch.setenv("GUARDID_FAKEPORT_DEVICE", "echo")
    res = _capture(tmp_path, "-o", str(log), "--force", "--timeout", "0.2")
    _one_line_error(res, "HELLO")
    assert _digest(log) == before
    new = tmp_path / "new.csv"
    _one_line_error(_capture(tmp_path, "-o", str(new), "--timeout", "0.2"), "HELLO")
    assert not new.exists()  # no empty file either


@pytest.mark.parametrize("spelling", ["same", "dotted", "symlink", "hardlink"])
def test_capture_output_may_not_be_its_trajectory(tmp_path, spelling):
    traj = gentle_trajectory(tmp_path / "traj.yaml")
    before = _digest(traj)
    (tmp_path / "sub").mkdir()
    out = {
        "same": traj,
        "dotted": tmp_path / "sub" / ".." / "traj.yaml",
        "symlink": tmp_path / "link.yaml",
        "hardlink": tmp_path / "hard.yaml",
    }[spelling]
    if spelling == "symlink":
        out.symlink_to(traj)
    if spelling == "hardlink":
        os.link(traj, out)
    res = _capture(tmp_path, "-o", str(out), "--force", traj=traj)
    _one_line_error(res, "--trajectory", "another output")
    assert _digest(traj) == before


def test_capture_output_may_not_be_its_robot_yaml(tmp_path):
    robot = _guard_yaml_copy(tmp_path)
    before = _digest(robot)
    res = _capture(tmp_path, "--robot", str(robot), "-o", str(robot), "--force")
    _one_line_error(res, "--robot")
    assert _digest(robot) == before


def test_same_file_by_independent_cases(tmp_path):
    a = tmp_path / "a.csv"
    a.write_text("x")
    assert same_file(a, tmp_path / "." / "a.csv")
    assert not same_file(a, tmp_path / "b.csv")
    assert same_file(tmp_path / "new.csv", tmp_path / "x" / ".." / "new.csv")  # not there yet


def test_identify_output_may_not_be_an_input_log(tmp_path):
    log = tmp_path / "run.csv"
    assert _capture(tmp_path, "-o", str(log)).exit_code == 0
    before = _digest(log)
    for option in ("-o", "--plot"):
        res = CliRunner().invoke(main, ["identify", str(log), option, str(log)])
        _one_line_error(res, option, "LOG", "another output")
        assert _digest(log) == before


def test_simulate_output_may_not_be_its_robot(tmp_path):
    robot = _guard_yaml_copy(tmp_path)
    before = _digest(robot)
    res = CliRunner().invoke(
        main, ["simulate", "--robot", str(robot), "--duration", "0.1", "-o", str(robot)]
    )
    _one_line_error(res, "--robot")
    assert _digest(robot) == before


# ------------------------------------------------------------------ write errors
class DiskFull:
    """LogWriter._write on a disk that fills after ``ok_rows`` rows: the next row gets a
    short write of ``partial`` bytes (if > 0), then ENOSPC, as the kernel does. ``heals``
    True: space comes back for the footer. ``events`` gets 'footer' when the footer is
    attempted."""

    def __init__(self, ok_rows: int, partial: int = 0, heals: bool = False, events=None):
        self.ok_rows, self.partial, self.heals = ok_rows, partial, heals
        self.rows = 0
        self.full = False
        self.events = events if events is not None else []

    def _enospc(self):
        self.full = True
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))

    def __call__(self, fd, data) -> int:
        data = bytes(data)
        if data.startswith(b"# footer:"):
            self.events.append("footer")
            return os.write(fd, data) if self.heals or not self.full else self._enospc()
        if data.startswith((b"#", b"tick,")):
            return os.write(fd, data)  # the header
        if self.full:
            self._enospc()
        if self.rows < self.ok_rows:
            self.rows += 1
            return os.write(fd, data)
        if self.partial and not self.full:
            self.full = True
            return os.write(fd, data[: self.partial])  # a short write; ENOSPC next
        self._enospc()


@pytest.mark.parametrize(
    "ok_rows,partial,heals", [(0, 0, False), (37, 0, False), (37, 25, False), (61, 40, True)]
)
def test_disk_full_mid_capture_idles_first_and_keeps_every_row(
    tmp_path, monkeypatch, ok_rows, partial, heals
):
    events = []
    monkeypatch.setattr(
        LogWriter, "_write", staticmethod(DiskFull(ok_rows, partial, heals, events))
    )
    log = tmp_path / "run.csv"
    with witnessed(events=events) as robots:
        res = _capture(tmp_path, "-o", str(log))
    (robot,) = robots
    line = _one_line_error(res, str(log), "No space left on device", f"{ok_rows} rows kept")
    assert res.exit_code == 2, line
    # the motors first, the file after
    assert "idle" in events and "footer" in events, events
    assert events.index("idle") < events.index("footer"), events
    assert robot.fw.mode == IDLE and not robot.fw.streaming
    # every completed row is there, nothing half-written; the footer if the disk allowed it
    rows = parse_rows(log, log_fields())
    assert len(rows) == ok_rows
    assert log.read_bytes().endswith(b"\n")
    footer = "\n".join(footer_lines(log))
    if heals:
        assert f"rows: {ok_rows}" in footer and "log write error" in footer
        assert "footer written" in line
    else:
        assert footer == "" and "no footer" in line
    ticks = [int(r[0]) for r in rows]
    assert ticks == list(range(ticks[0], ticks[0] + ok_rows)) if rows else True


class RowBug(RuntimeError):
    """A bug in a caller's per-row work (e.g. an online tracker's), not a link or disk error."""


def test_any_other_error_mid_capture_idles_first_then_writes_the_footer(tmp_path, monkeypatch):
    """Promise: whatever else goes wrong mid-capture (here the on_row callback raises at
    the 50th row), the error propagates unchanged, the motors are put idle and the stream
    stopped before the footer is written, and the footer says what ended the run. 50 rows
    are in the log: each row is written before on_row sees it."""
    from guardid.capture.run import capture
    from guardid.excitation.sines import SumOfSines
    from guardid.link import Session, open_port
    from guardid.log import read_log
    from guardid.robot import load_robot

    guard = load_robot("guard")
    traj = SumOfSines.load(gentle_trajectory(tmp_path / "traj.yaml"))
    events = []
    robots = []
    write = DiskFull(ok_rows=10**9, events=events)  # never full: only records the footer

    def write_noting_the_robot(fd, data) -> int:
        if bytes(data).startswith(b"# footer:"):  # the robot's state as the footer goes out
            events.append(("robot", robots[0].fw.mode, robots[0].fw.streaming))
        return write(fd, data)

    monkeypatch.setattr(LogWriter, "_write", staticmethod(write_noting_the_robot))
    seen = []

    def on_row(t, q, v, i):
        seen.append(t)
        if len(seen) == 50:
            raise RowBug("row 50 went wrong")

    log = tmp_path / "run.csv"
    with witnessed(events=events) as made:
        port = open_port("sim://guard?seed=3")
        robots.extend(made)
        try:
            session = Session(port)
            session.handshake()
            with pytest.raises(RowBug, match="row 50 went wrong"):
                capture(session, guard, traj, 3.0, log, {"robot": "guard"}, on_row=on_row)
            (robot,) = robots
            # the motors first, the file after; nothing else written once the footer is
            assert robot.fw.mode == IDLE and not robot.fw.streaming
            assert ("robot", IDLE, False) in events, events
            assert events.index("idle") < events.index("footer"), events
            assert robot.moving_ticks > 0  # it did move before the error
        finally:
            port.close()
    assert len(parse_rows(log, log_fields())) == 50
    footer = read_log(log).footer
    assert footer["rows"] == 50
    assert footer["ended"] == "error: RowBug: row 50 went wrong"


def test_dev_full_is_one_line_and_the_robot_stays_idle(tmp_path):
    if not os.path.exists("/dev/full"):
        pytest.skip("no /dev/full")
    with witnessed() as robots:
        res = _capture(tmp_path, "-o", "/dev/full", "--force")
    _one_line_error(res, "/dev/full", "No space left on device")
    (robot,) = robots
    assert robot.fw.mode == IDLE
    assert not any(c[0] == "SET_MODE" and c[1] != IDLE for c in robot.commands)  # never moved
    proc = subprocess.run(
        [sys.executable, "-m", "guardid", "capture", "--trajectory", str(tmp_path / "traj.yaml"),
         "--duration", "1", "-o", "/dev/full", "--force", "--quiet"],
        capture_output=True, text=True,
    )  # fmt: skip
    assert proc.returncode == 2 and "Traceback" not in proc.stderr
    assert proc.stderr.startswith("guardid: error: /dev/full") and proc.stderr.count("\n") == 1


def test_log_writer_creates_exclusively_unless_told_to_overwrite(tmp_path):
    from guardid.log import LogWriteError

    log = tmp_path / "run.csv"
    log.write_text("a recorded log\n")
    with pytest.raises(LogWriteError, match="run.csv: already exists"):
        LogWriter(log, ["pan"], {"robot": "guard"})
    assert log.read_text() == "a recorded log\n"
    LogWriter(log, ["pan"], {"robot": "guard"}, overwrite=True).close({"ended": "complete"})
    assert log.read_text().startswith("tick,time_s,counts_pan,")
