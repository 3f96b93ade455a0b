"""guardid flash: the firmware built for the robot, written through the real Arduino boot
loaders (Debian's arduino-core-avr) by avrdude into simavr behind a pty, then a capture on
the same pty.

Slow by nature (avrdude's own sync delays, an 18 kB image at 115200 baud, the boot loaders'
real-time wait): one flash per boot loader. Needs avrdude and what firmware=avr needs;
skipped with the reason when missing, except under CI (CI=true).
"""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
import threading

import numpy as np
import pytest
from capturetools import gentle_trajectory
from click.testing import CliRunner

from guardid.cli import main as cli
from guardid.firmware.avr_sim.build import BOOTLOADERS, missing_toolchain, read_ihex
from guardid.flash import BOARDS
from guardid.flash.avrdude import AvrdudeError, explain
from guardid.link import board
from guardid.link.session import RetryPolicy

MISSING = missing_toolchain() + [
    f"arduino-core-avr ({path})" for _, path in BOOTLOADERS.values() if not path.is_file()
]
if shutil.which("avrdude") is None:
    MISSING.append("avrdude")
NEEDS_FLASH = pytest.mark.skipif(
    bool(MISSING) and os.environ.get("CI") != "true",
    reason=f"needs {', '.join(MISSING)} (apt-get install avrdude arduino-core-avr gcc-avr "
    "avr-libc binutils-avr simavr libsimavr-dev)",
)


@pytest.fixture
def patient_boot(monkeypatch):
    """The simulated MCU boots on the wall clock (its boot loader's wait is real time, as on
    a board), but simavr, on a host starved of CPU, runs slower than the wall clock: its
    firmware answers later than a board's would. A boot loader takes a byte it receives for
    the start of a command and listens on, so HELLOs resent every second (in wall-clock time)
    can keep a slowed boot loader listening for good: 32 resends 1 s apart (30.75 s) went
    unanswered in a CI run beside two CPU-bound processes. Here the resends after a reset
    back off to 5 s apart (0.25, 0.5, 1, 2, 4, then 5 s; about 48 s in all, against a board's
    4.75 s, :data:`guardid.link.board.BOOT_RETRY`): the boot loader gets silences long enough
    to time out and start the firmware even when simavr runs five times slower than the
    wall clock. How long the host waits, not what it checks."""
    slow = RetryPolicy(attempts=13, first_wait_s=0.25, backoff=2.0, max_wait_s=5.0)
    monkeypatch.setattr(board, "BOOT_RETRY", slow)


def _rows(path) -> list[str]:
    return [ln for ln in path.read_text().splitlines() if not ln.startswith("#")]


def _same_telemetry(pty_rows: list[str], sim_rows: list[str]) -> None:
    """Row for row: ticks (from the first), time, setpoints and status equal; the motion
    within a few encoder counts of firmware=avr's. Over a pty the host's bytes reach the
    simulated UART at a point of the tick that depends on the wall clock (and on the
    machine's load; the firmware's tick counts from its boot, in wall-clock time), and its
    interrupts
    move an ADC conversion (of ~36 per channel and tick) across a tick's edge now and then: a
    tick's voltage and current means move by a fraction of a conversion's step, and the PID
    (fed those currents only through the motor) may then differ by a count in a few rows
    (docs/REAL_ROBOT.md). With sim:// the boot loader path is byte-identical
    (tests/test_firmware_avr_boot.py)."""
    assert len(pty_rows) == len(sim_rows) and pty_rows[0] == sim_rows[0]
    head = pty_rows[0].split(",")
    exact = [k for k, n in enumerate(head) if n in ("time_s", "status")
             or n.startswith("setpoint")]  # fmt: skip
    counts = [k for k, n in enumerate(head) if n.startswith("counts_")]
    sensors = [k for k, n in enumerate(head) if n.startswith(("v_", "i_"))]
    assert exact and len(counts) == 2 and len(sensors) == 4, head
    a = [r.split(",") for r in pty_rows[1:]]
    b = [r.split(",") for r in sim_rows[1:]]
    assert [[r[k] for k in exact] for r in a] == [[r[k] for k in exact] for r in b]
    tick = head.index("tick")  # the firmware's own count: from when it booted (wall clock)
    ta, tb = (np.array([int(r[tick]) for r in x]) for x in (a, b))
    assert np.array_equal(ta - ta[0], tb - tb[0])
    ca = np.array([[float(r[k]) for k in counts] for r in a])
    cb = np.array([[float(r[k]) for k in counts] for r in b])
    assert np.abs(ca - cb).max() <= 3, np.abs(ca - cb).max(axis=0)
    va = np.array([[float(r[k]) for k in sensors] for r in a])
    vb = np.array([[float(r[k]) for k in sensors] for r in b])
    assert np.sqrt(np.mean((va - vb) ** 2, axis=0)).max() < 0.1


def _capture(runner, port, traj, seconds, out):
    res = runner.invoke(cli, ["capture", "--trajectory", str(traj), "--duration", str(seconds),
                              "--port", port, "--quiet", "-o", str(out)])  # fmt: skip
    assert res.exit_code == 0, res.output
    return _rows(out)


def _capture_like(runner, port, traj, seconds, tmp_path, sim_rows, attempts=3):
    """A capture on the pty that starts at sim_rows' tick from the firmware's boot (rows,
    log path): the comparison needs the same start (the idle tilt falls ~12 counts a tick).
    The pty's lock-step rule guesses from the wall clock when the host has finished a turn
    (SETTLE_S, IDLE_S); a host starved of CPU can still make it guess wrong once before the
    stream starts, and that capture is taken again (at most ``attempts``, each a new file)."""
    for k in range(attempts):
        out = tmp_path / f"pty{k}.csv"
        rows = _capture(runner, port, traj, seconds, out)
        if rows[1].split(",")[0] == sim_rows[1].split(",")[0]:
            break
    assert rows[1].split(",")[0] == sim_rows[1].split(",")[0], (rows[1], sim_rows[1])
    return rows, out


IDLE_S = 0.5
"""[s] the pty's lock-step fallback (``--idle-ms``, 0.1 s by default): it steps the MCU after
this much host silence. Under load a busy host can be silent that long between a reply and
its next command; the step then runs ticks the host's ``sim://`` twin does not see (its
reads advance the clock only when short of data), and the pty capture starts later, the
tilt further down (a 0.25 s delay injected before the host's 3rd or 6th write did that at
0.1 s, not at 0.5 s). Half the host's telemetry timeout (1 s) keeps the stream alive where
the host does wait (the trajectory's last rows)."""

SETTLE_S = 0.02
"""[s] the pty's settle time (``--settle-ms``, 2 ms by default): the server steps once the
host has written and then stayed silent this long. After a reset the host sends HELLO, takes
the INFO the firmware sent at its start as the answer, and writes its next command without
waiting; a host descheduled for more than the settle time between the two (under load) saw
a step between them that ``sim://`` does not make, and the capture started a tick later
(tilt 16-18 counts lower in the first rows; seen in 5 of 14 runs beside two busy loops and
four other jobs at 2 ms)."""


def _serve(raw: dict):
    """A simulated board behind a pty, served in-process (what ``guardid fake-port`` does),
    so that the test can read its flash; yields (server, device)."""
    from guardid.fakeport.engine import LinkEngine
    from guardid.fakeport.factory import make_device
    from guardid.fakeport.options import parse_options
    from guardid.fakeport.pty_server import PtyServer

    options = parse_options("guard", raw)
    device = make_device("guard", options)
    server = PtyServer(
        LinkEngine(device, options.faults, options.seed), None, idle_s=IDLE_S, settle_s=SETTLE_S
    )
    stop = threading.Event()
    thread = threading.Thread(target=server.serve, args=(stop.is_set,), daemon=True)
    thread.start()
    try:
        yield server, device
    finally:
        stop.set()
        thread.join(timeout=10)
        server.close()
        device.close()


@pytest.fixture
def optiboot_pty():
    """``guardid fake-port --firmware avr --bootloader optiboot --no-noise --seed 7``."""
    yield from _serve({"firmware": "avr", "bootloader": "optiboot", "noise": "0", "seed": "7"})


@NEEDS_FLASH
def test_flash_through_optiboot_then_a_capture_on_the_same_pty(
    optiboot_pty, tmp_path, patient_boot
):
    """avrdude writes and verifies, the simulated flash holds the image avr-objcopy made
    of the ELF, INFO reports the build's id, and a 1 s capture on the pty follows firmware=avr's
    row for row."""
    server, device = optiboot_pty
    runner = CliRunner()
    traj = gentle_trajectory(tmp_path / "t.yaml")
    sim = "sim://guard?firmware=avr&noise=0&seed=7"
    sim_rows = _capture(
        runner, sim, traj, 1, tmp_path / "sim.csv"
    )  # first: its imports done before the pty's open
    res = runner.invoke(cli, ["flash", "--port", server.path, "--board", "uno"])
    assert res.exit_code == 0, res.output
    from guardid.flash import build_for_robot
    from guardid.robot import load_robot

    build = build_for_robot(load_robot("guard"), "atmega328p")
    assert f"firmware id {build.firmware_id:#010x}, the new build runs" in res.output
    base, image = read_ihex(build.hex)
    assert base == 0 and device.read_flash(0, len(image)) == image
    pty_rows, out = _capture_like(runner, server.path, traj, 1, tmp_path, sim_rows)
    header = out.read_text()
    assert f"firmware_id: {build.firmware_id}" in header
    assert len(pty_rows) == round(1 / 0.015) + 1
    _same_telemetry(pty_rows, sim_rows)


@NEEDS_FLASH
def test_fake_port_cli_stk500v2_flash_then_capture(tmp_path, patient_boot):
    """guardid fake-port --firmware avr --bootloader stk500v2: flash --board mega, then a
    short capture on the same pty, row for row that of firmware=avr on the ATmega2560."""
    runner = CliRunner()
    traj = gentle_trajectory(tmp_path / "t.yaml")
    sim = "sim://guard?firmware=avr&mcu=atmega2560&noise=0&seed=2"
    sim_rows = _capture(
        runner, sim, traj, 1, tmp_path / "sim.csv"
    )  # first: its imports done before the pty's open
    env = dict(os.environ)
    env.pop("GUARDID_FAKEPORT_DEVICE", None)
    cmd = [sys.executable, "-m", "guardid", "fake-port", "--firmware", "avr", "--bootloader",
           "stk500v2", "--no-noise", "--seed", "2", "--idle-ms", str(IDLE_S * 1000),
           "--settle-ms", str(SETTLE_S * 1000)]  # fmt: skip
    proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            env=env)  # fmt: skip
    try:
        path = proc.stdout.readline().strip()
        assert path.startswith("/dev/"), proc.stderr.read()
        res = runner.invoke(cli, ["flash", "--port", path, "--board", "mega"])
        assert res.exit_code == 0, res.output
        assert "through stk500v2" in res.output and "the new build runs" in res.output
        pty_rows, _ = _capture_like(runner, path, traj, 1, tmp_path, sim_rows)
    finally:
        proc.terminate()
        proc.wait(timeout=20)
    _same_telemetry(pty_rows, sim_rows)


def test_flash_without_avrdude_says_so_in_one_line():
    res = CliRunner().invoke(
        cli, ["flash", "--port", "/dev/null", "--avrdude", "/nonexistent/avrdude"]
    )
    assert res.exit_code == 2
    assert res.output == (
        "guardid: error: /nonexistent/avrdude: not found; install it (apt-get install avrdude)\n"
    )


# avrdude 7.1's own words, recorded against the optiboot pty: -p m168 (another chip), and
# -U flash:v: with another image (the read-back differs)
WRONG_CHIP = """avrdude: AVR device initialized and ready to accept instructions
avrdude: device signature = 0x1e950f (probably m328p)
avrdude error: expected signature for ATmega168 is 1E 94 06
        double check chip or use -F to override this check
"""
VERIFY = """avrdude warning: verification mismatch
        device 0x9d != input 0x31 at addr 0x0084 (error)
avrdude error: verification mismatch
"""
NO_SUCH_PORT = "avrdude OS error: cannot open port /dev/ttyACM9: No such file or directory\n"
# a pty served without a boot loader (the firmware ignores STK500 sync bytes)
NO_ANSWER = """avrdude: send: 0 [30]   [20]
avrdude: ser_recv(): programmer is not responding
avrdude stk500_recv() [stk500.c:63] error: programmer is not responding
avrdude error: unable to open programmer arduino on port /dev/pts/3
"""


def test_avrdude_failures_become_one_line_with_their_exit_code():
    uno = BOARDS["uno"]
    err = explain(uno, "/dev/ttyACM0", WRONG_CHIP)
    assert err.exit_code == 2 and "not an ATmega328P (device signature 0x1e950f)" in str(err)
    err = explain(uno, "/dev/ttyACM0", VERIFY)
    assert isinstance(err, AvrdudeError) and err.exit_code == 3 and "verification" in str(err)
    err = explain(uno, "/dev/ttyACM9", NO_SUCH_PORT)
    assert err.exit_code == 3 and "cannot open" in str(err)
    err = explain(uno, "/dev/pts/3", NO_ANSWER)
    assert err.exit_code == 3 and "no answer from the optiboot boot loader" in str(err)
    texts = (WRONG_CHIP, VERIFY, NO_SUCH_PORT, NO_ANSWER)
    assert all("\n" not in str(explain(uno, "p", t)) for t in texts)
