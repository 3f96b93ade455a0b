"""Ready-made excitation trajectories for a robot description, scaled onto its limits.

- :func:`seeded_fourier`: a seeded random Fourier series at rest at the start pose (the
  optimiser's starting guess; also what ``guardid excite --no-optimise`` writes).
- :func:`robot_sines`: hand-picked sums of sines, harmonics 1..H of f on every joint with
  amplitudes ~ 1/l and joint-dependent phases.
- :func:`robot_schroeder`: Schroeder multisines, joint j (0-based) on harmonics
  j + 1, j + 1 + n, ... (H each, interleaved so no two joints share a frequency).

Sines and multisines oscillate about the middle of a limited joint's range (the start
pose for an unlimited one) and do not start at rest.
"""

from __future__ import annotations

import math

import numpy as np

from guardid.excitation.limits import JointLimits, fit_to_limits
from guardid.excitation.optimise import ConditionProblem
from guardid.excitation.sines import SchroederMultisine, SumOfSines


def centre_pose(limits: JointLimits, start) -> np.ndarray:
    """Middle of each limited joint's range, else the start pose (n,) [rad]."""
    start = np.asarray(start, dtype=float)
    limited = np.isfinite(limits.lo) & np.isfinite(limits.hi)
    mid = 0.5 * (np.where(limited, limits.lo, 0.0) + np.where(limited, limits.hi, 0.0))
    return np.where(limited, mid, start)


def seeded_fourier(
    model, desc, harmonics: int, base_freq: float, start, seed: int, margin: float = 0.05
):
    """Seeded random Fourier series at rest at ``start`` [rad], within the shrunk limits."""
    limits = JointLimits.of(desc, margin)
    limits.check_pose(start)
    prob = ConditionProblem(model, limits, base_freq, harmonics, start)
    z = prob.random_start(np.random.default_rng(seed))
    names = [j.name for j in desc.joints]
    return fit_to_limits(prob.trajectory(z, names), limits)


def robot_sines(desc, harmonics: int, base_freq: float, start, margin: float = 0.05):
    """Hand-picked sums of sines (see module docstring), scaled to just fit the limits."""
    limits = JointLimits.of(desc, margin)
    n = len(desc.joints)
    orders = np.arange(1, harmonics + 1)
    freqs = [base_freq * orders for _ in range(n)]
    amps = [1.0 / orders for _ in range(n)]
    phases = [(j * math.pi / 2 + orders * math.pi / (j + 2)) % (2 * math.pi) for j in range(n)]
    names = [j.name for j in desc.joints]
    traj = SumOfSines(amps, freqs, phases, centre_pose(limits, start), joint_names=names)
    return fit_to_limits(traj, limits, grow=True)


def robot_schroeder(desc, harmonics: int, base_freq: float, start, margin: float = 0.05):
    """Schroeder multisines (see module docstring), scaled to just fit the limits."""
    limits = JointLimits.of(desc, margin)
    n = len(desc.joints)
    freqs = [base_freq * (j + 1 + n * np.arange(harmonics)) for j in range(n)]
    names = [j.name for j in desc.joints]
    traj = SchroederMultisine(np.ones(n), freqs, centre_pose(limits, start), joint_names=names)
    return fit_to_limits(traj, limits, grow=True)


def highest_frequency(kind: str, n_joints: int, harmonics: int, base_freq: float) -> float:
    """Highest frequency [Hz] in a ``kind`` trajectory of these presets (``guardid excite``):
    harmonics x base_freq for fourier and sines; the Schroeder multisine interleaves the
    joints' harmonics, so its highest is n_joints x harmonics x base_freq."""
    per_joint = n_joints if kind == "schroeder" else 1
    return float(per_joint * harmonics * base_freq)
