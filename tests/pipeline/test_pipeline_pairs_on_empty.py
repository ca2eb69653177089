"""Leg pairs on spots seen empty: someone standing by a wall, whom the leg model scores low (something
stands less than a metre behind their legs), is found where the moving robot saw that spot empty before;
a chair by the same wall, there all along, is not."""

from __future__ import annotations

import numpy as np
import pytest

from studio.detect.laser import get_laser_detector
from studio.detect.laser.static_map import StaticMap
from studio.geometry.se import Pose2
from studio.pipeline import LabelOptions
from studio.pipeline.label import _EMPTY_LEG_SCORE, _pairs_on_empty, fuse_all
from studio.pipeline.perceive import PerceptionFrame, compact_beams, detect_again, odom_scans

ANGLES = np.radians(np.arange(-135.0, 135.0, 0.25))
WALL_Y = 2.0
PERSON = np.array([[6.0, 1.4], [6.2, 1.4]])  # two legs 0.6 m in front of the wall, from frame 80 on
CHAIR = np.array([[3.0, 1.45], [3.25, 1.45]])  # two chair legs by the same wall, all along
LEG_R, CHAIR_R = 0.06, 0.05


def _scan(x0: float, circles: list[tuple[np.ndarray, float]], rng: np.random.Generator) -> np.ndarray:
    """Points (M, 3) in the base frame of a robot at (x0, 0) facing +x: a 0.25° scanner with 1 cm of range
    noise in a corridor (walls at y = ±2 m), with the given leg circles."""
    d = np.c_[np.cos(ANGLES), np.sin(ANGLES)]
    t = np.full(len(ANGLES), np.inf)
    for wall in (WALL_Y, -WALL_Y):
        with np.errstate(divide="ignore"):
            tw = wall / d[:, 1]
        t = np.where((tw > 0) & np.isfinite(tw), np.minimum(t, tw), t)
    o = np.array([x0, 0.0])
    for centres, r in circles:
        for c in centres:
            oc = o - c
            b = d @ oc
            disc = b**2 - (oc @ oc - r**2)
            hit = -b - np.sqrt(np.maximum(disc, 0.0))
            t = np.where((disc > 0) & (hit > 0), np.minimum(t, hit), t)
    t = t + rng.normal(0.0, 0.01, len(t))
    t = np.where(t <= 10.0, t, np.nan)
    return np.c_[t * d[:, 0], t * d[:, 1], np.full(len(t), 0.3)].astype(np.float32)


def _frame(i: int, pose: Pose2, pts: np.ndarray, laser=None, z=None) -> PerceptionFrame:
    """Frame ``i`` (10 Hz) of one scanner at the base frame's origin."""
    z = np.zeros(0) if z is None else z
    return PerceptionFrame(
        i,
        i * 100_000_000,
        pose,
        None,
        None,
        laser,
        z,
        np.zeros((1, 2)),
        *compact_beams(pts, np.zeros(len(pts)), 1),
    )


@pytest.fixture(scope="module")
def corridor() -> tuple[list[PerceptionFrame], StaticMap]:
    """160 frames at 10 Hz of a robot driving 0.6 m/s down the corridor, with the detector's people."""
    rng = np.random.default_rng(7)
    detector = get_laser_detector("classical")
    frames = []
    for i in range(160):
        pose = Pose2(0.06 * i, 0.0, 0.0)
        circles = [(CHAIR, CHAIR_R)] + ([(PERSON, LEG_R)] if i >= 80 else [])
        pts = _scan(pose.x, circles, rng)
        frames.append(_frame(i, pose, pts, *detect_again(_frame(i, pose, pts), detector)))
    return frames, StaticMap.build(s for f in frames for s in odom_scans(f))


def _found(f: PerceptionFrame, xy_base: np.ndarray, where: np.ndarray) -> bool:
    base = f.robot_pose.inverse().apply(where.mean(0))
    return bool(len(xy_base)) and float(np.min(np.hypot(*(xy_base - base).T))) <= 0.2


def test_someone_by_a_wall_is_found_where_the_spot_was_seen_empty(corridor) -> None:
    frames, smap = corridor
    weak = get_laser_detector("classical", leg_min_score=_EMPTY_LEG_SCORE)
    assert smap.seen_empty(PERSON).all()  # the robot passed the spot before the person came
    assert not smap.seen_empty(CHAIR).any()
    plain = with_rule = chair = 0
    for f in frames[85:130]:  # the robot passes the person at frame 100; from 131 on they are behind it
        assert f.laser is not None
        laser, z, static = _pairs_on_empty(f, f.laser, f.laser_z, np.zeros(len(f.laser), bool), smap, weak)
        assert len(laser) == len(z) == len(static) >= len(f.laser)
        assert laser.segments is not None
        assert len(laser.segments) == len(laser)
        plain += _found(f, f.laser.xy, PERSON)
        with_rule += _found(f, laser.xy, PERSON)
        chair += _found(f, laser.xy[len(f.laser) :], CHAIR)
    # measured: the leg model alone finds the person in 5 of these 45 frames, with the rule in 39
    assert plain <= 8
    assert with_rule >= 35
    assert chair == 0


def test_fusion_without_a_camera_keeps_them(corridor) -> None:
    frames, _ = corridor
    fused = fuse_all(frames, None, LabelOptions(sources="laser"))
    found = sum(
        _found(f, r.observations.xy, PERSON) for f, r in zip(frames[85:130], fused[85:130], strict=True)
    )
    assert found >= 35  # measured: 39 (5 without the rule)


def test_a_robot_that_never_moves_sees_nothing_empty() -> None:
    rng = np.random.default_rng(3)
    frames = []
    for i in range(60):
        pts = _scan(2.0, [(PERSON, LEG_R)] if i >= 30 else [], rng)
        frames.append(_frame(i, Pose2(2.0, 0.0, 0.0), pts))
    smap = StaticMap.build(s for f in frames for s in odom_scans(f))
    assert not smap.seen_empty(PERSON).any()
