"""Capture: drive the robot along a trajectory and record its telemetry to a log."""

from guardid.capture.run import CaptureResult, capture

__all__ = ["CaptureResult", "capture"]
