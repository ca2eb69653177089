"""People in 2D laser scans: the detector contract, a classical leg detector, a static-world filter.

Backends load lazily through :func:`get_laser_detector`; ``import studio.detect.laser`` imports no backend.
"""

from __future__ import annotations

from studio.detect.laser.base import (
    KIND_BLOB,
    KIND_LEG,
    KIND_NAMES,
    KIND_PAIR,
    LaserDetections,
    LaserDetector,
    get_laser_detector,
    laser_detector_names,
    merge_detections,
    register_laser_detector,
)
from studio.detect.laser.errors import LaserDetectorError

__all__ = [
    "KIND_BLOB",
    "KIND_LEG",
    "KIND_NAMES",
    "KIND_PAIR",
    "LaserDetections",
    "LaserDetector",
    "LaserDetectorError",
    "get_laser_detector",
    "laser_detector_names",
    "merge_detections",
    "register_laser_detector",
]
