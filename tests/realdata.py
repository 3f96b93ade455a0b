"""Where the real measured data the tests use live: ``tests/data/`` (in the repository, so
that nothing skips on a fresh clone; licence and provenance in ``tests/data/README.md``)."""

from pathlib import Path

# DFKI double pendulum, design A.0, sys_id runs 00-02 and the lab's published parameters
DFKI = Path(__file__).resolve().parent / "data" / "dfki-double-pendulum"
