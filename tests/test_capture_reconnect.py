"""capture --reconnect: a port lost mid-capture comes back (or not); every branch.

The simulated outage: sim://guard?disconnect_s=T&reconnect_s=U (the robot runs on, its
watchdog idles it). A 2 s-period trajectory keeps the captures short (lock-step)."""

from __future__ import annotations

import os
import signal
import subprocess
import sys

import numpy as np
import pytest
import yaml
from badinput_tools import ERROR_PREFIX, invoke

from guardid.capture.checks import counts_per_rad
from guardid.capture.resume import approach_ticks, link_lost, next_rest_index, resume_rows
from guardid.errors import LinkError
from guardid.excitation import load_trajectory
from guardid.fakeport import register_device_factory
from guardid.fakeport.engine import LinkEngine
from guardid.firmware.emulator import FirmwareEmulator, make_sim_device
from guardid.link import open_port
from guardid.robot import load_robot

GUARD = load_robot("guard")
T = GUARD.sample_period
OUTAGE = "sim://guard?seed=2&disconnect_s=2.5&reconnect_s=3"


@pytest.fixture(scope="module")
def trajectory(tmp_path_factory):
    path = tmp_path_factory.mktemp("reconnect") / "traj.yaml"
    res = invoke("excite", "--no-optimise", "--base-freq", "0.5", "--harmonics", "3", "-o", path)
    assert res.exit_code == 0, res.stderr
    return path


def footer(path) -> dict:
    lines = path.read_text().splitlines()
    start = lines.index("# footer:")
    return yaml.safe_load("\n".join(x[2:] for x in lines[start:]))["footer"]


def capture(trajectory, log, port=OUTAGE, *extra):
    return invoke("capture", "--trajectory", trajectory, "--duration", 8, "--port", port,
                  "--quiet", "-o", log, *extra)  # fmt: skip


def test_port_back_in_time_rows_before_and_after_one_gap(trajectory, tmp_path):
    log = tmp_path / "run.csv"
    res = capture(trajectory, log, OUTAGE, "--reconnect", 5)
    assert res.exit_code == 0, res.stderr
    assert "resuming the trajectory at 4.005 s" in res.stderr  # 2 periods of 2 s: row 267
    d = np.genfromtxt(log, delimiter=",", names=True)
    jumps = np.flatnonzero(np.diff(d["tick"]) > 1)
    assert len(jumps) == 1  # one gap, contiguous rows either side
    k = jumps[0]
    assert d["time_s"][k] < 2.5 <= d["time_s"][k + 1] - 3.0  # before the outage; after it
    assert d["tick"][k + 1] - d["tick"][k] > 3.0 / T  # at least the 3 s away
    # after the gap: the trajectory's rows from its rest point at 4.005 s to its end
    traj = load_trajectory(trajectory)
    n_after = len(d) - (k + 1)
    rows = np.arange(267, 267 + n_after)
    assert rows[-1] == round(8 / T) - 1
    expect = np.rint(traj.positions(rows * T) * counts_per_rad(GUARD)) / counts_per_rad(GUARD)
    got = np.column_stack([d["sp_pan_rad"][k + 1 :], d["sp_tilt_rad"][k + 1 :]])
    assert np.allclose(got, expect, atol=1e-9)
    f = footer(log)
    assert f["ended"] == "complete" and f["reconnects"] == 1
    assert f["gaps"][0]["resume_row"] == 267 and f["gaps"][0]["ticks_away"] >= 3.0 / T
    ident = invoke("identify", log, "--method", "ls", "-o", tmp_path / "p.yaml")
    assert ident.exit_code == 0, ident.stderr
    assert sum("gap at" in x for x in ident.stderr.splitlines()) == 1


def test_not_back_within_the_wait_ends_with_rows_kept(trajectory, tmp_path):
    log = tmp_path / "run.csv"
    res = capture(trajectory, log, OUTAGE, "--reconnect", 1)
    assert res.exit_code == 3
    lines = res.stderr.strip().splitlines()
    assert lines[-1].startswith(ERROR_PREFIX) and "not back within 1 s" in lines[-1]
    assert "rows kept" in lines[-1]
    rows = np.genfromtxt(log, delimiter=",", names=True)
    assert 0 < len(rows) and rows["time_s"][-1] < 2.5
    f = footer(log)
    assert f["reconnects"] == 0 and f["ended"].startswith("link error")


def test_without_reconnect_as_before(trajectory, tmp_path):
    log = tmp_path / "run.csv"
    res = capture(trajectory, log)
    assert res.exit_code == 3
    lines = res.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith(ERROR_PREFIX) and "rows kept" in lines[0]
    assert "reconnects" not in footer(log)


def test_back_but_no_answer_ends_with_rows_kept(trajectory, tmp_path):
    class AnswersOnce(FirmwareEmulator):
        hellos = 0

        def _answer_once(self, frame):
            AnswersOnce.hellos += 1
            if AnswersOnce.hellos == 1:
                FirmwareEmulator._on_hello(self, frame)

        _HANDLERS = {**FirmwareEmulator._HANDLERS, "Hello": _answer_once}

    def factory(robot, options):
        plain = make_sim_device(robot, options)
        return AnswersOnce(plain.description, plain.plant)

    old = register_device_factory(factory)
    try:
        log = tmp_path / "run.csv"
        res = capture(trajectory, log, OUTAGE, "--reconnect", 5)
    finally:
        register_device_factory(old)
    assert res.exit_code == 3
    last = res.stderr.strip().splitlines()[-1]
    assert "no answer to HELLO" in last and "the robot did not answer" in last
    assert "rows kept" in last and footer(log)["reconnects"] == 0


def test_robot_restarted_meanwhile_is_not_resumed(trajectory, tmp_path, monkeypatch):
    original = LinkEngine._reconnect

    def reset_too(self):  # the board restarted while the cable was out: tick from 0
        original(self)
        self.device.tick = 0

    monkeypatch.setattr(LinkEngine, "_reconnect", reset_too)
    log = tmp_path / "run.csv"
    res = capture(trajectory, log, OUTAGE, "--reconnect", 5)
    assert res.exit_code == 3
    assert "restarted" in res.stderr and "rows kept" in res.stderr
    assert footer(log)["reconnects"] == 0


# ------------------------------------------------------------------ pieces
def test_sim_link_comes_back_with_the_robot_run_on():
    port = open_port("sim://guard?disconnect_s=1&reconnect_s=0.5", timeout_s=0.1)
    try:
        with pytest.raises(Exception, match="disconnected"):
            while True:
                port.read(1)
                port.write(b"\x00")  # keep reading: the stream is off, time runs on reads
        assert port.sim_time_s == pytest.approx(1.0)
        assert not port.wait_link(0.2) and port.sim_time_s == pytest.approx(1.2)
        assert port.wait_link(1.0) and port.sim_time_s == pytest.approx(1.5)
        # ran on meanwhile: ticks every 15 ms to 1.485 s (the one at 1.5 s follows the
        # reconnect at the same time, the engine's order of events)
        assert port.engine.device.tick == round(1.5 / T) - 1
    finally:
        port.close()


def test_next_rest_index_by_hand():
    class Traj:
        period = 2.0

        @staticmethod
        def velocities(t):
            return np.zeros((1, 2))

    # a period is 133.33 ticks: its starts fall on rows 0, 134 (ceil 133.33), 267, 400
    assert next_rest_index(Traj, GUARD, 170) == 267
    assert next_rest_index(Traj, GUARD, 134) == 134
    assert next_rest_index(Traj, GUARD, 170, after=267) == 400

    class Moving(Traj):
        @staticmethod
        def velocities(t):
            return np.full((1, 2), 0.2)

    assert next_rest_index(Moving, GUARD, 170) is None


def test_link_lost_is_not_a_refusal():
    assert link_lost(LinkError("port x: read failed (disconnected?): gone"))
    assert link_lost(LinkError("port x: telemetry stopped (no frame for 1 s)"))
    assert not link_lost(LinkError("port x: SET_MODE refused by the robot: estop_active"))


def test_approach_within_half_the_limits(trajectory):
    traj = load_trajectory(trajectory)
    per_rad = counts_per_rad(GUARD)
    start = np.array([1.0, -0.17]) * per_rad  # pan turned away, tilt on its stop
    rows, lead = resume_rows(traj, GUARD, np.rint(start), 267, 533)
    approach = np.array([rows[k] for k in range(lead)]) / per_rad
    assert np.allclose(approach[0], np.rint(start) / per_rad)
    target = np.rint(traj.positions(np.array([267 * T]))[0] * per_rad) / per_rad
    assert np.allclose(approach[-1], target) and np.allclose(rows[lead], target)
    speed = np.abs(np.diff(approach, axis=0)) / T
    vmax = np.array([j.limits.velocity for j in GUARD.joints])
    assert np.all(speed.max(axis=0) <= 0.5 * vmax + 2 / per_rad / T)  # + quantisation
    ramp = approach_ticks(GUARD, approach[0], target)
    assert ramp * T >= 1.875 * 1.0 / (0.5 * 0.9)  # the pan's 1 rad at half its 0.9 rad/s
    assert len(rows) == lead + 533 - 267


def test_pty_whose_server_goes_away_and_comes_back(trajectory, tmp_path):
    """fake-port --link: the pty vanishes at 2.5 s (simulated) with its symlink, a new one
    comes up 0.3 s later behind the same link; the capture waits, re-handshakes, goes on."""
    link = tmp_path / "robot"
    cmd = [sys.executable, "-m", "guardid", "fake-port", "--link", str(link),
           "--disconnect-s", "2.5", "--reconnect-s", "0.3"]  # fmt: skip
    proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, text=True)
    try:
        first = proc.stdout.readline().strip()
        assert os.readlink(link) == first
        log = tmp_path / "run.csv"
        res = invoke("capture", "--trajectory", trajectory, "--duration", 4.5, "--port", link,
                     "--reconnect", 20, "--quiet", "-o", log)  # fmt: skip
        assert res.exit_code == 0, res.stderr
        assert os.path.exists(link)  # a new pty (its number may be reused) behind the path
    finally:
        proc.send_signal(signal.SIGINT)
        assert proc.wait(timeout=60) == 0
        proc.stdout.close()
    assert not os.path.lexists(link)  # removed at exit
    d = np.genfromtxt(log, delimiter=",", names=True)
    assert len(np.flatnonzero(np.diff(d["tick"]) > 1)) == 1
    assert d["time_s"][0] < 2.5 and d["tick"][-1] - d["tick"][-2] == 1  # to the end
    f = footer(log)
    assert f["reconnects"] == 1 and f["gaps"][0]["resume_row"] == 267
    assert f["ended"] == "complete" and len(d) == f["rows"]


def test_reconnect_needs_a_disconnect():
    res = invoke("fake-port", "--reconnect-s", "1")
    assert res.exit_code == 2 and "--reconnect-s" in res.stderr
    assert len(res.stderr.strip().splitlines()) == 1


def test_wait_for_a_device_path(tmp_path):
    """A device path that is not there: None after the wait; a stop request raises at the
    next attempt; a path that is there opens."""
    from guardid.link.reconnect import wait_for_port

    class Gone:
        closed = False

        def close(self):
            Gone.closed = True

    missing = str(tmp_path / "ttyUSB9")
    assert wait_for_port(Gone(), missing, 115200, 0.2, poll_s=0.05) is None and Gone.closed
    calls = []

    def check():
        calls.append(1)
        if len(calls) == 3:
            raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        wait_for_port(Gone(), missing, 115200, 60.0, poll_s=0.01, check=check)
    master, slave = os.openpty()
    try:
        port = wait_for_port(Gone(), os.ttyname(slave), 115200, 1.0)
        assert port is not None and port.is_open
        port.close()
    finally:
        os.close(master)
        os.close(slave)
