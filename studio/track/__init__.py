"""People tracking: odom-frame UKF + GNN online tracker, offline smoothing and stitching, thesis baseline.

Positions are metres in the tracking frame, time stamps integer nanoseconds. Entry points:
:class:`UkfTracker` (online), :func:`track_offline` (whole recording, for labeling), :class:`ThesisTracker`
(the baseline), :func:`track_sequence` (run any online tracker over a sequence).
"""

from __future__ import annotations

from studio.track.base import (
    Observations,
    Tracker,
    TrackEstimate,
    TrackFrame,
    TrackPoint,
    TrackResult,
    track_sequence,
)
from studio.track.errors import TrackingError
from studio.track.offline import OfflineConfig, track_offline, tracks_from_hits
from studio.track.stitch import StitchConfig
from studio.track.thesis import ThesisTracker, ThesisTrackerConfig
from studio.track.ukf import UkfTracker, UkfTrackerConfig

__all__ = [
    "Observations",
    "OfflineConfig",
    "StitchConfig",
    "ThesisTracker",
    "ThesisTrackerConfig",
    "TrackEstimate",
    "TrackFrame",
    "TrackPoint",
    "TrackResult",
    "Tracker",
    "TrackingError",
    "UkfTracker",
    "UkfTrackerConfig",
    "track_offline",
    "track_sequence",
    "tracks_from_hits",
]
