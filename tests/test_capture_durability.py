"""Every row a capture has reported written is in the file when the process is killed
(SIGKILL: no handler, no footer, no flush at exit)."""

from __future__ import annotations

import os
import random
import re
import signal
import subprocess
import sys
import threading
import time

import pytest
from capturetools import footer_lines, gentle_trajectory, log_fields, parse_rows

PERIOD_S = 0.015
GUARD_S = 120.0  # failure guard only: a capture that never reports its rows


class ProgressReader(threading.Thread):
    """Reads the capture's stderr; ``reported`` is the largest 'rows N' seen."""

    def __init__(self, stream) -> None:
        super().__init__(daemon=True)
        self.stream = stream
        self.text = ""
        self.reported = 0

    def run(self) -> None:
        fd = self.stream.fileno()
        while chunk := os.read(fd, 4096):
            self.text += chunk.decode(errors="replace")
            counts = [int(n) for n in re.findall(r"rows\s+(\d+)", self.text)]
            self.reported = max(counts, default=0)


@pytest.mark.parametrize("seed", range(5))
def test_sigkill_keeps_every_reported_row(tmp_path, seed):
    rng = random.Random(seed)
    target = rng.randrange(10, 150)  # rows reported before the kill
    extra_s = rng.uniform(0.0, 0.04)  # then a little more, to land anywhere in a tick
    traj = gentle_trajectory(tmp_path / "traj.yaml")
    log = tmp_path / "run.csv"
    # pacing=2: twice real time, so a progress report (every 0.25 s) covers ~33 rows,
    # about 3.5 kB: a writer that buffered its rows instead of writing each at once
    # would still hold the reported ones when killed
    port = f"sim://guard?seed={seed}&pacing=2"
    cmd = [sys.executable, "-m", "guardid", "capture", "--trajectory", str(traj),
           "--duration", "30", "--port", port, "-o", str(log)]  # fmt: skip
    proc = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    reader = ProgressReader(proc.stderr)
    reader.start()
    deadline = time.monotonic() + GUARD_S
    while reader.reported < target and proc.poll() is None and time.monotonic() < deadline:
        time.sleep(0.005)
    assert proc.poll() is None, reader.text  # still running
    time.sleep(extra_s)
    proc.send_signal(signal.SIGKILL)
    proc.wait()
    reader.join()
    reported = reader.reported
    assert proc.returncode == -signal.SIGKILL
    assert reported >= target, reader.text
    rows = parse_rows(log, log_fields())
    assert len(rows) >= reported, (len(rows), reported)
    ticks = [int(r[0]) for r in rows]
    assert ticks == list(range(ticks[0], ticks[0] + len(rows)))  # clean link: no gaps
    assert [round(r[1] / PERIOD_S) for r in rows] == list(range(len(rows)))
    assert footer_lines(log) == []  # killed: no footer
