"""Waiting for a port that vanished (a bumped USB cable) to come back."""

from __future__ import annotations

import time

from guardid.errors import GuardidError
from guardid.link.port import open_port

POLL_S = 0.2  #: between two attempts to open a device that is gone [s]


def wait_for_port(port, url: str, baud: int, within_s: float, poll_s: float = POLL_S, check=None):
    """The port to ``url`` again once it is back, within ``within_s`` [s]; None if not.

    A ``sim://`` port (it has ``wait_link``) is the same object, its link back (the
    simulated robot ran on meanwhile: simulated time in lock-step); a device is closed and
    opened again every ``poll_s`` [s] until it opens or the time is up. ``check`` (if
    given) is called before every attempt (a stop request raises there)."""
    if hasattr(type(port), "wait_link"):
        return port if port.wait_link(within_s) else None
    try:
        port.close()
    except OSError:
        pass
    deadline = time.monotonic() + within_s
    while True:
        if check is not None:
            check()
        try:
            return open_port(url, baud)
        except GuardidError:
            pass
        if time.monotonic() >= deadline:
            return None
        time.sleep(min(poll_s, max(deadline - time.monotonic(), 0.0)))
