"""Identification: from runs (logs) to base parameters by registered estimators, and motors.

In five lines (docs/CONTRACTS.md, README "Python API")::

    from guardid.identify import IdentifyOptions, identify, load_run
    from guardid.robot import load_robot

    result = identify([load_run("run.csv")], load_robot("guard"), IdentifyOptions(methods=("wls",)))
    print(dict(zip(result.names, result.results["wls"].theta)))
"""

from guardid.identify.electrical import MotorEstimate, identify_motor
from guardid.identify.methods import Method, MethodFit, method_names, register
from guardid.identify.pipeline import (
    HopfieldSettings,
    Identification,
    IdentifyOptions,
    MethodResult,
    identification_rows,
    identify,
    run_from_arrays,
)
from guardid.identify.runs import Run, load_run

__all__ = [
    "HopfieldSettings",
    "Identification",
    "IdentifyOptions",
    "Method",
    "MethodFit",
    "MethodResult",
    "MotorEstimate",
    "Run",
    "identification_rows",
    "identify",
    "identify_motor",
    "load_run",
    "method_names",
    "register",
    "run_from_arrays",
]
