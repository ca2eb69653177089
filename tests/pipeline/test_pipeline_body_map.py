"""Returns from the robot's own body are dropped: per scanner, what it hits in most of its scans in the base
frame. A part only one of two scanners sees must count against that scanner's scans, not both's."""

from __future__ import annotations

import numpy as np

from studio.detect.laser import KIND_BLOB, LaserDetections
from studio.geometry.se import Pose2
from studio.pipeline.label import _static_masks
from studio.pipeline.perceive import PerceptionFrame, compact_beams

POST = np.array([0.3, 0.2])  # a mast strut in front scanner 0's view, hidden from scanner 1


def _frame(k: int) -> PerceptionFrame:
    rng = np.random.default_rng(k)
    a = np.linspace(0, 2 * np.pi, 8, endpoint=False)
    post = POST + 0.03 * np.stack([np.cos(a), np.sin(a)], 1)
    # the robot drives along x: the world (a wall 4 m ahead, some clutter) moves past in the base frame
    wall = np.stack([np.full(40, 4.0 - 0.1 * k), np.linspace(-2, 2, 40)], 1)
    clutter = rng.uniform(-3, 3, (10, 2))
    s0 = np.concatenate([post, wall, clutter])
    s1 = np.concatenate([-wall, clutter])
    pts = np.zeros((len(s0) + len(s1), 3), np.float32)
    pts[:, :2] = np.concatenate([s0, s1])
    owner = np.r_[np.zeros(len(s0), np.int16), np.ones(len(s1), np.int16)]
    segs = [np.arange(8), np.arange(8, 16)]  # the post, and a piece of the wall
    laser = LaserDetections(
        np.array([POST, wall[:8].mean(0)]), np.full(2, 0.9), np.full(2, KIND_BLOB), np.full(2, 0.1), segs
    )
    return PerceptionFrame(
        k, k * 100_000_000, Pose2(0.1 * k, 0.0, 0.0), None, None, laser, np.full(2, 0.3),
        np.array([[0.2, 0.0], [-0.2, 0.0]]), *compact_beams(pts, owner, 2),
    )  # fmt: skip


def test_a_part_one_scanner_sees_in_every_scan_is_the_body() -> None:
    frames = [_frame(k) for k in range(40)]
    det_static, pt_static = _static_masks(frames)
    for ds, ps in zip(det_static, pt_static, strict=True):
        assert ps[:8].all()  # the post's points
        assert ds[0]  # the detection on the post
        assert ds[1]  # the wall is static in the world (the robot drives towards it)
    # the clutter comes and goes: not the body
    assert np.mean([ps[48:58].mean() for ps in pt_static]) < 0.2
