"""The one YAML loader guardid reads its files with (robots, trajectories, params files, log
headers, robot mappings): libyaml's safe loader when PyYAML has it (its wheels do), else
PyYAML's own. The same documents as ``yaml.safe_load``, several times faster."""

from __future__ import annotations

import yaml

SAFE_LOADER = getattr(yaml, "CSafeLoader", yaml.SafeLoader)


def safe_load(stream):
    """``yaml.safe_load`` of ``stream`` (text or an open file) with :data:`SAFE_LOADER`."""
    return yaml.load(stream, Loader=SAFE_LOADER)
