"""Helpers of the capture tests: a witness on the simulated robot's side, a trajectory
inside the guard's limits, and a log parser of our own (independent of guardid.log)."""

from __future__ import annotations

import math
import os
from contextlib import contextmanager
from pathlib import Path

import yaml

from guardid.excitation.sines import SumOfSines
from guardid.fakeport import register_device_factory
from guardid.firmware import FirmwareEmulator
from guardid.plant import make_plant
from guardid.protocol import ENUMS, FrameParser
from guardid.robot import load_robot

VARIANT = Path(__file__).resolve().parents[1] / "bench" / "robots" / "guard_variant.yaml"
"""A robot no default was tuned on (the guard's kinematics, other PID period, drives,
encoders, friction and masses; its header says what differs)."""
THIRD = VARIANT.parent / "guard_third.yaml"
"""A third robot nobody tuned on (PID every 20 ms, a 12-bit current ADC finer than the
telemetry's whole mA, a friction offset on the pan; its header says what differs)."""
IDLE = ENUMS["mode"]["idle"]
POSITION = ENUMS["mode"]["position"]


def gentle_trajectory(path: Path) -> Path:
    """A sum of sines well inside guard's limits (worked out by hand below), period 10 s.

    pan: 0.3 sin(2 pi 0.2 t): |qd| <= 0.377 rad/s (limit 0.9), |qdd| <= 0.474 (limit 3);
    tilt: 0.2 + 0.1 sin(2 pi 0.3 t): 0.1..0.3 rad (limit -0.175..0.611),
    |qd| <= 0.188 (limit 0.45), |qdd| <= 0.355 (limit 2).
    """
    SumOfSines([[0.3], [0.1]], [[0.2], [0.3]], [[0.0], [0.0]], [0.0, 0.2]).save(path)
    return path


class Witness:
    """The firmware emulator plus a record, on the robot's side, of the host's commands.

    ``commands``: (name, mode or None, device tick) per host frame, parsed by a parser of
    its own. ``trigger``: ("frame", k) sends ``signum`` to this process when the k-th host
    frame arrives (0 = HELLO), ("tick", k) at the k-th tick after position mode began.
    ``sent_at``: index into ``commands`` when the signal was sent, ``sent_tick`` the
    ticks of motion until then. ``events`` (a list shared
    with the test) gets 'idle' whenever a SET_MODE idle arrives.
    """

    def __init__(self, fw: FirmwareEmulator, trigger=None, signum=None, events=None) -> None:
        self.fw = fw
        self.tick_period_s = fw.tick_period_s
        self.parser = FrameParser()
        self.commands: list[tuple[str, int | None, int]] = []
        self.trigger, self.signum = trigger, signum
        self.sent_at: int | None = None
        self.sent_tick: int | None = None  # ticks of motion when the signal was sent
        self.moving_ticks = 0
        self.events = events if events is not None else []

    def _fire(self) -> None:
        if self.sent_at is None:
            self.sent_at = len(self.commands)
            self.sent_tick = self.moving_ticks
            os.kill(os.getpid(), self.signum)

    def receive(self, data: bytes) -> None:
        for frame in self.parser.feed(data):
            name = frame.msg.SPEC.name
            mode = frame.msg.mode if name == "SET_MODE" else None
            self.commands.append((name, mode, self.fw.tick))
            if name == "SET_MODE" and mode == IDLE:
                self.events.append("idle")
            if self.trigger == ("frame", len(self.commands) - 1):
                self._fire()
        self.fw.receive(data)

    def advance(self) -> None:
        self.fw.advance()
        if self.fw.mode == POSITION:
            self.moving_ticks += 1
            if self.trigger == ("tick", self.moving_ticks):
                self._fire()

    def take_output(self) -> bytes:
        return self.fw.take_output()

    def wants_time(self) -> bool:
        return self.fw.wants_time()

    def close(self) -> None:
        self.fw.close()

    def idled_after_signal(self) -> bool:
        """True when a SET_MODE idle reached the robot after the signal was sent."""
        later = self.commands[self.sent_at :] if self.sent_at is not None else []
        return any(name == "SET_MODE" and mode == IDLE for name, mode, _ in later)


@contextmanager
def witnessed(trigger=None, signum=None, robot_yaml=None, events=None):
    """Make every ``sim://`` port's device a :class:`Witness`; yields the list of them."""
    made: list[Witness] = []

    def factory(robot, options):
        desc = load_robot(robot_yaml or robot)
        made.append(
            Witness(FirmwareEmulator(desc, make_plant(desc, options)), trigger, signum, events)
        )
        return made[-1]

    old = register_device_factory(factory)
    try:
        yield made
    finally:
        register_device_factory(old)


def parse_rows(path: Path, n_fields: int) -> list[list[float]]:
    """The complete data rows of a log file: lines ending in a newline, not comments,
    after the column-name line, with ``n_fields`` numeric fields (a cut last line is
    left out). Written here, not taken from guardid.log, to check the writer."""
    text = Path(path).read_bytes().decode("utf-8", errors="replace")
    lines = text.split("\n")[:-1]  # the part after the last newline is not complete
    rows = []
    for line in lines[1:]:
        if not line or line.startswith("#"):
            continue
        parts = line.split(",")
        assert len(parts) == n_fields, f"{path}: a complete line with {len(parts)} fields"
        rows.append([float(x) for x in parts])
    return rows


def footer_lines(path: Path) -> list[str]:
    """The commented lines after the last data row (the footer, if any)."""
    lines = Path(path).read_text().splitlines()
    tail = []
    for line in reversed(lines):
        if not line.startswith("#"):
            break
        tail.append(line)
    return tail[::-1] if any(x.startswith("# footer:") for x in tail) else []


def footer_dict(path: Path) -> dict:
    """The footer mapping (YAML in the commented lines after the rows), or {}."""
    lines = footer_lines(path)
    return yaml.safe_load("\n".join(x[2:] for x in lines))["footer"] if lines else {}


def log_fields(n_joints: int = 2) -> int:
    """Fields per row: tick, time, 5 per-joint groups, status."""
    return 2 + 5 * n_joints + 1


DEG = math.pi / 180
