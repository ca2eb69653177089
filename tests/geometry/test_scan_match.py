"""Drift correction by scan matching (studio.geometry.scan_match) on ray-cast scans of a synthetic room."""

from __future__ import annotations

import itertools

import numpy as np
import pytest

from studio.geometry import GeometryError
from studio.geometry.scan_match import ScanMatchConfig, ScanOdometry
from studio.geometry.se import Pose2

# an L-shaped room (walls as segments x1, y1, x2, y2) with a pillar-like box and a cabinet
ROOM = np.array(
    [
        [-4, -3, 6, -3],
        [6, -3, 6, 2],
        [6, 2, 5, 2],
        [5, 2, 5, 4],
        [5, 4, -4, 4],
        [-4, 4, -4, -3],
        [0.0, -0.3, 0.4, -0.3],
        [0.4, -0.3, 0.4, 0.1],
        [0.4, 0.1, 0.0, 0.1],
        [0.0, 0.1, 0.0, -0.3],
        [4.0, -3.0, 4.0, -2.4],
        [4.0, -2.4, 5.0, -2.4],
    ],
    dtype=np.float64,
)
CORRIDOR = np.array([[-50, -1, 50, -1], [-50, 1, 50, 1]], dtype=np.float64)


def cast(walls: np.ndarray, pose: Pose2, *, n: int = 720, max_range: float = 12.0, noise: float = 0.0,
         rng: np.random.Generator | None = None) -> np.ndarray:  # fmt: skip
    """A 360° scan from ``pose`` in the base frame: (n, 2), NaN where no wall is in range."""
    ang = pose.yaw + np.linspace(-np.pi, np.pi, n, endpoint=False)
    d = np.stack([np.cos(ang), np.sin(ang)], axis=1)
    o = np.array([pose.x, pose.y])
    a, b = walls[:, :2], walls[:, 2:]
    e = b - a
    # o + t d = a + s e  →  solve per beam and wall
    den = d[:, None, 0] * e[None, :, 1] - d[:, None, 1] * e[None, :, 0]
    w = a[None] - o
    with np.errstate(divide="ignore", invalid="ignore"):
        t = (w[..., 0] * e[None, :, 1] - w[..., 1] * e[None, :, 0]) / den
        s = (w[..., 0] * d[:, None, 1] - w[..., 1] * d[:, None, 0]) / den
    t = np.where((np.abs(den) > 1e-12) & (s >= 0) & (s <= 1) & (t > 0.05), t, np.inf).min(axis=1)
    if rng is not None and noise:
        t = t + rng.normal(0.0, noise, n)
    t[t > max_range] = np.nan
    world = o + d * t[:, None]
    return pose.inverse().apply(world)


def loop_path(steps: int = 240) -> list[Pose2]:
    """Around the box in room A at ~0.5 m/s (10 Hz), turning as it goes."""
    th = np.linspace(0.0, 2 * np.pi, steps)
    x, y = 1.0 + 2.5 * np.cos(th), 0.2 + 2.0 * np.sin(th)
    yaw = np.arctan2(np.gradient(y), np.gradient(x))
    return [Pose2(float(a), float(b), float(c)) for a, b, c in zip(x, y, yaw, strict=True)]


def drifting(truth: list[Pose2], *, scale: float = 1.04, yaw_per_m: float = 0.03) -> list[Pose2]:
    """Wheel odometry with a scale error and a heading bias per metre driven."""
    out = [truth[0]]
    for a, b in itertools.pairwise(truth):
        inc = a.inverse().compose(b)
        dist = float(np.hypot(inc.x, inc.y))
        out.append(out[-1].compose(Pose2(inc.x * scale, inc.y * scale, inc.yaw + yaw_per_m * dist)))
    return out


def error(a: Pose2, b: Pose2) -> tuple[float, float]:
    rel = a.inverse().compose(b)
    return float(np.hypot(rel.x, rel.y)), float(np.degrees(abs(rel.yaw)))


def test_drifting_odometry_is_corrected() -> None:
    rng = np.random.default_rng(1)
    truth = loop_path()
    odom = drifting(truth)
    so = ScanOdometry()
    est = [so.step(cast(ROOM, p, noise=0.01, rng=rng), o) for p, o in zip(truth, odom, strict=True)]
    assert error(truth[-1], odom[-1])[0] > 0.4
    assert error(truth[-1], odom[-1])[1] > 20.0
    err = np.array([error(t, e) for t, e in zip(truth, est, strict=True)])
    # 24° of heading drift at the end of the loop; the scans keep it below a degree, 0.1° on average
    assert err[:, 0].max() < 0.05
    assert err[:, 1].max() < 1.0
    assert err[:, 1].mean() < 0.2
    assert so.matched == len(truth) - 1
    assert so.rejected == 0


def test_without_odometry_the_scans_alone_give_the_motion() -> None:
    truth = loop_path()
    so = ScanOdometry()
    est = [so.step(cast(ROOM, p), None) for p in truth]
    assert est[0] == Pose2()  # the first frame defines the world
    start = truth[0].inverse()
    err = np.array([error(start.compose(t), e) for t, e in zip(truth, est, strict=True)])
    assert err[:, 0].max() < 0.05
    assert err[:, 1].max() < 1.0


def test_a_corridor_keeps_the_odometry_along_it_and_corrects_across() -> None:
    truth = [Pose2(0.1 * k, 0.0, 0.0) for k in range(60)]
    # odometry drifts sideways and in heading, and overestimates the distance by 10 %
    odom = [Pose2(0.11 * k, 0.004 * k, 0.002 * k) for k in range(60)]
    so = ScanOdometry()
    est = [so.step(cast(CORRIDOR, p, max_range=8.0), o) for p, o in zip(truth, odom, strict=True)]
    # across the corridor and in heading the walls correct it; along it nothing can, the odometry stands
    assert abs(est[-1].y) < 0.02
    assert abs(np.degrees(est[-1].yaw)) < 0.3
    assert est[-1].x == pytest.approx(odom[-1].x, abs=0.05)


def test_nothing_to_match_falls_back_to_the_odometry() -> None:
    so = ScanOdometry()
    odom = [Pose2(0.1 * k, 0.0, 0.01 * k) for k in range(5)]
    empty = np.full((100, 2), np.nan)
    for o in odom:
        assert max(error(so.step(empty, o), o)) < 1e-9
    assert so.matched == 0
    assert so.rejected == 4


def test_a_jump_larger_than_the_correction_limit_is_rejected() -> None:
    truth = loop_path()[:20]
    so = ScanOdometry(ScanMatchConfig(max_correction=0.2))
    for p in truth[:10]:
        so.step(cast(ROOM, p), p)
    # the odometry says the robot moved 0.5 m sideways at once: the scans disagree by more than the limit
    wrong = truth[10].compose(Pose2(0.0, 0.5, 0.0))
    # the prediction stands: the corrected previous pose moved as the odometry says
    assert error(so.step(cast(ROOM, truth[10]), wrong), wrong)[0] < 0.01
    assert so.rejected == 1


def test_bad_config_is_an_error() -> None:
    with pytest.raises(GeometryError):
        ScanMatchConfig(min_match=0.6, max_match=0.5)
    with pytest.raises(GeometryError):
        ScanMatchConfig(every=0)


def test_registering_every_other_frame_follows_the_odometry_in_between() -> None:
    rng = np.random.default_rng(2)
    truth = loop_path()
    odom = drifting(truth)
    so = ScanOdometry(ScanMatchConfig(every=2))
    est = [so.step(cast(ROOM, p, noise=0.01, rng=rng), o) for p, o in zip(truth, odom, strict=True)]
    assert so.matched + so.rejected == (len(truth) - 1) // 2
    assert so.skipped == len(truth) - 1 - so.matched - so.rejected
    err = np.array([error(t, e) for t, e in zip(truth, est, strict=True)])
    assert err[:, 0].max() < 0.05
    assert err[:, 1].max() < 1.5
    # without odometry every frame is registered
    so = ScanOdometry(ScanMatchConfig(every=2))
    for p in truth[:20]:
        so.step(cast(ROOM, p), None)
    assert so.skipped == 0
