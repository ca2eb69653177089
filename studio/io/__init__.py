"""Recordings in: read ROS1/ROS2/MCAP bags, decode sensor data, build the TF tree, synchronise frames.

Typical use::

    from studio.io import load_rig, open_recording, iter_frames

    rig = load_rig("rig.yaml")
    with open_recording("recording.mcap") as rec:
        for frame in iter_frames(rec, rig):
            ...
"""

from __future__ import annotations

from studio.io.base import Frame, LaserScan, Odometry, Panorama, RawMessage, ScanInBase, TopicInfo
from studio.io.decode import decode_odometry, decode_panorama, decode_scan, decode_tf
from studio.io.errors import RecordingError, RigError, TfError
from studio.io.reader import Recording, open_recording
from studio.io.rig import (
    CameraConfig,
    LaserConfig,
    OdometryConfig,
    Rig,
    SyncConfig,
    load_rig,
    parse_rig,
    save_rig,
)
from studio.io.sync import (
    LaserSyncStats,
    SyncReport,
    count_frames,
    iter_frames,
    resolve_sensor_poses,
    unplaced_reason,
)
from studio.io.tf import TfBuffer, TfEdge
from studio.io.writer import RecordingWriter

__all__ = [
    "CameraConfig",
    "Frame",
    "LaserConfig",
    "LaserScan",
    "LaserSyncStats",
    "Odometry",
    "OdometryConfig",
    "Panorama",
    "RawMessage",
    "Recording",
    "RecordingError",
    "RecordingWriter",
    "Rig",
    "RigError",
    "ScanInBase",
    "SyncConfig",
    "SyncReport",
    "TfBuffer",
    "TfEdge",
    "TfError",
    "TopicInfo",
    "count_frames",
    "decode_odometry",
    "decode_panorama",
    "decode_scan",
    "decode_tf",
    "iter_frames",
    "load_rig",
    "open_recording",
    "parse_rig",
    "resolve_sensor_poses",
    "save_rig",
    "unplaced_reason",
]
