"""Physically consistent identification (``guardid identify --consistent``).

:func:`fit_consistent` turns identification rows into a full set of standard parameters
whose every link is a physical body (log-Cholesky pseudo-inertia) and whose rotor inertias
and friction coefficients are non-negative; :func:`description_with` makes the identified
robot description from it. Report helpers live in :mod:`guardid.physical.report`.
"""

from guardid.physical.apply import description_with
from guardid.physical.fit import BIAS_PER_STD, ConsistentFit, fit_consistent
from guardid.physical.pseudo_inertia import (
    consistency_margin,
    link_violations,
    log_cholesky_from_standard,
    pseudo_inertia,
    standard_from_log_cholesky,
)

__all__ = [
    "BIAS_PER_STD",
    "ConsistentFit",
    "consistency_margin",
    "description_with",
    "fit_consistent",
    "link_violations",
    "log_cholesky_from_standard",
    "pseudo_inertia",
    "standard_from_log_cholesky",
]
