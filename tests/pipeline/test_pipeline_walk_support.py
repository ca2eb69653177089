"""With a camera, a track is output at a frame when the camera saw it within ``camera_support_s``, or when
the frame lies in a stretch of its observations in which it walked ``min_walk_m`` (the walk gate's
stretches): someone far away whom MoveNet no longer boxes is still a person while the laser sees them walk,
but a track that stands on one spot without the camera may have left its person for clutter."""

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

W, H = 1920, 960
CAM = EquirectCamera(W, H, Pose3.from_xyz_rpy(0.0, 0.0, 1.15))
HZ = 10
N = 100  # 10 s
BOXED = 10  # the camera boxes the person in the first second only (every other frame: 5 boxes)


def _walker(k: int) -> np.ndarray:
    """6 m ahead, walks across at 0.8 m/s for the whole recording."""
    return np.array([6.0, -4.0 + 0.8 * k / HZ])


def _stander(k: int) -> np.ndarray:
    """Walks the first second, then stands where they are."""
    return _walker(min(k, BOXED))


def _box_over(xy: np.ndarray) -> ImageDetections:
    pts = np.array([[xy[0], xy[1] + s, z] for s in (-0.25, 0.25) for z in (0.0, 1.75)])
    uv, _ = CAM.project(pts)
    box = np.array([uv[:, 0].min(), uv[:, 1].min(), uv[:, 0].max(), uv[:, 1].max()])
    return ImageDetections(box[None], np.array([0.7]), None, W, H)


def _labelled(where, options: LabelOptions) -> int:  # type: ignore[no-untyped-def]
    """Frames in which the person (at ``where(k)``) is labelled."""
    no_points = (np.zeros((1, 2)), np.zeros((0, 2), np.float32), np.zeros(1, np.int32), np.zeros((1, 3)))
    frames = []
    for k in range(N):
        xy = where(k)
        laser = LaserDetections(
            xy[None].copy(), np.full(1, 0.8), np.full(1, KIND_PAIR), np.full(1, 0.2), (np.zeros(0, int),)
        )
        image = _box_over(xy) if k < BOXED and k % 2 == 0 else None
        stamp = k * 1_000_000_000 // HZ
        frames.append(PerceptionFrame(k, stamp, Pose2(), image, None, laser, np.full(1, 0.3), *no_points))
    fused = fuse_all(frames, CAM, options)
    labels, _ = track_all(frames, fused, options, has_camera=True)
    return sum(
        any(np.hypot(p.x - where(lf.frame)[0], p.y - where(lf.frame)[1]) < 0.2 for p in lf.people)
        for lf in labels
    )


OPTIONS = replace(LabelOptions(), static_filter=False)


def test_a_walker_the_camera_saw_once_is_labelled_while_they_walk() -> None:
    assert _labelled(_walker, OPTIONS) == N


def test_one_who_stands_is_labelled_only_near_the_camera_s_support() -> None:
    """Boxed up to frame 8, supported 3 s on: frames 0–38; the 1 s walk before standing counts too."""
    n = _labelled(_stander, OPTIONS)
    assert BOXED <= n <= BOXED + int(OPTIONS.camera_support_s * HZ) + 1


def test_without_the_walk_gate_only_the_camera_supports() -> None:
    n = _labelled(_walker, replace(OPTIONS, min_walk_m=0.0))
    assert n <= BOXED + int(OPTIONS.camera_support_s * HZ) + 1
