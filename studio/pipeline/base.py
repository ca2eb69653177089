"""Contract of the labeling pipeline: options in, a labeled run out."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

from studio.fuse.base import FusionConfig, PersonObservations
from studio.geometry.se import Pose2

__all__ = ["METHODS", "SOURCES_OPTIONS", "FrameResult", "LabelOptions"]

METHODS = ("studio", "thesis")
SOURCES_OPTIONS = ("both", "laser", "camera")


@dataclass(frozen=True)
class LabelOptions:
    """What ``studio label`` does.

    Attributes:
        method: ``studio`` (ours) or ``thesis`` (the baseline it is compared against).
        sources: ``both``, ``laser`` (laser-only baseline) or ``camera`` (camera-only baseline).
        image_detector: registry name or a YOLO ``.onnx`` path (None: the bundled default).
        laser_detector: registry name (None: the classical detector).
        static_filter: suppress laser detections on structure that never moves (odom-frame map).
        min_camera_hits: on rigs with a camera and ``sources=both``, a track must be confirmed by the camera
            (a fused or image observation) in at least this many frames, else it is dropped as laser clutter.
        laser_track_min_travel: a track the camera did not confirm is still kept when it moves at least
            this far from where it started, m (people beyond the image detector's range).
        min_track_s: tracks shorter than this are dropped, s.
        fusion: association parameters.
        export_frames: also write the labeled panoramas as JPEG files (a self-contained dataset).
    """

    method: str = "studio"
    sources: str = "both"
    image_detector: str | None = None
    laser_detector: str | None = None
    static_filter: bool = True
    min_camera_hits: int = 3
    laser_track_min_travel: float = 1.5
    min_track_s: float = 1.0
    fusion: FusionConfig = field(default_factory=FusionConfig)
    export_frames: bool = False

    def __post_init__(self) -> None:
        if self.method not in METHODS:
            raise ValueError(f"method must be one of {METHODS}, got {self.method!r}")
        if self.sources not in SOURCES_OPTIONS:
            raise ValueError(f"sources must be one of {SOURCES_OPTIONS}, got {self.sources!r}")

    def as_dict(self) -> dict[str, Any]:
        from dataclasses import asdict

        return asdict(self)


@dataclass(frozen=True)
class FrameResult:
    """What the pipeline knows of one frame after fusion (before tracking).

    Attributes:
        index: frame index (0, 1, …).
        stamp_ns: the header stamp of the image (or scan) the frame was built from.
        robot_pose: T_odom_base at the frame stamp.
        observations: fused people in the base frame.
    """

    index: int
    stamp_ns: int
    robot_pose: Pose2
    observations: PersonObservations
