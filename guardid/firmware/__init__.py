"""The microcontroller side, emulated in Python: fixed-point PID and the protocol state machine.

The emulator follows the state machine of ``firmware_proto/README.md`` and uses the same
integer arithmetic as the portable C core, so both give the same telemetry.
"""

from guardid.firmware.emulator import FirmwareEmulator, make_sim_device
from guardid.firmware.pid import FixedPid, pid_gains_q16

__all__ = ["FirmwareEmulator", "FixedPid", "make_sim_device", "pid_gains_q16"]
