"""The camera gate (``LabelOptions.min_camera_hits``, ``camera_support_s``) asks whether the camera saw a
person where a track is, not whether the track took the camera's observation: a track that holds someone's
laser detections while their fused ones go to nobody (the online association turned them down for the
track's colours) is confirmed by those observations when they lie within 0.3 m of it."""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from studio.detect.image.base import ImageDetections
from studio.detect.laser.base import KIND_PAIR, LaserDetections
from studio.geometry import EquirectCamera, Pose3
from studio.geometry.se import Pose2
from studio.pipeline import LabelOptions
from studio.pipeline.label import fuse_all, track_all
from studio.pipeline.perceive import PerceptionFrame
from studio.track.base import Observations, TrackFrame, TrackPoint, TrackResult

W, H = 1920, 960
CAM = EquirectCamera(W, H, Pose3.from_xyz_rpy(0.0, 0.0, 1.15))
PERSON = np.array([5.0, 0.0])  # the laser sees this person in every frame
N = 30  # 3 s at 10 Hz, a box every other frame


def _box_over(xy: np.ndarray) -> ImageDetections:
    pts = np.array([[xy[0], xy[1] + s, z] for s in (-0.25, 0.25) for z in (0.0, 1.75)])
    uv, _ = CAM.project(pts)
    box = np.array([uv[:, 0].min(), uv[:, 1].min(), uv[:, 0].max(), uv[:, 1].max()])
    return ImageDetections(box[None], np.array([0.7]), None, W, H)


def _frames(boxed: np.ndarray) -> list[PerceptionFrame]:
    laser = LaserDetections(
        PERSON[None].copy(), np.full(1, 0.8), np.full(1, KIND_PAIR), np.full(1, 0.2), (np.zeros(0, int),)
    )
    no_points = (np.zeros((1, 2)), np.zeros((0, 2), np.float32), np.zeros(1, np.int32), np.zeros((1, 3)))
    return [
        PerceptionFrame(k, k * 100_000_000, Pose2(), _box_over(boxed) if k % 2 == 0 else None, None, laser,
                        np.full(1, 0.3), *no_points)
        for k in range(N)
    ]  # fmt: skip


def _laser_only_track(observations: list[Observations], config: object = None) -> TrackResult:
    """One track on the person that takes laser observations only and coasts through the others."""
    out = []
    for o in observations:
        d = np.hypot(*(o.xy - PERSON).T) if len(o.xy) else np.array([])
        k = int(np.argmin(d)) if len(d) else -1
        if k >= 0 and d[k] < 0.2 and o.source[k] == "laser":
            point = TrackPoint(0, o.xy[k], o.cov[k], det_index=k)
        else:
            point = TrackPoint(0, PERSON, 0.01 * np.eye(2), interpolated=True)
        out.append(TrackFrame(o.stamp_ns, (point,)))
    return TrackResult(tuple(out))


def _labelled(boxed: np.ndarray) -> int:
    opts = replace(LabelOptions(), static_filter=False)
    frames = _frames(boxed)
    fused = fuse_all(frames, CAM, opts)
    labels, _ = track_all(frames, fused, opts, has_camera=True, tracker=_laser_only_track)
    return sum(any(np.hypot(p.x - PERSON[0], p.y - PERSON[1]) < 0.2 for p in lf.people) for lf in labels)


def test_a_camera_observation_nobody_took_confirms_the_track_beside_it() -> None:
    assert _labelled(PERSON) == N


def test_one_a_metre_away_does_not() -> None:
    assert _labelled(PERSON + np.array([0.0, 1.0])) == 0
