"""What pass one keeps of a frame's beams: x, y per beam and a plane per scanner, not a height per beam."""

from __future__ import annotations

import numpy as np
import pytest

from studio.detect.laser import get_laser_detector
from studio.geometry.se import Pose2, Pose3
from studio.io.base import Frame, LaserScan, ScanInBase
from studio.pipeline.perceive import PerceptionFrame, compact_beams, detect_again, laser_in_base

STAMP = 1_000_000_000


def _scan(topic: str, pose: Pose3, rng: np.random.Generator) -> ScanInBase:
    """A 270° scan of a room 4 m across, with a person's two legs 1.5 m ahead and some beams lost."""
    ang = np.deg2rad(np.arange(-135.0, 135.0, 0.5))
    r = np.full(len(ang), 4.0) + rng.normal(0.0, 0.01, len(ang))
    legs = np.abs(ang - np.deg2rad(3.0)) < np.deg2rad(2.0), np.abs(ang + np.deg2rad(3.0)) < np.deg2rad(2.0)
    for leg in legs:
        r[leg] = 1.5
    r[rng.random(len(ang)) < 0.1] = np.nan  # no return
    scan = LaserScan(STAMP, topic, float(ang[0]), float(np.deg2rad(0.5)), r.astype(np.float32), 0.05, 20.0)
    return ScanInBase(topic, scan, pose)  # type: ignore[call-arg]


def _frame(poses: list[Pose3]) -> Frame:
    rng = np.random.default_rng(3)
    scans = tuple(_scan(f"/scan{k}", pose, rng) for k, pose in enumerate(poses))
    return Frame(0, STAMP, None, scans, Pose2())


LEVEL = Pose3.from_xyz_rpy(0.3, 0.0, 0.25, 0.0, 0.0, 0.0)
TILTED = Pose3.from_xyz_rpy(-0.3, 0.1, 0.4, 0.03, -0.08, np.pi)  # a scanner mounted 5° off level, facing back
UPSIDE_DOWN = Pose3.from_xyz_rpy(0.0, 0.2, 0.6, np.pi, 0.0, 1.0)


@pytest.mark.parametrize(
    "poses", [[LEVEL], [LEVEL, TILTED], [TILTED, UPSIDE_DOWN]], ids=["level", "two", "tilted"]
)
def test_the_kept_beams_give_back_every_beam_and_its_height(poses: list[Pose3]) -> None:
    frame = _frame(poses)
    laser, laser_z, points, origins, owner = laser_in_base(frame, get_laser_detector("classical"))
    assert points.shape[1] == 3
    assert np.isnan(points[:, 0]).any()
    f = PerceptionFrame(
        0, STAMP, Pose2(), None, None, laser, laser_z, origins, *compact_beams(points, owner, len(poses))
    )
    assert f.points.shape == (len(points), 2)
    assert f.points.dtype == np.float32
    np.testing.assert_array_equal(f.points, points[:, :2])  # NaN where no return, as before
    np.testing.assert_array_equal(f.origin_of_point, owner)
    hit = np.isfinite(points[:, 0])
    z = f.points_z()
    if poses == [LEVEL]:  # a level scanner's height is kept exactly
        np.testing.assert_array_equal(z[hit].astype(np.float32), points[hit, 2])
    np.testing.assert_allclose(z[hit], points[hit, 2], atol=1e-5)  # a tilted one's to float precision
    sel = np.flatnonzero(hit)[::7]
    np.testing.assert_allclose(f.points_z(sel), points[sel, 2], atol=1e-5)
    # the detector run again on the kept beams puts each person at the height of its beams
    again, again_z = detect_again(f, get_laser_detector("classical"))
    assert len(again.xy)
    assert again.segments is not None
    np.testing.assert_allclose(again_z, [np.nanmedian(points[s, 2]) for s in again.segments], atol=1e-5)


def test_a_scan_with_no_return_keeps_its_beams_and_a_flat_plane() -> None:
    points = np.full((5, 3), np.nan, np.float32)
    kept, sizes, planes = compact_beams(points, np.zeros(5, np.int16), 2)
    assert kept.shape == (5, 2)
    assert np.isnan(kept).all()
    np.testing.assert_array_equal(sizes, [5, 0])
    np.testing.assert_array_equal(planes, np.zeros((2, 3)))


def test_beams_that_do_not_run_scanner_by_scanner_are_refused() -> None:
    with pytest.raises(ValueError, match="scanner by scanner"):
        compact_beams(np.zeros((4, 3), np.float32), np.array([0, 1, 0, 1]), 2)


def test_the_kept_beams_take_a_third_less_memory() -> None:
    frame = _frame([LEVEL, TILTED])
    _, _, points, _, owner = laser_in_base(frame, get_laser_detector("classical"))
    kept, sizes, planes = compact_beams(points, owner, 2)
    before = points.nbytes + owner.nbytes
    after = kept.nbytes + sizes.nbytes + planes.nbytes
    assert after < 0.65 * before
