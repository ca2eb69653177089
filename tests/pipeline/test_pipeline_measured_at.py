"""Each fused observation carries when its beams were measured (a scan off the frame stamp, a beam late in a
sweep) to the tracker; an image-only one was measured at the stamp."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from studio.detect.image import ImageDetections
from studio.detect.laser import KIND_PAIR, LaserDetections
from studio.geometry import EquirectCamera
from studio.geometry.se import Pose2, Pose3
from studio.pipeline import LabelOptions
from studio.pipeline.label import _to_odom, fuse_all
from studio.pipeline.perceive import PerceptionFrame, compact_beams

CAMERA = EquirectCamera(1920, 960, Pose3.from_xyz_rpy(0.0, 0.0, 1.2, 0.0, 0.0, 0.0))
WALKER = np.array([3.0, 0.0])  # the laser sees them (and the camera)
SEEN = np.array([0.0, 4.0])  # only the camera sees them


def _box(c: np.ndarray) -> np.ndarray:
    side = np.array([-c[1], c[0]]) / np.hypot(*c) * 0.25
    uv, _ = CAMERA.project(np.array([[*(c - side), 0.0], [*(c + side), 1.7]]))
    return np.array([*uv.min(axis=0), *uv.max(axis=0)])


def _frame(clocks: np.ndarray | None) -> PerceptionFrame:
    a = np.linspace(-0.6, 0.6, 6) + np.pi
    legs = [WALKER + off + 0.06 * np.stack([np.cos(a), np.sin(a)], 1) for off in ([0, 0.1], [0, -0.1])]
    far = np.array([[-4.0, -4.0], [-4.0, -4.1]])  # a wall far away, measured at another time
    pts = np.zeros((14, 3), np.float32)
    pts[:, :2] = np.concatenate([*legs, far])
    pts[:, 2] = 0.3
    laser = LaserDetections(
        WALKER[None],
        np.array([0.9]),
        np.array([KIND_PAIR]),
        np.array([0.2]),
        (np.arange(12),),
        np.array([[WALKER + np.array([0, 0.1]), WALKER - np.array([0, 0.1])]]),
    )
    image = ImageDetections(np.array([_box(WALKER), _box(SEEN)]), np.array([0.9, 0.9]), None, 1920, 960)
    owner = np.r_[np.zeros(12), np.ones(2)].astype(np.int16)  # the legs in one scan, the wall in another
    f = PerceptionFrame(
        0, 0, Pose2(), image, None, laser, np.full(1, 0.3), np.zeros((2, 2)), *compact_beams(pts, owner, 2)
    )
    f.beam_clocks = clocks
    return f


def test_a_laser_position_carries_its_beams_time_and_an_image_only_one_the_stamp() -> None:
    # the legs' scan 50 ms after the frame, its beams 4 ms apart; the wall's 40 ms before
    clocks = np.array([[0.05, 0.004], [-0.04, 0.0]])
    options = replace(LabelOptions(), static_filter=False)
    (fr,) = fuse_all([_frame(clocks)], CAMERA, options)
    obs = fr.observations
    walker = int(np.argmin(np.hypot(*(obs.xy - WALKER).T)))
    seen = int(np.argmin(np.hypot(*(obs.xy - SEEN).T)))
    assert obs.source[walker] == "fused"
    assert obs.source[seen] == "image"
    assert fr.obs_dt is not None
    assert fr.obs_dt[walker] == pytest.approx(0.05 + 0.004 * 5.5)  # its legs' beams', not the wall's
    assert fr.obs_dt[seen] == 0.0
    tracked = _to_odom(fr, None, 0.1)
    assert tracked.dt_s is not None
    assert tracked.alt_of is not None
    legs = np.flatnonzero(tracked.alt_of == walker)
    assert len(legs) == 2
    np.testing.assert_array_equal(tracked.dt_s[legs], fr.obs_dt[walker])  # its two legs: the same time
    np.testing.assert_array_equal(tracked.dt_s[: len(obs)], fr.obs_dt)
    # beams without times (a stored pass one): everything at the stamp, as before
    (plain,) = fuse_all([_frame(None)], CAMERA, options)
    assert plain.obs_dt is None
    assert _to_odom(plain, None, 0.1).dt_s is None
