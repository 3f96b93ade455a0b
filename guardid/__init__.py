"""guardid: host-side bridge and dynamic identification toolkit for the guard robot.

Importing guardid registers the ``sim://`` URL scheme with pyserial, so that
``serial.serial_for_url("sim://guard?seed=1")`` opens a port to the emulated robot
(:mod:`guardid.fakeport`, imported by pyserial only when such a URL is opened; importing
guardid itself loads pyserial and nothing heavier).

The Python API (docs/API.md), imported on first use: ``guardid.read_log``,
``guardid.load_robot``, ``guardid.identify_logs``, ``guardid.validate``,
``guardid.simulate`` (:mod:`guardid.api`).
"""

import serial as _serial

__version__ = "0.1.0"

if "guardid.fakeport" not in _serial.protocol_handler_packages:
    _serial.protocol_handler_packages.append("guardid.fakeport")

_API = ("read_log", "load_robot", "identify_logs", "validate", "simulate", "IdentifyResult",
        "ValidationResult")  # fmt: skip


def __getattr__(name):
    if name in _API:
        from guardid import api

        return getattr(api, name)
    raise AttributeError(f"module 'guardid' has no attribute {name!r}")


def __dir__():
    return sorted([*globals(), *_API])
