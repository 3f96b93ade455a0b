"""How closely a real-time ``sim://`` port follows the wall clock (timings moved out of tests).

Run: python bench/bench_pacing.py [runs]   (default 5). For ``pacing=realtime`` and
``pacing=20`` it streams 40 ticks (0.6 s simulated) of the EchoDevice and prints, per
pacing, the ratio simulated time / wall time from the write to the 40th frame (1.0 for
real time, 20 for the factor) as median and worst over the runs.
"""

from __future__ import annotations

import statistics
import sys
import time

import serial

import guardid.fakeport as fp

TICKS = 40


def one_run(pacing: str) -> float:
    """Simulated seconds per wall second to receive TICKS frames."""
    port = serial.serial_for_url(f"sim://guard?pacing={pacing}", timeout=30.0)
    try:
        start = time.monotonic()
        port.write(b"START")
        data = port.read(5 + TICKS * fp.EchoDevice.FRAME_LEN)
        wall = time.monotonic() - start
        if len(data) != 5 + TICKS * fp.EchoDevice.FRAME_LEN:
            raise SystemExit(f"pacing={pacing}: only {len(data)} bytes in 30 s")
        return TICKS * 0.015 / wall
    finally:
        port.close()


def main(runs: int = 5) -> None:
    old = fp.register_device_factory(lambda robot, options: fp.EchoDevice())
    try:
        print("pacing     expected  median  worst   (simulated s per wall s)")
        for pacing, expected in (("realtime", 1.0), ("20", 20.0)):
            ratios = [one_run(pacing) for _ in range(runs)]
            worst = max(ratios, key=lambda r: abs(r - expected))
            print(f"{pacing:10s} {expected:8.1f} {statistics.median(ratios):7.2f} {worst:6.2f}")
    finally:
        fp.register_device_factory(old)


if __name__ == "__main__":
    main(int(sys.argv[1]) if len(sys.argv) > 1 else 5)
