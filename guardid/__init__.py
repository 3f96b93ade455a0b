"""guardid: host-side bridge and dynamic identification toolkit for the guard robot.

Importing guardid registers the ``sim://`` URL scheme with pyserial, so that
``serial.serial_for_url("sim://guard?seed=1")`` opens a port to the emulated robot
(:mod:`guardid.fakeport`, imported by pyserial only when such a URL is opened; importing
guardid itself loads pyserial and nothing heavier).
"""

import serial as _serial

__version__ = "0.1.0"

if "guardid.fakeport" not in _serial.protocol_handler_packages:
    _serial.protocol_handler_packages.append("guardid.fakeport")
