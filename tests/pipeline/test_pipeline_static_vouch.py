"""A laser person on a spot the static-world map calls structure (someone standing still where the laser
never saw the floor free) is kept on frames without an image when a box confirmed it on an image frame
close in time; static detections no box vouched for are dropped there."""

from __future__ import annotations

import numpy as np

from studio.detect.image import ImageDetections
from studio.detect.laser import KIND_PAIR, LaserDetections
from studio.detect.laser.static_map import StaticMap
from studio.geometry import EquirectCamera
from studio.geometry.se import Pose2, Pose3
from studio.pipeline import LabelOptions
from studio.pipeline.label import fuse_all
from studio.pipeline.perceive import PerceptionFrame, compact_beams

CAMERA = EquirectCamera(1920, 960, Pose3.from_xyz_rpy(0.0, 0.0, 1.2, 0.0, 0.0, 0.0))
PERSON = np.array([3.0, 0.0])  # standing still, straight ahead
CHAIR = np.array([0.0, 2.5])  # a chair leg pair on the left


def _legs(c: np.ndarray) -> np.ndarray:
    """Points of two leg arcs around ``c`` (base frame)."""
    a = np.linspace(-0.6, 0.6, 6) + np.pi + np.arctan2(c[1], c[0])
    arcs = [
        c + off + 0.06 * np.stack([np.cos(a), np.sin(a)], 1)
        for off in (np.array([0, 0.1]), np.array([0, -0.1]))
    ]
    return np.concatenate(arcs)


def _frame(k: int, with_image: bool) -> PerceptionFrame:
    person = PERSON + np.array([0.04 * (k % 3 - 1), 0.0])  # sways a little
    pts2 = np.concatenate([_legs(person), _legs(CHAIR)])
    pts = np.zeros((len(pts2), 3), np.float32)
    pts[:, :2] = pts2
    pts[:, 2] = 0.3
    segs = [np.arange(12), np.arange(12, 24)]
    laser = LaserDetections(
        np.array([person, CHAIR]), np.array([0.9, 0.9]), np.full(2, KIND_PAIR), np.full(2, 0.2), segs
    )
    image = None
    if with_image:  # a box around the person: feet on the floor at 3 m, head at 1.7 m
        uv, _ = CAMERA.project(np.array([[3.0, -0.25, 0.0], [3.0, 0.25, 1.7]]))
        box = np.array([[*uv.min(axis=0), *uv.max(axis=0)]])
        image = ImageDetections(box, np.array([0.9]), None, 1920, 960)
    return PerceptionFrame(
        k, k * 100_000_000, Pose2(), image, None, laser, np.full(2, 0.3), np.zeros((1, 2)),
        *compact_beams(pts, np.zeros(len(pts)), 1),
    )  # fmt: skip


def _static_everywhere() -> StaticMap:
    hits = np.full((200, 200), 50, np.int32)
    return StaticMap(cell=0.05, origin=(-5.0, -5.0), hits=hits, free=np.zeros_like(hits), n_scans=50)


def test_a_box_vouches_for_a_static_laser_person_on_the_frames_around_it() -> None:
    frames = [_frame(k, with_image=k % 2 == 0) for k in range(6)]
    out = fuse_all(frames, CAMERA, LabelOptions(), static_map=_static_everywhere(), body_maps=[])
    assert [f.index for f in out] == list(range(6))  # in order, although image frames go first
    for f in out:
        near_person = np.hypot(*(f.observations.xy - PERSON).T) < 0.3
        near_chair = np.hypot(*(f.observations.xy - CHAIR).T) < 0.3
        assert near_person.sum() == 1, f.index
        assert not near_chair.any(), f.index
        if f.index % 2 == 0:
            assert f.observations.source[int(np.argmax(near_person))] == "fused"


def test_without_a_box_nearby_in_time_static_detections_are_dropped() -> None:
    frames = [_frame(0, with_image=True)] + [_frame(k, with_image=False) for k in range(1, 12)]
    out = fuse_all(frames, CAMERA, LabelOptions(), static_map=_static_everywhere(), body_maps=[])
    kept = [bool((np.hypot(*(f.observations.xy - PERSON).T) < 0.3).any()) for f in out]
    # 0.5 s at 10 Hz: frames 1–5 are vouched for by the box of frame 0, the later ones are not
    assert kept == [True] * 6 + [False] * 6


def test_a_box_on_someone_walking_past_does_not_vouch_for_the_chair_beside_them() -> None:
    # someone walks past a chair 0.27 m away; the box of each image frame takes their (moving) laser person:
    # that says nothing of the chair, whose static detection stays dropped on the frames between images
    chair, walker = np.array([3.0, 0.0]), np.array([2.85, 0.22])
    hits = np.zeros((200, 200), np.int32)
    hits[157:162, 96:104] = 50  # the chair's cells: x 2.85–3.1, y -0.2–0.2 (cell 0.05 m from -5, -5)
    free = np.where(hits > 0, 0, 50).astype(np.int32)
    smap = StaticMap(cell=0.05, origin=(-5.0, -5.0), hits=hits, free=free, n_scans=50)
    frames = []
    for k in range(6):
        pts2 = np.concatenate([_legs(walker), _legs(chair)])
        pts = np.c_[pts2, np.full(len(pts2), 0.3)].astype(np.float32)
        laser = LaserDetections(
            np.array([walker, chair]), np.array([0.9, 0.9]), np.full(2, KIND_PAIR), np.full(2, 0.2),
            [np.arange(12), np.arange(12, 24)],
        )  # fmt: skip
        image = None
        if k % 2 == 0:
            uv, _ = CAMERA.project(np.array([[2.85, -0.03, 0.0], [2.85, 0.47, 1.7]]))
            image = ImageDetections(
                np.array([[*uv.min(axis=0), *uv.max(axis=0)]]), np.array([0.9]), None, 1920, 960
            )
        frames.append(
            PerceptionFrame(
                k,
                k * 100_000_000,
                Pose2(),
                image,
                None,
                laser,
                np.full(2, 0.3),
                np.zeros((1, 2)),
                *compact_beams(pts, np.zeros(len(pts)), 1),
            )
        )
    out = fuse_all(frames, CAMERA, LabelOptions(), static_map=smap, body_maps=[])
    for f in out:
        assert (np.hypot(*(f.observations.xy - walker).T) < 0.05).sum() == 1, f.index
        assert not (np.hypot(*(f.observations.xy - chair).T) < 0.05).any(), f.index
