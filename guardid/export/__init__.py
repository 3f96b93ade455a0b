"""Export the (identified) robot for other tools: URDF with its side YAML, MuJoCo MJCF.

Frames: :mod:`guardid.export.frames`; formats: :mod:`guardid.export.urdf`,
:mod:`guardid.export.mjcf`, :mod:`guardid.export.side` (docs/URDF.md).
"""

from guardid.export.mjcf import mjcf_text, write_mjcf
from guardid.export.side import side_path
from guardid.export.urdf import urdf_text, urdf_texts, write_urdf

__all__ = ["mjcf_text", "side_path", "urdf_text", "urdf_texts", "write_mjcf", "write_urdf"]
