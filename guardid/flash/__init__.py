"""Flash the AVR port onto an Arduino-class board: build for the robot YAML, write and verify
through the board's serial boot loader with avrdude, check the firmware id INFO reports."""

from guardid.flash.avrdude import AvrdudeError, run_avrdude
from guardid.flash.boards import BOARDS, Board
from guardid.flash.firmware import FirmwareBuild, build_for_robot

__all__ = ["BOARDS", "AvrdudeError", "Board", "FirmwareBuild", "build_for_robot", "run_avrdude"]
