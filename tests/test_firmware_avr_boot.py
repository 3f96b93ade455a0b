"""The Arduino boot loaders in simavr before the AVR port (firmware=avr&bootloader=...), the
host's DTR reset, and capture's reset on open (guardid.link.board).

Needs the AVR toolchain, simavr and Debian's arduino-core-avr (the boot loader images):
skipped with the reason when they are missing, except under CI (CI=true).
"""

from __future__ import annotations

import os

import pytest

from guardid.firmware.avr_sim.build import BOOTLOADERS, missing_toolchain

MISSING = missing_toolchain() + [
    f"arduino-core-avr ({path})" for _, path in BOOTLOADERS.values() if not path.is_file()
]
NEEDS_BOOT = pytest.mark.skipif(
    bool(MISSING) and os.environ.get("CI") != "true",
    reason=f"needs {', '.join(MISSING)} (apt-get install gcc-avr avr-libc binutils-avr "
    "simavr libsimavr-dev arduino-core-avr)",
)
TICK_S = 0.015


def _boot_s(device) -> float:
    """Simulated seconds [s] until the firmware's first tick (device.advance per tick)."""
    n = 0
    while device.booting:
        device.advance()
        n += 1
    return n * TICK_S


@NEEDS_BOOT
def test_optiboot_listens_then_its_watchdog_starts_the_firmware_and_dtr_resets_again():
    """optiboot.c (Debian's build, LED_START_FLASHES=3): 3 LED flashes of 2 x 1/16 s on
    Timer1, then a 1 s watchdog timeout for a programmer, then a watchdog reset into the
    application: the firmware's INFO comes 0.375 + 1.0 s + its own set-up (< 0.05 s) after
    the reset, not at once; an external reset (DTR) runs the boot loader again."""
    from guardid.fakeport.options import parse_sim_url
    from guardid.firmware.avr_sim.device import make_sim_device_avr

    dev = make_sim_device_avr(
        "guard", parse_sim_url("sim://guard?firmware=avr&bootloader=optiboot")
    )
    try:
        assert dev.mcu == "atmega328p" and dev.booting
        first = _boot_s(dev)
        info = dev.take_output()
        assert 1.375 <= first <= 1.375 + 0.05 + 2 * TICK_S, first
        assert info[:1] == b"\x03" and dev.stats()["resets"] == 1  # the watchdog's
        dev.reset()
        assert dev.take_output() == b""
        again = _boot_s(dev)
        assert again == pytest.approx(first) and dev.take_output()[:1] == b"\x03"
        assert dev.stats()["resets"] == 3  # DTR, then the watchdog again
    finally:
        dev.close()


@NEEDS_BOOT
def test_the_mega_boot_loader_waits_before_the_firmware_on_the_atmega2560():
    from guardid.fakeport.options import parse_sim_url
    from guardid.firmware.avr_sim.device import make_sim_device_avr

    dev = make_sim_device_avr(
        "guard", parse_sim_url("sim://guard?firmware=avr&bootloader=stk500v2")
    )
    try:
        assert dev.mcu == "atmega2560"
        # stk500boot.c leaves for the application after its boot_timeout loop without a
        # byte (no watchdog reset): well after the firmware's own 31 ms set-up
        assert _boot_s(dev) > 0.5 and dev.stats()["resets"] == 0
    finally:
        dev.close()


@NEEDS_BOOT
@pytest.mark.parametrize("reset", [True, False])
def test_connect_resets_the_board_and_waits_for_its_firmware_or_not(reset):
    """connect(): a DTR pulse and a silent wait (one more reset than the boot's, no HELLO
    lost to the boot loader); --no-reset: no pulse, HELLO at once goes to optiboot, which
    takes it for a bad command and starts the firmware (16 ms watchdog): INFO all the same."""
    from guardid.link import Session, open_port
    from guardid.link.board import connect

    url = "sim://guard?firmware=avr&bootloader=optiboot&noise=0"
    port = open_port(url, timeout_s=0.1, reset=reset)
    try:
        session = Session(port, timeout_s=1.0)
        info = connect(session, url, reset=reset)
        device = port.engine.device
        assert info["firmware_id"] == 0x47554331  # "GUC1"
        # built in reset (EXTRF), then DTR (with reset) and optiboot's watchdog
        assert device.stats()["resets"] == (2 if reset else 1)
        assert port.sim_time_s > 1.375  # optiboot's wait passed either way
    finally:
        port.close()


@NEEDS_BOOT
def test_a_capture_through_the_boot_loader_gets_the_bytes_of_one_without(tmp_path):
    """The reset on open costs boot time only: 2 s through optiboot, row for row the
    capture of firmware=avr without a boot loader (noise off: the ADC's conversions fall on
    the same ticks; see docs/REAL_ROBOT.md for the noise-on case)."""
    from capturetools import gentle_trajectory
    from click.testing import CliRunner

    from guardid.cli import main as cli

    runner = CliRunner()
    traj = gentle_trajectory(tmp_path / "t.yaml")
    rows = {}
    for name, extra in (("plain", ""), ("boot", "&bootloader=optiboot")):
        log = tmp_path / f"{name}.csv"
        res = runner.invoke(cli, ["capture", "--trajectory", str(traj), "--duration", "2",
                                  "--port", f"sim://guard?firmware=avr&noise=0&seed=5{extra}",
                                  "--quiet", "-o", str(log)])  # fmt: skip
        assert res.exit_code == 0, res.output
        rows[name] = [ln for ln in log.read_text().splitlines() if not ln.startswith("#")]
    assert len(rows["boot"]) == round(2 / TICK_S) + 1
    assert rows["boot"] == rows["plain"]


def test_bootloader_option_checks():
    from guardid.fakeport.options import SimUrlError, parse_sim_url
    from guardid.link.board import resets_on_open

    assert parse_sim_url("sim://guard?firmware=avr&bootloader=stk500v2").mcu == "atmega2560"
    for bad in ("bootloader=optiboot", "firmware=avr&bootloader=caterina",
                "firmware=avr&mcu=atmega2560&bootloader=optiboot"):  # fmt: skip
        with pytest.raises(SimUrlError, match="bootloader"):
            parse_sim_url(f"sim://guard?{bad}")
    assert resets_on_open("/dev/ttyACM0")
    assert resets_on_open("sim://guard?firmware=avr&bootloader=optiboot")
    assert not resets_on_open("sim://guard?firmware=avr")
    assert not resets_on_open("socket://localhost:7777")


def test_ci_must_not_skip_the_boot_loader_tests():
    if os.environ.get("CI") == "true":
        assert MISSING == [], f"CI without: {MISSING}"


def test_a_pty_opens_without_reset_and_has_no_dtr_to_pulse():
    """--no-reset on a device path: pyserial opens it with DTR released; a pseudo-terminal
    has no modem lines, so the pulse reports False instead of failing (its server resets)."""
    from guardid.link import open_port
    from guardid.link.board import pulse_dtr

    master, slave = os.openpty()
    try:
        port = open_port(os.ttyname(slave), reset=False)
        assert port.is_open and port.dtr is False
        assert pulse_dtr(port, wall_clock=False) is False
        port.close()
    finally:
        os.close(master)
        os.close(slave)
