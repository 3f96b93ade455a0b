"""Signal conditioning for identification (DESIGN.md sections 2 and 5).

Offline entry point: :func:`condition` (filter, differentiate, align the period-mean
current, convert to torque, decimate, mask stiction) -> :class:`Conditioned`.
Online: :class:`CausalConditioner`. The building blocks are plain functions.
"""

from guardid._lazy import lazy_attributes

_SOURCE = {  # loaded on first use: a submodule's constants need no scipy (excite, capture)
    "CausalConditioner": "causal",
    "Conditioned": "pipeline",
    "StreamOutput": "causal",
    "align_period_mean": "alignment",
    "central_derivatives": "filters",
    "choose_cutoff": "bandwidth",
    "condition": "pipeline",
    "counts_per_joint_rev": "units",
    "counts_to_rad": "units",
    "current_to_torque": "units",
    "dc_group_delay": "causal",
    "decimate": "filters",
    "decimation_factor": "filters",
    "default_stiction_threshold": "stiction",
    "drive_gain": "units",
    "energy_bandwidth": "bandwidth",
    "lowpass_sos": "filters",
    "parallel_filter": "parallel",
    "resample": "filters",
    "stiction_mask": "stiction",
    "uniform_grid": "filters",
    "zero_phase_lowpass": "filters",
}


__getattr__ = lazy_attributes(__name__, _SOURCE)


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
