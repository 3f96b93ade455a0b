"""The pty server's lock-step fallback after a boot: a host silent through the boot gets
``idle_s`` from the firmware's first tick to answer, so no tick runs behind its back."""

from __future__ import annotations

import os
import select
import threading
import time

from guardid.fakeport.engine import LinkEngine
from guardid.fakeport.faults import FaultConfig
from guardid.fakeport.pty_server import PtyServer

BOOT_TICKS = 40  # 0.6 s of wall clock at 15 ms: longer than the fallback's 0.3 s


class BootingBoard:
    """A board that boots for BOOT_TICKS ticks after each reset, then says b"INFO\\n" and
    runs its plant; it records the plant tick at which each host byte arrived."""

    tick_period_s = 0.015

    def __init__(self) -> None:
        self.booting, self.boot_left, self.plant_ticks = True, BOOT_TICKS, 0
        self.heard: list[tuple[int, bytes]] = []
        self._out = bytearray()

    def reset(self, power_cycle: bool = False) -> None:
        self.booting, self.boot_left, self.plant_ticks = True, BOOT_TICKS, 0
        self._out.clear()

    def receive(self, data: bytes) -> None:
        if not self.booting:
            self.heard.append((self.plant_ticks, bytes(data)))

    def advance(self) -> None:
        if self.booting:
            self.boot_left -= 1
            if self.boot_left == 0:
                self.booting = False
                self._out += b"INFO\n"
            return
        self.plant_ticks += 1  # silent until the host asks

    def take_output(self) -> bytes:
        out, self._out = bytes(self._out), bytearray()
        return out

    def wants_time(self) -> bool:
        return True

    def close(self) -> None:
        pass


def _read_until(fd: int, marker: bytes, limit_s: float = 10.0) -> bytes:
    got, deadline = b"", time.monotonic() + limit_s
    while marker not in got and time.monotonic() < deadline:
        if select.select([fd], [], [], 0.05)[0]:
            got += os.read(fd, 100)
    return got


def test_a_host_silent_through_the_boot_answers_before_any_tick():
    board = BootingBoard()
    server = PtyServer(LinkEngine(board, FaultConfig(), 0), None, idle_s=0.3)
    stop = threading.Event()
    thread = threading.Thread(target=server.serve, args=(stop.is_set,), daemon=True)
    thread.start()
    try:
        fd = os.open(server.path, os.O_RDWR | os.O_NOCTTY)  # the open resets the board
        try:
            assert _read_until(fd, b"INFO\n").endswith(b"INFO\n")
            time.sleep(0.02)  # the host's own work before it answers (under the 0.3 s)
            os.write(fd, b"PING")
            deadline = time.monotonic() + 10.0
            while not board.heard and time.monotonic() < deadline:
                time.sleep(0.01)
        finally:
            os.close(fd)
    finally:
        stop.set()
        thread.join(timeout=10)
        server.close()
    assert server.resets == 1
    assert board.heard[:1] == [(0, b"PING")]  # no plant tick ran before the host's answer
