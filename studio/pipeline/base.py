"""Contract of the labeling pipeline: options in, a labeled run out."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from studio.fuse.base import FusionConfig, PersonObservations
from studio.geometry.se import Pose2
from studio.track.offline import OfflineConfig
from studio.track.ukf import UkfTrackerConfig

__all__ = ["METHODS", "SOURCES_OPTIONS", "FrameResult", "LabelOptions"]

METHODS = ("studio", "thesis")

PIPELINE_TRACKING = OfflineConfig(
    tracker=UkfTrackerConfig(
        max_coast_s=1.0,
        accel_sigma=0.65,
        appearance_weight=0.1,
        appearance_gate=40.0,
        confirm_min_span_s=0.18,
    ),
    min_track_duration_s=1.5,
    correlation_s=0.1,
)
"""Offline tracking for labeling. ``accel_sigma`` 0.65 (m/s per √s of white acceleration, walking people)
instead of the tracker's generic 1.5: on the simulated static 50 s, moving 96 s and moving 15 s
recordings it raised F1 by 0.012–0.036 and MOTA by 0.018–0.075 (IDF1 mixed). Clothing colours in the
online association (0.1 per ΔE, pairs more than 40 apart never associated): ID switches 26 → 18 on
``moving`` seeds 1, 2 (96 s), ``static`` seed 1 and ``moving`` 15 s seed 11 together, F1 within ±0.006;
see docs/results.md. A new track's three confirming hits must span 0.18 s, as they do at the 10 Hz every
parameter was tuned at (0.2 s, less room for stamp jitter): the frames of a 40 Hz scanner on a laser-only
rig confirmed legs and clutter in 50 ms (session 39).

A track is labelled only if it spans 1.5 s (the tracker's generic 0.5 s): a shorter piece is most often a
few frames of someone whose own track goes on around it, cut off another track by the colour repair or
left over by stitching; left in, it is two identity switches. Session 60 (``docs/results.md``): held-out
simulated ``moving`` seeds 21–40 19 → 17 switches (F1 0.9630 → 0.9628); seeds 1–20 and 41–50,
laser-only seeds 1–12 and ``rooms`` seed 1 the same.

Observations closer than 0.1 s in time count as one (``correlation_s``): at a higher frame rate (a Ricoh
Theta streams 30 frames/s; a laser-only rig's frames are its scans, often at 25–40 Hz) their covariances are
widened by the rate over 10 Hz, so a second of observations weighs as much as at the 10 Hz every parameter
was tuned at, and a track's excursion onto someone else's way may be as many more hits long (as long in
time as at 10 Hz); at 10 Hz and below nothing changes. A person's detections a few tens of milliseconds
apart share their error (the same legs in nearly the same stride, the same part hidden), and taken as
independent they made the tracks follow that error. Session 69 (``docs/results.md``), simulated ``moving``
seeds 1–20 (60 s) with a 30 Hz camera: F1 0.9680 → 0.9706, MOTA 0.9369 → 0.9419, IDF1 0.9595 → 0.9589,
identity switches 19 → 17 and 26.7 → 17.4 on average under three seeds of 5 mm noise (15.3 at 10 Hz); the
rig without its camera, frames at its 40 Hz scans (seeds 1–11): F1 0.9649 → 0.9657, MOTA 0.9299 → 0.9315,
IDF1 0.7815 → 0.7804, 56 switches either way."""
SOURCES_OPTIONS = ("both", "laser", "camera")


@dataclass(frozen=True)
class LabelOptions:
    """What ``studio label`` does.

    Attributes:
        method: ``studio`` (ours) or ``thesis`` (the baseline it is compared against).
        sources: ``both``, ``laser`` (laser-only baseline) or ``camera`` (camera-only baseline).
        image_detector: registry name or a YOLO ``.onnx`` path (None: the bundled default).
        laser_detector: registry name (None: the classical detector).
        image_period_s: run the image detector at most this often, s (0: on every frame). The frames in
            between are fused from the laser alone; tracks carry the camera's confirmation across them.
        quiet_view_period_s: with a detector that can look at part of the panorama (the bundled ones:
            MoveNet through narrow views on the busy columns, CenterNet through the views of its sweep that
            see them), the part where nobody was seen in the past second is looked at only this often, s (at
            most ``image_period_s``: always all of it). The laser still sees people there in between, and
            a box found there brings its views back to every image.
        static_filter: suppress laser detections on structure that never moves (world-frame map).
        scan_matching: correct the odometry's drift by matching each frame's scans to the recent ones
            (:mod:`studio.geometry.scan_match`; without odometry it is the robot's only motion estimate); the
            static map and the tracker work in the corrected frame, the outputs stay in the odometry frame
            (on a rig without odometry, scan matching's).
        min_camera_hits: on rigs with a camera and ``sources=both``, a track must be confirmed by the camera
            (a fused or image observation, or a laser one ``beside-box``: inside a box that took someone
            beside it, see ``FusionConfig.beside_box_range``; or, in a frame, a fused or image observation
            that no track took lies within 0.3 m of it) in at least this many frames, else it is dropped as
            laser clutter. The last case: a track that holds a person's laser detections while their
            camera-described ones go to nobody (its colours are someone else's, so the online association
            turned them down, and they lie too close to it to start a track of their own) is still that
            person, seen by the camera; without it 22 s of one person went unlabelled on simulated
            ``moving`` seed 20 (session 30, ``docs/results.md``).
        camera_support_s: on rigs with a camera and ``sources=both``, a track is output at a frame only if
            the camera saw it (as for ``min_camera_hits``) within this many seconds before or after, or the
            frame lies in a stretch of its observations in which it walked ``min_walk_m`` (as the walk gate
            measures it: someone far away whom the image detector no longer boxes, walking in the scans);
            this cuts the stretches where a track left its person and followed laser clutter, s.
        min_track_s: tracks shorter than this are dropped, s (the thesis baseline's limit; the ``studio``
            method's tracker already leaves out tracks under ``tracking.min_track_duration_s``, 1.5 s).
        min_walk_m: without the camera (laser-only rigs, ``sources=laser``), a track must somewhere walk this
            far in one stretch of observations (no gap over 0.5 s, positions median-filtered over
            five observations: the diameter of the stretch), else it is dropped as laser clutter: chair and
            table legs a moving robot sees too briefly for the static map to judge stand still, and a track
            that hops between them does so across gaps. Offline, the whole track counts, so someone who
            walked in and then stood is kept throughout; someone who stood still for the whole recording
            is not (without a camera, nothing tells them from furniture). With a camera, the stretches in
            which a track walked this far count as the camera's support (``camera_support_s``). 0 turns
            both off, m.
        fusion: association parameters.
        tracking: offline tracking parameters (online UKF pass, stitching, smoothing).
        recover_radius: after a first tracking pass, a track that has no observation in a frame takes the
            off-structure scan points within this distance of its smoothed position as one (the laser
            detector missed the person there), and tracking runs again; 0 turns this off, m.
        export_frames: also write the labeled panoramas as JPEG files (a self-contained dataset).
    """

    method: str = "studio"
    sources: str = "both"
    image_detector: str | None = None
    laser_detector: str | None = None
    image_period_s: float = 0.2
    quiet_view_period_s: float = 0.4
    static_filter: bool = True
    scan_matching: bool = True
    min_camera_hits: int = 3
    camera_support_s: float = 3.0
    min_track_s: float = 1.0
    min_walk_m: float = 1.0
    fusion: FusionConfig = field(default_factory=FusionConfig)
    tracking: OfflineConfig = field(default_factory=lambda: PIPELINE_TRACKING)
    recover_radius: float = 0.35
    export_frames: bool = False

    def __post_init__(self) -> None:
        if self.method not in METHODS:
            raise ValueError(f"method must be one of {METHODS}, got {self.method!r}")
        if self.sources not in SOURCES_OPTIONS:
            raise ValueError(f"sources must be one of {SOURCES_OPTIONS}, got {self.sources!r}")
        if not 0.0 <= self.min_walk_m < float("inf"):
            raise ValueError(f"min_walk_m must be a finite distance >= 0, got {self.min_walk_m}")

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
        scan_points: ``(M, 3)`` valid scan points off static structure, base frame (None: no laser used).
        track_pose: T_world_base the tracker uses (the odometry corrected by scan matching), or None for
            ``robot_pose``.
        legs: ``(N, 2, 2)`` base frame, the two legs of each observation made from a laser leg pair (NaN
            rows for the others; observations appended later have none), or None.
        colours_hidden: ``(N,)`` observations whose box may show someone standing in front of them
            (:func:`~studio.fuse.colours_hidden`): their clothing colours are not used (observations
            appended later have none), or None.
        obs_dt: ``(N,)`` when each observation was measured, seconds after the frame stamp: that of the
            beams on the person for a laser position (0 for an image-only one), or None (all at the stamp).
        occupied: ``(N,)`` how occupied the static-world map saw each observation's place (the median over
            its laser detection's beams of the cell's occupied fraction, 0 where the cell changed while the
            scanner stood still); NaN without a laser detection (a cluster recovered where a track coasted
            gets the median over its scan points, see ``scan_occupied``), or None (not computed: no map, or
            ``LabelOptions.min_walk_m`` 0). The walk gate of laser-only labels and, with a camera, the
            walking stretches that count as the camera's support use it.
        scan_occupied: ``(M,)`` the same share for each of ``scan_points``, or None where ``occupied`` is.
    """

    index: int
    stamp_ns: int
    robot_pose: Pose2
    observations: PersonObservations
    scan_points: NDArray[np.float32] | None = None
    track_pose: Pose2 | None = None
    legs: NDArray[np.float64] | None = None
    colours_hidden: NDArray[np.bool_] | None = None
    obs_dt: NDArray[np.float64] | None = None
    occupied: NDArray[np.float64] | None = None
    scan_occupied: NDArray[np.float16] | None = None

    @property
    def world_pose(self) -> Pose2:
        """``track_pose``, else ``robot_pose``."""
        return self.robot_pose if self.track_pose is None else self.track_pose
