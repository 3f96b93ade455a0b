"""Signal conditioning for identification (DESIGN.md sections 2 and 5).

Offline entry point: :func:`condition` (filter, differentiate, align the period-mean
current, convert to torque, decimate, mask stiction) -> :class:`Conditioned`.
Online: :class:`CausalConditioner`. The building blocks are plain functions.
"""

from guardid.conditioning.alignment import align_period_mean
from guardid.conditioning.bandwidth import choose_cutoff, energy_bandwidth
from guardid.conditioning.causal import CausalConditioner, StreamOutput, dc_group_delay
from guardid.conditioning.filters import (
    central_derivatives,
    decimate,
    decimation_factor,
    lowpass_sos,
    resample,
    uniform_grid,
    zero_phase_lowpass,
)
from guardid.conditioning.parallel import parallel_filter
from guardid.conditioning.pipeline import Conditioned, condition
from guardid.conditioning.stiction import default_stiction_threshold, stiction_mask
from guardid.conditioning.units import (
    counts_per_joint_rev,
    counts_to_rad,
    current_to_torque,
    drive_gain,
)

__all__ = [
    "CausalConditioner",
    "Conditioned",
    "StreamOutput",
    "align_period_mean",
    "central_derivatives",
    "choose_cutoff",
    "condition",
    "counts_per_joint_rev",
    "counts_to_rad",
    "current_to_torque",
    "dc_group_delay",
    "decimate",
    "decimation_factor",
    "default_stiction_threshold",
    "drive_gain",
    "energy_bandwidth",
    "lowpass_sos",
    "parallel_filter",
    "resample",
    "stiction_mask",
    "uniform_grid",
    "zero_phase_lowpass",
]
