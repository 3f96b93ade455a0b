"""Lock-step HIL speed with the C firmware core in the loop vs the Python emulator.

Host session -> sim:// port -> firmware (firmware=py: Python emulator; firmware=c: the
portable C core via ctypes) -> simulated guard plant, closed loop on sums of sines; also
checks that both firmwares sent the same bytes.
Run: python bench/bench_firmware_c.py [seconds of robot time, default 300]
"""

from __future__ import annotations

import sys
import time

import numpy as np
from bench_hil import sines_setpoints

from guardid.firmware.c_core import build_library
from guardid.link import Session, open_port


class Recorder:
    """Port proxy keeping every byte the host read."""

    def __init__(self, port) -> None:
        self._port = port
        self.received = bytearray()

    def read(self, size: int = 1) -> bytes:
        data = self._port.read(size)
        self.received += data
        return data

    def __getattr__(self, name):
        return getattr(self._port, name)


def run(firmware: str, rows: np.ndarray) -> tuple[float, bytes]:
    port = Recorder(open_port(f"sim://guard?seed=1&firmware={firmware}"))
    session = Session(port)
    start = time.perf_counter()
    session.handshake()
    for _ in session.track(rows):
        pass
    session.finish()
    wall = time.perf_counter() - start
    port.close()
    return wall, bytes(port.received)


def main(robot_seconds: float = 300.0) -> None:
    rows = sines_setpoints(robot_seconds)
    n = len(rows)
    start = time.perf_counter()
    lib = build_library()
    print(f"C core library: {lib} ({time.perf_counter() - start:.2f} s to build or find)")
    results = {fw: run(fw, rows) for fw in ("py", "c")}
    for fw, (wall, _) in results.items():
        speed = robot_seconds / wall
        per_tick = wall / n * 1e6
        print(f"firmware={fw}: wall {wall:.2f} s, {speed:.0f}x real time, {per_tick:.1f} us/tick")
    same = results["py"][1] == results["c"][1]
    print(f"identical bytes: {same} ({len(results['c'][1])} bytes)")


if __name__ == "__main__":
    main(float(sys.argv[1]) if len(sys.argv) > 1 else 300.0)
