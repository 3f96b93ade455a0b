"""The fake serial device: an emulated robot behind a pyserial port or a pseudo-terminal.

``import guardid`` registers the ``sim://`` URL scheme with pyserial, so that
``serial.serial_for_url("sim://guard?seed=1")`` opens a port to the emulated robot
(handler: :mod:`guardid.fakeport.protocol_sim`).
The device (firmware emulator) is built by :func:`make_device`, pluggable with
:func:`register_device_factory`.
"""

from guardid.fakeport.device import Device, EchoDevice
from guardid.fakeport.engine import Disconnected, LinkEngine
from guardid.fakeport.factory import make_device, register_device_factory
from guardid.fakeport.faults import DirectionStats, FaultConfig, FaultStats
from guardid.fakeport.options import SimOptions, SimUrlError, parse_options, parse_sim_url

__all__ = [
    "Device",
    "DirectionStats",
    "Disconnected",
    "EchoDevice",
    "FaultConfig",
    "FaultStats",
    "LinkEngine",
    "SimOptions",
    "SimUrlError",
    "make_device",
    "parse_options",
    "parse_sim_url",
    "register_device_factory",
]
