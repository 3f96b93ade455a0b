"""sim:// URL grammar, validation and registration with pyserial."""

import os
import subprocess
import sys
import textwrap

import pytest
import serial

import guardid.fakeport as fp
from guardid.errors import GuardidError


def test_defaults():
    opts = fp.parse_sim_url("sim://guard")
    assert opts.robot == "guard" and opts.seed == 0 and opts.lockstep
    assert opts.faults == fp.FaultConfig()
    assert fp.parse_sim_url("sim://").robot == "guard"


def test_all_options():
    opts = fp.parse_sim_url(
        "sim://robots/my.yaml?seed=7&pacing=10&noise=0&payload_time=30&payload_mass=1.0"
        "&payload_com=0.12,0.02,0&drop=1e-4&flip=1e-5&latency_ms=16&disconnect_s=40"
        "&firmware=c&upstream=1"
    )
    assert opts.robot == "robots/my.yaml"
    assert (opts.seed, opts.pacing, opts.noise, opts.firmware) == (7, 10.0, False, "c")
    assert (opts.payload_time, opts.payload_mass) == (30.0, 1.0)
    assert opts.payload_com == (0.12, 0.02, 0.0)
    f = opts.faults
    assert (f.drop, f.flip, f.latency_s, f.disconnect_s, f.upstream) == (
        1e-4,
        1e-5,
        0.016,
        40.0,
        True,
    )
    assert fp.parse_sim_url("sim:///abs/path.yaml?pacing=realtime").robot == "/abs/path.yaml"
    assert fp.parse_sim_url("sim://g?pacing=realtime").pacing == 1.0


@pytest.mark.parametrize(
    "query, option",
    [
        ("bogus=1", "bogus"),
        ("seed=-1", "seed"),
        ("seed=x", "seed"),
        ("pacing=fast", "pacing"),
        ("pacing=0", "pacing"),
        ("noise=2", "noise"),
        ("drop=1.5", "drop"),
        ("flip=-0.1", "flip"),
        ("latency_ms=nan", "latency_ms"),
        ("disconnect_s=0", "disconnect_s"),
        ("payload_com=1,2", "payload_com"),
        ("payload_mass=-1", "payload_mass"),
        ("firmware=rust", "firmware"),
        ("seed=1&seed=2", "seed"),
    ],
)
def test_bad_option_names_the_option(query, option):
    with pytest.raises(fp.SimUrlError, match=option) as info:
        fp.parse_sim_url(f"sim://guard?{query}")
    assert isinstance(info.value, ValueError) and isinstance(info.value, GuardidError)
    assert "\n" not in str(info.value)


def test_serial_for_url_validates_and_defaults_to_the_emulator(monkeypatch):
    monkeypatch.delenv(fp.factory.DEVICE_ENV, raising=False)
    assert "guardid.fakeport" in serial.protocol_handler_packages
    with pytest.raises(ValueError, match="latency_ms"):
        serial.serial_for_url("sim://guard?latency_ms=-3")
    old = fp.register_device_factory(None)
    try:
        port = serial.serial_for_url("sim://guard?seed=1")
        assert type(port.engine.device).__name__ == "FirmwareEmulator"
        port.close()
        # firmware=c: the C core in the loop (tests/test_firmware_c.py), or a one-line
        # error naming the option when no C compiler is installed
        try:
            port = serial.serial_for_url("sim://guard?firmware=c")
        except ValueError as exc:
            assert "firmware=c" in str(exc) and "\n" not in str(exc)
        else:
            assert type(port.engine.device).__name__ == "CFirmware"
            port.close()
    finally:
        fp.register_device_factory(old)


def test_factory_receives_robot_and_options(monkeypatch):
    monkeypatch.delenv(fp.factory.DEVICE_ENV, raising=False)
    seen = []

    def factory(robot, options):
        seen.append((robot, options))
        return fp.EchoDevice()

    old = fp.register_device_factory(factory)
    try:
        port = serial.serial_for_url("sim://planar2?seed=3&payload_mass=2")
        port.close()
    finally:
        fp.register_device_factory(old)
    assert seen[0][0] == "planar2" and seen[0][1].seed == 3 and seen[0][1].payload_mass == 2.0


def test_named_device_from_environment(monkeypatch):
    monkeypatch.setenv(fp.factory.DEVICE_ENV, "echo")
    port = serial.serial_for_url("sim://guard")
    assert isinstance(port.engine.device, fp.EchoDevice)
    port.close()
    assert port.engine.device.closed and not port.is_open
    monkeypatch.setenv(fp.factory.DEVICE_ENV, "nope")
    with pytest.raises(fp.SimUrlError, match="nope"):
        serial.serial_for_url("sim://guard")


def test_import_guardid_alone_registers_sim_urls():
    """In a fresh interpreter, ``import guardid`` (and nothing else from guardid) is enough
    for ``serial.serial_for_url("sim://guard")``; importing guardid loads neither numpy nor
    scipy nor the fake port (pyserial imports that when the URL is opened). The port is the
    emulated robot: a lock-step read of 0.1 s advances its clock by exactly 0.1 s."""
    code = textwrap.dedent(
        """
        import sys
        import guardid
        import serial
        heavy = sorted(m for m in ("numpy", "scipy", "guardid.fakeport") if m in sys.modules)
        assert not heavy, heavy
        port = serial.serial_for_url("sim://guard?seed=1", timeout=0.1)
        assert type(port).__module__ == "guardid.fakeport.protocol_sim", type(port)
        assert port.read(1) == b"" and port.sim_time_s == 0.1
        assert type(port.engine.device).__name__ == "FirmwareEmulator"
        port.close()
        print("ok")
        """
    )
    env = {k: v for k, v in os.environ.items() if k != fp.factory.DEVICE_ENV}
    res = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env,
                         timeout=300)  # fmt: skip
    assert res.returncode == 0 and res.stdout == "ok\n", res.stderr
