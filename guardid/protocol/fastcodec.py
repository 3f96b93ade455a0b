"""The protocol's C codec as a CPython extension for the host's hot paths, when it can be built.

``firmware_proto/host/gp_pyext.c`` (on ``guard_proto.c`` and the generated
``guard_proto_msgs.h``) packs one frame per call and takes the leading valid frames of one
kind out of a chunk, making the Python objects itself: the per-frame COBS, CRC and struct
calls of the Python path in one call; it also runs the firmware emulator's position-mode
tick and TELEMETRY frame (``pid_pwm``, ``telemetry``), its whole position-mode tick, one or
several in a row (``fw_tick``, ``fw_ticks``), and its queueing of SETPOINT frames
(``fw_setpoints``: guardid.firmware.emulator, tests/test_firmware_fast_tick.py). Built
once into the cache by :func:`guardid.native.cached_library`. :func:`module` is None
without a C compiler, without Python's headers, without the sources (an install without
``firmware_proto/``), when it does not compile, cannot be written to the cache or does not
load (a warning says why), with ``GUARDID_NATIVE=0`` or on a Python from
:data:`MAX_PYTHON` on: then :class:`guardid.protocol.FrameParser` and
:meth:`guardid.protocol.Encoder.packer` take their Python path, which gives the same bytes,
frames and counters (tests/test_protocol_fast.py).
"""

from __future__ import annotations

import os
import sys
import warnings
from pathlib import Path
from types import ModuleType

FIRMWARE_DIR = Path(__file__).resolve().parents[2] / "firmware_proto"
SOURCES = ("host/gp_pyext.c", "guard_proto.c", "guard_proto.h", "guard_proto_msgs.h")
NAME = "gp_pyext"
MAX_PYTHON = (3, 14)
"""The extension makes its messages with the tuple type's ``tp_alloc`` (zero-filled); a
CPython that caches a tuple's hash in the object (main, from about 3.14) would read 0 as a
cached hash, so messages made in C would hash unlike equal ones made in Python. Untested
there: from this version on the Python path runs."""

_module: ModuleType | None | bool = False  # False: not looked for yet


def module() -> ModuleType | None:
    """The extension (built on first use), or None (see the module docstring)."""
    global _module
    if _module is False:
        _module = _load()
    return _module


def _load() -> ModuleType | None:
    if os.environ.get("GUARDID_NATIVE", "1") == "0" or sys.version_info >= MAX_PYTHON:
        return None
    import importlib.machinery  # here: commands that never parse a frame do not pay them
    import importlib.util
    import sysconfig

    from guardid.native import HOST_CFLAGS, NativeBuildError, cached_library

    include = sysconfig.get_paths().get("include") or ""
    paths = [FIRMWARE_DIR / s for s in SOURCES]
    if not (Path(include) / "Python.h").is_file() or not all(p.is_file() for p in paths):
        return None
    try:  # a build that fails, a cache it cannot write, a library that does not load
        lib = cached_library(NAME, paths, (*HOST_CFLAGS, f"-I{include}"))
        if lib is None:
            return None
        loader = importlib.machinery.ExtensionFileLoader(NAME, str(lib))
        mod = importlib.util.module_from_spec(importlib.util.spec_from_loader(NAME, loader))
        loader.exec_module(mod)
    except (NativeBuildError, OSError, ImportError) as exc:  # a speed-up only: say so once
        warnings.warn(f"guardid: the protocol's C fast path is off: {exc}", stacklevel=2)
        return None
    return mod
