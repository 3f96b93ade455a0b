"""``guardid fake-port`` over a pseudo-terminal gives the same bytes as sim:// lock-step."""

import os
import signal
import subprocess
import sys

import pytest
import serial

import guardid.fakeport as fp

N = fp.EchoDevice.FRAME_LEN


def _command():
    """The documented command, ``guardid fake-port``: no fallback to the module, so a
    broken or missing subcommand fails these tests."""
    return [sys.executable, "-m", "guardid", "fake-port"]


def _ping_pong(port, frames=30):
    """Host that answers each telemetry frame; returns everything it read."""
    port.write(b"START")
    got = [port.read(5)]
    for i in range(frames):
        got.append(port.read(N))
        port.write(b"ok%d" % (i % 10))
        got.append(port.read(3))
    return got


def _listener(port, frames=10):
    """Host that never answers after START."""
    port.write(b"START")
    return [port.read(5)] + [port.read(N) for _ in range(frames)]


@pytest.fixture
def server():
    procs = []

    def start(*args, sig=signal.SIGINT):
        env = dict(os.environ, GUARDID_FAKEPORT_DEVICE="echo")
        proc = subprocess.Popen(
            _command() + ["--seed", "1", *args], stdout=subprocess.PIPE, env=env, text=True
        )
        procs.append((proc, sig))
        path = proc.stdout.readline().strip()
        assert path.startswith("/dev/"), path
        return path

    yield start
    for proc, sig in procs:
        proc.send_signal(sig)
        assert proc.wait(timeout=60) == 0  # a generous bound, ended by the exit
        proc.stdout.close()


def _sim(script, query=""):
    os.environ.pop(fp.factory.DEVICE_ENV, None)
    old = fp.register_device_factory(lambda robot, options: fp.EchoDevice())
    try:
        port = serial.serial_for_url(f"sim://guard?seed=1{query}", timeout=1.0)
        out = script(port)
        port.close()
    finally:
        fp.register_device_factory(old)
    return out


def test_pty_ping_pong_matches_sim_lockstep(server):
    # the host answers every frame, so no timing-based fallback: deterministic under load
    path = server("--idle-ms", "0")
    with serial.Serial(path, timeout=10) as port:
        over_pty = _ping_pong(port)
    expected = _sim(_ping_pong)
    assert expected[1] == fp.EchoDevice.frame(1, 0)
    assert over_pty == expected


def test_pty_listener_with_idle_fallback(server):
    path = server("--idle-ms", "5", sig=signal.SIGTERM)
    with serial.Serial(path, timeout=10) as port:
        over_pty = _listener(port)
    assert over_pty == _sim(_listener)


def test_pty_rejects_bad_option():
    env = dict(os.environ, GUARDID_FAKEPORT_DEVICE="echo")
    result = subprocess.run(
        _command() + ["--drop", "2"], capture_output=True, text=True, env=env, timeout=30
    )
    assert result.returncode != 0 and "--drop" in result.stderr
    assert "Traceback" not in result.stderr
