"""Identification: from a log to base parameters (LS, WLS, RLS, Hopfield, gradient) and motors."""

from guardid.identify.electrical import MotorEstimate, identify_motor
from guardid.identify.pipeline import (
    METHODS,
    Identification,
    MethodResult,
    identification_rows,
    identify,
)

__all__ = [
    "METHODS",
    "Identification",
    "MethodResult",
    "MotorEstimate",
    "identification_rows",
    "identify",
    "identify_motor",
]
