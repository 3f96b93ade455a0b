"""Promises of the log, capture and trajectory checks that no test defended (issue 26,
deliverable 7): each test here failed with a deliberate one-line bug and passes without it.

* the log writer fsyncs rows at least every ``sync_interval_s`` of (fake) wall-clock time,
  not only with the header and the footer;
* a robot whose INFO tick period is 1 us off the description's sample period is refused
  (INFO carries whole microseconds);
* a trajectory below a joint's lower position limit is refused (tilt's -10 deg);
* a repeated tick is refused by the log reader and by ``load_run``;
* when the last tick's telemetry frame is lost, no row past the trajectory is logged.
"""

from __future__ import annotations

import math
import types

import numpy as np
import pytest
from linktools import Sines

from guardid.capture import capture
from guardid.capture.checks import check_info
from guardid.errors import ConfigError, LogFormatError
from guardid.excitation.limits import first_violation
from guardid.excitation.sines import SumOfSines
from guardid.identify.runs import load_run
from guardid.link import Session, open_port
from guardid.log import LogWriter, read_log
from guardid.log import csvlog as csvlog_module
from guardid.robot import load_robot

GUARD = load_robot("guard")
TILT_LO = -0.17453292519943295  # rad, guard.yaml: -10 deg
PER_RAD = np.array([48 * 500, 48 * 1000]) / (2 * math.pi)  # counts per joint rad, by hand


# ---------------------------------------------------------------- (a) rows are fsynced
class FakeClock:
    """Stands in for the writer's ``time`` module: ``monotonic()`` returns ``now`` [s]."""

    def __init__(self) -> None:
        self.now = 0.0

    def monotonic(self) -> float:
        return self.now


def _synced_rows(tmp_path, monkeypatch, interval_s, row_times_s):
    """Write one row at each fake time; returns the writer's row count at every fsync."""
    clock = FakeClock()
    monkeypatch.setattr(csvlog_module, "time", types.SimpleNamespace(monotonic=clock.monotonic))
    at_sync: list[int] = []
    holder: dict = {}
    real_fsync = csvlog_module.os.fsync

    def fsync(fd):
        at_sync.append(holder["w"].rows if "w" in holder else -1)
        real_fsync(fd)

    monkeypatch.setattr(csvlog_module.os, "fsync", fsync)
    w = holder["w"] = LogWriter(tmp_path / "run.csv", ["pan", "tilt"], {"robot": "guard"},
                                sync_interval_s=interval_s)  # fmt: skip
    at_sync[:] = [0] * len(at_sync)  # the header's fsync(s), before any row
    for k, t in enumerate(row_times_s):
        clock.now = t
        w.write_row(100 + k, 0.015 * k, [1, 2], [0.1, 0.2], [1.0, 2.0], [0.1, 0.2],
                    [0.1, 0.2], 0)  # fmt: skip
    w.close({"ended": "complete"})
    return at_sync


def test_rows_are_fsynced_at_least_every_sync_interval(tmp_path, monkeypatch):
    """Rows every 0.3 s (fake clock), interval 1 s: the header's fsync at 0 s, then the first
    row at least 1 s after the last fsync is synced: row 4 (1.2 s), row 8 (2.4 s); row 10
    (3.0 s) only 0.6 s after; the footer's fsync closes. Worked out by hand."""
    times = [0.3 * k for k in range(1, 11)]
    at_sync = _synced_rows(tmp_path, monkeypatch, 1.0, times)
    assert at_sync[0] == 0 and at_sync[-1] == 10  # the header's and the footer's
    assert at_sync[1:-1] == [4, 8]
    # never more than the interval (plus one row spacing) of rows without an fsync
    synced_times = [0.0] + [times[r - 1] for r in at_sync[1:-1]]
    assert np.all(np.diff(synced_times + [times[-1]]) <= 1.0 + 0.3 + 1e-12)


def test_with_interval_zero_every_row_is_fsynced(tmp_path, monkeypatch):
    at_sync = _synced_rows(tmp_path, monkeypatch, 0.0, [0.0] * 5)
    assert at_sync == [0, 1, 2, 3, 4, 5, 5]  # header, each of 5 rows, footer


# ---------------------------------------------------------------- (b) INFO tick period
INFO = {"joint_count": 2, "counts_per_rev": (24000, 48000), "capabilities": 0b01111}


def test_info_tick_period_one_microsecond_off_is_refused():
    """INFO carries the tick period in whole microseconds: 15 000 us matches guard's
    0.015 s; 15 001 us (or 14 999) is another firmware build and must be refused."""
    check_info({**INFO, "tick_period": 15000e-6}, GUARD, "sim://guard")  # fine
    for us in (15001, 14999):
        shown = f"{us / 1000:g}".replace(".", r"\.")  # 15.001 / 14.999 ms
        with pytest.raises(ConfigError, match=rf"sample_period 15 ms.*tick period of {shown} ms"):
            check_info({**INFO, "tick_period": us * 1e-6}, GUARD, "sim://guard")


# ---------------------------------------------------------------- (d) lower position limit
def test_first_violation_of_the_lower_position_limit_worked_by_hand():
    """tilt = 0.2 - 0.5 sin(2 pi 0.05 t) passes -10 deg when sin(w t) = (0.2 - lo) / 0.5,
    t* = asin(0.749066) / (0.1 pi) = 2.7016 s; velocity <= 0.157 rad/s and acceleration
    <= 0.049 rad/s^2 stay far inside, the upper limit +35 deg is never reached before it."""
    traj = SumOfSines([[0.0], [-0.5]], [[0.05], [0.05]], [[0.0], [0.0]], [0.0, 0.2])
    bad = first_violation(traj, GUARD)
    t_star = math.asin((0.2 - TILT_LO) / 0.5) / (2 * math.pi * 0.05)
    assert bad is not None
    assert (bad.joint, bad.kind, bad.limit) == ("tilt", "position", TILT_LO)
    assert t_star <= bad.time_s <= t_star + 1e-3  # the first 1 ms grid point past t*
    assert TILT_LO - 0.5 * 0.1 * math.pi * 1e-3 - 1e-12 < bad.value < TILT_LO
    assert "joint tilt" in bad.describe() and "-10.0 deg" in bad.describe()


# ---------------------------------------------------------------- (e) repeated tick
def test_reader_refuses_a_repeated_tick_naming_the_line(tmp_path):
    """Line 1 the names, line 2 the header, data from line 3: the tick 2 repeated on line 5."""
    path = tmp_path / "rep.csv"
    path.write_text("tick,time_s,x\n# guardid-log: 1\n1,0.000,1\n2,0.015,2\n2,0.015,3\n"
                    "3,0.030,4\n")  # fmt: skip
    with pytest.raises(LogFormatError) as info:
        read_log(path)
    msg = str(info.value)
    assert "\n" not in msg and str(path) in msg and "line 5" in msg and "tick 2" in msg
    assert "after 2" in msg or "repeat" in msg
    # the same rows with the ticks increasing are read (the refusal is about the tick)
    path.write_text(path.read_text().replace("2,0.015,3", "4,0.045,3").replace("3,0.030", "5,0.06"))
    assert read_log(path).columns["tick"].tolist() == [1, 2, 4, 5]


def _guard_log(path, ticks):
    w = LogWriter(path, ["pan", "tilt"], {"robot": "guard", "sample_period": 0.015})
    for k, tick in enumerate(ticks):
        q = [0.01 * k, 0.02 * k]
        counts = np.rint(np.array(q) * PER_RAD)
        w.write_row(tick, 0.015 * (tick - ticks[0]), counts, q, [1.0, 2.0], [0.1, 0.2], q, 0)
    w.close({"ended": "complete"})


def test_load_run_refuses_a_repeated_tick(tmp_path):
    ticks = list(range(100, 110)) + [109] + list(range(110, 120))  # row 11 repeats tick 109
    path = tmp_path / "rep.csv"
    _guard_log(path, ticks)
    with pytest.raises(LogFormatError) as info:
        load_run(path, sample_period_s=0.015)
    msg = str(info.value)
    lines = path.read_text().splitlines()
    data_lines = [k + 1 for k, ln in enumerate(lines) if k and not ln.startswith("#")]
    assert "\n" not in msg and str(path) in msg
    assert "109 after 109" in msg or ("109" in msg and "repeat" in msg)
    assert f"line {data_lines[10]}" in msg or "row 11" in msg  # the repeated row, either way
    # the same log with every tick increasing loads
    _guard_log(tmp_path / "ok.csv", list(range(100, 121)))
    assert len(load_run(tmp_path / "ok.csv", sample_period_s=0.015).t) == 21


# ---------------------------------------------------------------- (l) the last frame lost
def test_no_row_past_the_trajectory_when_the_last_ticks_frame_is_lost(tmp_path):
    """The telemetry frame of the trajectory's last tick is lost on the link: the session
    then yields the next tick's frame (index n_ticks, past the trajectory). The log must hold
    ticks 0 .. n_ticks - 2 of the trajectory only, and say one row was lost."""
    port = open_port("sim://guard?seed=5")
    session = Session(port)
    session.handshake()
    real_track = session.track

    def losing_track(rows, *args, **kwargs):
        last = len(rows) - 1
        for index, t in real_track(rows, *args, **kwargs):
            if index == last:  # this frame is lost: the next one is the tick after
                yield index + 1, session.next_telemetry()
                return
            yield index, t

    session.track = losing_track
    log = tmp_path / "run.csv"
    n_ticks = 100  # 1.5 s at 15 ms
    result = capture(session, GUARD, Sines(), 1.5, log, {"robot": "guard"})
    port.close()
    data = read_log(log)
    ticks = data.columns["tick"].astype(int)
    index = ticks - ticks[0]  # the first row is trajectory row 0 (nothing else lost)
    assert index.tolist() == list(range(n_ticks - 1))
    assert result.rows == n_ticks - 1 and result.lost_rows == 1
    assert data.footer["rows"] == n_ticks - 1 and data.footer["ticks_expected"] == n_ticks
