"""Identification: from runs (logs) to base parameters by registered estimators, and motors.

In five lines (docs/CONTRACTS.md, docs/API.md)::

    from guardid.identify import IdentifyOptions, identify, load_run
    from guardid.robot import load_robot

    r = identify([load_run("run.csv")], load_robot("guard"), IdentifyOptions(methods=("wls",)))
    for name, value, std in zip(r.names, r.results["wls"].theta, r.results["wls"].std):
        print(f"{name} {value:.4g} +- {std:.2g}")  # base parameters [SI] and their std
"""

from importlib import import_module

_WHERE = {
    "MotorEstimate": "electrical",
    "identify_motor": "electrical",
    "identify_motor_runs": "electrical",
    "Method": "methods",
    "MethodFit": "methods",
    "method_names": "methods",
    "register": "methods",
    "HopfieldSettings": "pipeline",
    "Identification": "pipeline",
    "IdentifyOptions": "pipeline",
    "MethodResult": "pipeline",
    "identification_rows": "rows",
    "identify": "pipeline",
    "run_from_arrays": "runs",
    "Run": "runs",
    "load_run": "runs",
}
"""Where each name lives: imported on first use, so that ``guardid identify --help`` (which
lists the registered methods) does not load the numerical stack."""

__all__ = sorted(_WHERE)


def __getattr__(name):
    if name in _WHERE:
        return getattr(import_module(f"guardid.identify.{_WHERE[name]}"), name)
    raise AttributeError(f"module 'guardid.identify' has no attribute {name!r}")
