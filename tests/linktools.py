"""Test helpers for runs through sim://: a simple trajectory, and the bytes on both sides
of a faulty link."""

from __future__ import annotations

from contextlib import contextmanager

import numpy as np

from guardid.fakeport import register_device_factory
from guardid.firmware import make_sim_device


class Sines:
    """A minimal trajectory: q_j(t) = c_j + a_j sin(2 pi f_j t), ramped in over 2 s."""

    period = 10.0

    def positions(self, t):
        t = np.asarray(t, dtype=float)
        ramp = np.minimum(t / 2.0, 1.0)
        return np.column_stack(
            [
                ramp * 0.4 * np.sin(2 * np.pi * 0.1 * t),
                0.15 + ramp * 0.1 * np.sin(2 * np.pi * 0.2 * t),
            ]
        )

    def to_dict(self):
        return {"kind": "test-sines"}


class Recorder:
    """A port proxy that keeps every byte the host read."""

    def __init__(self, port) -> None:
        self._port = port
        self.received = bytearray()

    def read(self, size: int = 1) -> bytes:
        data = self._port.read(size)
        self.received += data
        return data

    def __getattr__(self, name):
        return getattr(self._port, name)


class BothWays(Recorder):
    """A port proxy that keeps every byte the host read and every byte it wrote."""

    def __init__(self, port) -> None:
        super().__init__(port)
        self.sent = bytearray()

    def write(self, data) -> int:
        self.sent += data
        return self._port.write(data)


class Tee:
    """Wraps a device to keep the clean bytes it sent (before the link's faults)."""

    def __init__(self, device) -> None:
        self.device = device
        self.sent = bytearray()
        self.tick_period_s = device.tick_period_s

    def take_output(self) -> bytes:
        out = self.device.take_output()
        self.sent += out
        return out

    def __getattr__(self, name):
        return getattr(self.device, name)


def expected_damage(clean: bytes, delivered: bytes) -> tuple[int, list[bytes]]:
    """Independent count of the damage: (segments that are not clean frames, lost frames).

    Frames are 0x00-delimited and carry a CRC-32, so every delivered segment that is not
    byte-identical to a frame that was sent is exactly one rejected segment, and every
    sent frame missing from the delivered ones is lost.
    """
    clean_frames = [s for s in clean.split(b"\x00") if s]
    got = [s for s in delivered.split(b"\x00") if s]
    clean_set, got_set = set(clean_frames), set(got)
    errors = sum(1 for s in got if s not in clean_set)
    lost = [s for s in clean_frames if s not in got_set]
    return errors, lost


@contextmanager
def teed_devices():
    """While active, sim:// ports get the firmware emulator wrapped in a :class:`Tee`;
    yields the list of those tees (one per port opened)."""
    tees: list[Tee] = []

    def factory(robot, options):
        tees.append(Tee(make_sim_device(robot, options)))
        return tees[-1]

    old = register_device_factory(factory)
    try:
        yield tees
    finally:
        register_device_factory(old)
