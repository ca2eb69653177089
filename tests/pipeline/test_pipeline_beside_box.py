"""Two people side by side make one box; the laser sees both. The camera confirmation that every output track
needs (``LabelOptions.min_camera_hits``, ``camera_support_s``) comes for the second one from being inside that
box, at that range, beside the first (``how`` ``beside-box``)."""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from studio.detect.image.base import ImageDetections
from studio.detect.laser.base import KIND_PAIR, LaserDetections
from studio.fuse import FusionConfig
from studio.geometry import EquirectCamera, Pose3
from studio.geometry.se import Pose2
from studio.pipeline import LabelOptions
from studio.pipeline.label import fuse_all, track_all
from studio.pipeline.perceive import PerceptionFrame

W, H = 1920, 960
CAM = EquirectCamera(W, H, Pose3.from_xyz_rpy(0.0, 0.0, 1.15))
PEOPLE = np.array([[5.0, 0.3], [5.0, 0.9]])  # 0.6 m apart, same range
N = 30  # 3 s at 10 Hz


def _one_box() -> ImageDetections:
    """One box over both people, feet to head."""
    pts = np.array([[x, y + s, z] for x, y in PEOPLE for s in (-0.25, 0.25) for z in (0.0, 1.75)])
    uv, _ = CAM.project(pts)
    box = np.array([uv[:, 0].min(), uv[:, 1].min(), uv[:, 0].max(), uv[:, 1].max()])
    return ImageDetections(box[None], np.array([0.7]), None, W, H)


def _frames() -> list[PerceptionFrame]:
    laser = LaserDetections(
        PEOPLE.copy(), np.full(2, 0.8), np.full(2, KIND_PAIR), np.full(2, 0.2), tuple(np.zeros((2, 0), int))
    )
    out = []
    for k in range(N):
        image = _one_box() if k % 2 == 0 else None
        no_points = (np.zeros((1, 2)), np.zeros((0, 2), np.float32), np.zeros(1, np.int32), np.zeros((1, 3)))
        out.append(
            PerceptionFrame(k, k * 100_000_000, Pose2(), image, None, laser, np.full(2, 0.3), *no_points)
        )
    return out


def _labelled(config: FusionConfig) -> dict[int, int]:
    """Per person, the frames with a label within 0.2 m."""
    opts = replace(LabelOptions(), fusion=config, static_filter=False)
    frames = _frames()
    labels, _ = track_all(frames, fuse_all(frames, CAM, opts), opts, has_camera=True)
    near = [
        [min((np.hypot(p.x - c[0], p.y - c[1]) for p in lf.people), default=np.inf) for c in PEOPLE]
        for lf in labels
    ]
    return {i: int(np.sum(np.array(near)[:, i] < 0.2)) for i in range(len(PEOPLE))}


def test_the_person_beside_the_boxed_one_is_labelled() -> None:
    seen = _labelled(FusionConfig())
    assert seen[0] >= N - 3
    assert seen[1] >= N - 3


def test_without_it_the_camera_never_confirms_them() -> None:
    seen = _labelled(FusionConfig(beside_box_range=0.0))
    assert seen[0] >= N - 3  # the one the box took
    assert seen[1] == 0
