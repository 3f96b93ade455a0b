"""On-line identification during a capture (and its replay from a log): estimators fed row by
row through causal conditioning, and a change report when the parameters move."""

from guardid.online.detector import ChangeDetector, ChangeReport, DetectorSettings
from guardid.online.tracker import (
    DEFAULT_BETA,
    DEFAULT_LAM,
    ONLINE_METHODS,
    OnlineIdentifier,
    Track,
    online_path,
    read_tracks_csv,
)

__all__ = [
    "DEFAULT_BETA",
    "DEFAULT_LAM",
    "ONLINE_METHODS",
    "ChangeDetector",
    "ChangeReport",
    "DetectorSettings",
    "OnlineIdentifier",
    "Track",
    "online_path",
    "read_tracks_csv",
]
