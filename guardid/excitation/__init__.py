"""Excitation trajectories for identification: Fourier series, Schroeder multisines, sines.

Every trajectory offers positions(t), velocities(t), accelerations(t) on a time array [s]
-> (N, n) [rad, rad/s, rad/s^2] (analytic), period and duration [s], to_dict()/from_dict(),
save(path)/load(path) (YAML with a ``kind:`` key). :func:`optimise_fourier` picks Fourier
coefficients minimising cond of the base regressor under the joint limits (seed 001
eqs. 34-38).
"""

from guardid.excitation.fourier import FourierTrajectory, rest_basis
from guardid.excitation.limits import (
    ExcitationError,
    JointLimits,
    JointUsage,
    fit_to_limits,
    limit_usage,
)
from guardid.excitation.optimise import ExcitationResult, optimise_fourier, regressor_cond
from guardid.excitation.sines import SchroederMultisine, SumOfSines, schroeder_phases
from guardid.excitation.trajectory import KINDS, Trajectory, load_trajectory

__all__ = [
    "KINDS",
    "ExcitationError",
    "ExcitationResult",
    "FourierTrajectory",
    "JointLimits",
    "JointUsage",
    "SchroederMultisine",
    "SumOfSines",
    "Trajectory",
    "fit_to_limits",
    "limit_usage",
    "load_trajectory",
    "optimise_fourier",
    "regressor_cond",
    "rest_basis",
    "schroeder_phases",
]
