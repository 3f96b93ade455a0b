"""``guardid fake-port``: serve the emulated robot on a pseudo-terminal.

The command lives in :mod:`guardid.fakeport.cli` so that it also runs as
``python -m guardid.fakeport.cli`` without the rest of the CLI.
"""

from guardid.fakeport.cli import fake_port

__all__ = ["fake_port"]
