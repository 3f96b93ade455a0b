"""Capture into crash-safe logs (the capture issue's acceptance checks)."""

from __future__ import annotations

import math
import os
import signal
import subprocess
import sys
import time

import numpy as np
import pytest
from capturetools import gentle_trajectory
from linktools import Recorder, Sines, expected_damage, teed_devices

from guardid.capture import capture
from guardid.errors import LinkError
from guardid.fakeport import register_device_factory
from guardid.firmware import FirmwareEmulator
from guardid.link import Session, open_port
from guardid.log import read_log
from guardid.plant import make_plant
from guardid.protocol import decode
from guardid.robot import load_robot

GUARD = load_robot("guard")
PER_RAD = np.array([48 * 500, 48 * 1000]) / (2 * math.pi)


class TruthRecorder:
    """Keeps the plant's true joint angles at every tick."""

    def __init__(self, plant) -> None:
        self.plant = plant
        self.q_true = {}

    def step(self, volts):
        s = self.plant.step(volts)
        self.q_true[s.tick] = s.q
        return s


@pytest.fixture
def recorded():
    made = {}

    def factory(robot, options):
        desc = load_robot(robot)
        made["plant"] = TruthRecorder(make_plant(desc, options))
        return FirmwareEmulator(desc, made["plant"])

    old = register_device_factory(factory)
    yield made
    register_device_factory(old)


def test_60s_capture_has_every_row_within_one_count_of_truth(tmp_path, recorded):
    port = open_port("sim://guard?seed=7")
    session = Session(port)
    session.handshake()
    log = tmp_path / "run.csv"
    result = capture(session, GUARD, Sines(), 60.0, log, {"robot": "guard"})
    port.close()
    assert result.rows == 4000 and result.ended == "complete"
    data = read_log(log)
    ticks = data.columns["tick"].astype(int)
    assert len(ticks) == 4000 and np.all(np.diff(ticks) == 1)
    q = data.joint_array("q")
    truth = np.array([recorded["plant"].q_true[k] for k in ticks])
    assert np.all(np.abs(q - truth) <= 1.0 / PER_RAD + 1e-12)
    # loadable by numpy directly, per the documented recipe
    arr = np.loadtxt(log, delimiter=",", skiprows=1)
    assert arr.shape == (4000, len(data.columns))
    assert data.footer["rows"] == 4000 and data.footer["link"]["crc_errors"] == 0
    assert np.allclose(data.columns["time_s"], (ticks - ticks[0]) * 0.015)


def test_disconnect_mid_capture_keeps_rows_and_says_why(tmp_path):
    port = open_port("sim://guard?seed=7&disconnect_s=5")
    session = Session(port, timeout_s=0.5)
    session.handshake()
    log = tmp_path / "run.csv"
    with pytest.raises(LinkError) as info:
        capture(session, GUARD, Sines(), 30.0, log, {"robot": "guard"})
    port.close()
    msg = str(info.value)
    assert "\n" not in msg and "rows kept" in msg and "sim://guard" in msg
    data = read_log(log)
    assert 250 < len(data.columns["tick"]) < 340  # ~5 s of 15 ms rows
    assert data.footer["ended"].startswith("link error")


def test_link_faults_show_as_gaps_and_footer_counts(tmp_path):
    with teed_devices() as tees:
        port = Recorder(open_port("sim://guard?seed=11&drop=3e-4&flip=3e-5&latency_ms=16"))
        session = Session(port, timeout_s=2.0)
        session.handshake()
        log = tmp_path / "run.csv"
        result = capture(session, GUARD, Sines(), 20.0, log, {"robot": "guard"})
        port.close()
    errors, lost = expected_damage(bytes(tees[0].sent), bytes(port.received))
    data = read_log(log)
    link = data.footer["link"]
    # the footer's counts equal the damage counted independently from the two byte streams
    assert errors > 0 and link["crc_errors"] + link["framing_errors"] == errors
    assert link["seq_gaps"] == len(lost)
    # lost telemetry rows are gaps in the tick column, never invented rows
    ticks = data.columns["tick"].astype(int)
    first = ticks[0] - int(round(data.columns["time_s"][0] / 0.015))  # tick of trajectory row 0
    lost_ticks = {
        f.msg.tick - first
        for f in map(decode, lost)
        if type(f.msg).__name__ == "Telemetry" and 0 <= f.msg.tick - first < result.ticks_expected
    }
    assert lost_ticks and set(ticks - first) == set(range(result.ticks_expected)) - lost_ticks
    assert data.footer["ticks_expected"] - data.footer["rows"] == len(lost_ticks)


def _cli_capture(tmp_path, duration: float):
    pytest.importorskip("guardid.commands.excite", reason="guardid excite not available")
    traj = tmp_path / "traj.yaml"
    subprocess.run(
        [sys.executable, "-m", "guardid", "excite", "--robot", "guard", "--no-optimise",
         "-o", str(traj)], check=True, capture_output=True,
    )  # fmt: skip
    log = tmp_path / "run.csv"
    port = "sim://guard?pacing=realtime"
    cmd = [sys.executable, "-m", "guardid", "capture", "--trajectory", str(traj),
           "--duration", str(duration), "--port", port, "-o", str(log)]  # fmt: skip
    return cmd, log


@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGKILL])
def test_killed_capture_leaves_a_readable_log(tmp_path, sig):
    cmd, log = _cli_capture(tmp_path, 60.0)
    proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    deadline = time.monotonic() + 30
    while time.monotonic() < deadline:  # wait until rows are being written
        if log.exists():
            lines = log.read_text().splitlines()[1:]
            if sum(1 for line in lines if not line.startswith("#")) > 40:
                break
        time.sleep(0.05)
    proc.send_signal(sig)
    out, err = proc.communicate(timeout=30)
    data = read_log(log)
    assert len(data.columns["tick"]) > 10
    if sig == signal.SIGINT:
        assert proc.returncode == 130 and "Traceback" not in err
        assert data.footer is not None and data.footer["ended"] == "interrupted"
    else:
        assert proc.returncode == -signal.SIGKILL
        assert data.footer is None  # killed: no footer, every completed row still there


def test_bad_log_gives_one_line_error(tmp_path):
    bad = tmp_path / "bad.csv"
    bad.write_text("tick,time_s\n# guardid-log: 1\n1,0.0\n2,abc\n")
    from guardid.errors import LogFormatError

    with pytest.raises(LogFormatError, match=r"bad.csv: line 4: not a number") as info:
        read_log(bad)
    assert "\n" not in str(info.value)
    missing = tmp_path / "nope.csv"
    with pytest.raises(LogFormatError, match="nope.csv: cannot read") as info:
        read_log(missing)
    assert "\n" not in str(info.value)


def test_missing_port_is_a_one_line_error(tmp_path):
    with pytest.raises(LinkError, match="port /dev/ttyNOPE0: cannot open") as info:
        open_port("/dev/ttyNOPE0")
    assert "\n" not in str(info.value)
    # the command line: one line on stderr naming the port, exit 3 (link), no log left
    traj = gentle_trajectory(tmp_path / "t.yaml")
    log = tmp_path / "run.csv"
    proc = subprocess.run(
        [sys.executable, "-m", "guardid", "capture", "--trajectory", str(traj), "--duration",
         "2", "--port", "/dev/ttyNOPE0", "-o", str(log)], capture_output=True, text=True,
    )  # fmt: skip
    err = proc.stderr.strip()
    assert proc.returncode == 3, proc.stderr
    assert err.count("\n") == 0 and err.startswith("guardid: error: port /dev/ttyNOPE0"), err
    assert not log.exists()
    env = dict(os.environ)
    proc = subprocess.run(
        [sys.executable, "-m", "guardid", "ports"], capture_output=True, text=True, env=env
    )
    assert proc.returncode == 0 and "sim://guard" in proc.stdout
