"""A scan that took time while the robot turned: each beam is placed from where the scanner was then."""

from __future__ import annotations

from pathlib import Path
from types import SimpleNamespace as NS  # noqa: N814

import numpy as np
import pytest
from io_testdata import T0

from studio.geometry.se import Pose2, Pose3
from studio.io import LaserScan, Odometry, RecordingWriter, SyncReport, iter_frames, open_recording, parse_rig
from studio.io.base import ScanInBase
from studio.io.decode import decode_scan

SPIN = 2.0  # rad/s, the robot turns on the spot
N = 360  # beams over the full circle
SWEEP_S = 0.1  # a 10 Hz scanner
WALL_Y = 3.0  # a wall along y = 3 m of the odometry frame


def _wall_scan(stamp_ns: int, ti: float) -> LaserScan:
    """The scan a scanner at the base origin takes of the wall while the robot spins: beam i leaves at
    ``stamp + i · SWEEP_S / (N - 1)`` (``ti`` is what the message says about it)."""
    a = -np.pi + 2 * np.pi * np.arange(N) / N
    t = (stamp_ns - T0) * 1e-9 + np.arange(N) * SWEEP_S / (N - 1)
    world = SPIN * t + a  # each beam's direction in the odometry frame at its own time
    with np.errstate(divide="ignore"):
        r = np.where(np.sin(world) > 0.2, WALL_Y / np.sin(world), np.inf)
    return LaserScan(stamp_ns, "laser", -np.pi, 2 * np.pi / N, r.astype(np.float32), 0.05, 30.0, None, ti)


def _wall_errors(tmp_path: Path, ti: float) -> np.ndarray:
    path = tmp_path / f"spin-{ti:g}.mcap"
    with RecordingWriter(path) as w:
        for k in range(51):  # odometry at 50 Hz for 1 s
            stamp = T0 + k * 20_000_000
            w.write_odometry(
                "/odom", Odometry(stamp, "odom", "base_link", Pose2(0.0, 0.0, SPIN * k * 0.02)), wz=SPIN
            )
        for k in range(1, 8):
            w.write_scan("/scan", _wall_scan(T0 + k * 100_000_000, ti))
    rig = parse_rig(
        {
            "base_frame": "base_link",
            "odometry": {"topic": "/odom"},
            "lasers": [{"topic": "/scan", "pose": {}}],
        }
    )
    errs = []
    with open_recording(path) as rec:
        for f in iter_frames(rec, rig, report=SyncReport()):
            (sib,) = f.scans
            pts = sib.points_base()[:, :2]
            world = f.robot_pose.apply(pts)
            errs.append(np.abs(world[:, 1] - WALL_Y))
    assert errs
    return np.concatenate(errs)


def test_a_spinning_robot_s_scan_is_straightened_by_the_time_between_beams(tmp_path: Path) -> None:
    # 2 rad/s over a 0.1 s sweep: the last beam left 0.2 rad later than an instantaneous scan assumes
    assert np.max(_wall_errors(tmp_path, SWEEP_S / (N - 1))) < 0.01
    assert np.max(_wall_errors(tmp_path, 0.0)) > 0.3  # a driver that does not say: the wall is bent


def test_deskewed_spreads_the_sweep_s_motion_over_the_beams() -> None:
    scan = LaserScan(
        T0, "laser", 0.0, np.pi / 2, np.array([1.0, 1.0, 1.0], np.float32), 0.0, 10.0, None, 0.05
    )
    start = Pose3.from_xyz_rpy(0.5, 0.0, 0.3)
    end = start.compose(Pose3.from_xyz_rpy(0.2, 0.0, 0.0, yaw=0.4))
    sib = ScanInBase("/scan", scan, start, end)
    got = sib.deskewed(scan.points())
    np.testing.assert_allclose(got[0], [1.0, 0.0], atol=1e-12)  # the first beam: as measured
    mid = Pose3.from_xyz_rpy(0.1, 0.0, 0.0, yaw=0.2).apply(np.array([[0.0, 1.0, 0.0]]))[0, :2]
    np.testing.assert_allclose(got[1], mid, atol=1e-12)  # halfway: half the motion
    np.testing.assert_allclose(ScanInBase("/scan", scan, start).deskewed(scan.points()), scan.points())


def test_the_time_between_beams_is_read_and_a_placeholder_ignored() -> None:
    def msg(ti: float) -> NS:
        return NS(
            header=NS(stamp=NS(sec=1, nanosec=0), frame_id="laser"),
            angle_min=0.0,
            angle_increment=0.01,
            range_min=0.0,
            range_max=10.0,
            ranges=[1.0] * 100,
            intensities=[],
            time_increment=ti,
        )

    assert decode_scan(msg(1e-4)).time_increment == pytest.approx(1e-4)
    assert decode_scan(msg(0.5)).time_increment == 0.0  # a 50 s sweep is no time
    assert decode_scan(msg(float("nan"))).time_increment == 0.0


@pytest.mark.parametrize(("roll", "step"), [(0.0, 1.0), (np.pi, 1.0), (0.0, -1.0), (np.pi, -1.0)])
def test_the_beam_clock_follows_the_upright_beam_order(roll: float, step: float) -> None:
    """Beam i at the scan's stamp + i · time_increment, after the frame stamp, in the order
    :meth:`ScanInBase.upright` gives the beams (counter-clockwise, whichever way the scanner turns)."""
    n = 5
    ranges = (1.0 + 0.1 * np.arange(n)).astype(np.float32)  # tells the beams apart
    scan = LaserScan(T0 + 20_000_000, "laser", 0.0, step * 0.1, ranges, 0.0, 10.0, None, 0.01)
    sib = ScanInBase("/scan", scan, Pose3.from_xyz_rpy(0.0, 0.0, 0.3, roll=roll))
    _, pts, _ = sib.upright()
    beam = np.round((np.hypot(pts[:, 0], pts[:, 1]) - 1.0) / 0.1).astype(int)
    assert sorted(beam) == list(range(n))
    a, b = sib.beam_clock(T0)
    np.testing.assert_allclose(a + b * np.arange(n), 0.02 + 0.01 * beam, atol=1e-9)
    assert np.all(np.diff(np.unwrap(np.arctan2(pts[:, 1], pts[:, 0]))) > 0)  # counter-clockwise


def test_without_odometry_scan_matching_s_motion_places_and_deskews_the_scans() -> None:
    """A robot without odometry spinning before the wall: the synchroniser knows no motion, so its scans are
    bent; placed with a constant-velocity twist (scan matching's, between the last frames) they are
    straight, and a scan taken before the frame stamp is placed where the robot was then."""
    from studio.io import Frame
    from studio.pipeline.perceive import _moved, _twist, moving_on

    stamp = T0 + 300_000_000
    spin = (0.0, 0.0, SPIN)
    for late_s in (0.0, 0.03):  # the frame stamp after the scan's
        scan = _wall_scan(stamp, SWEEP_S / (N - 1))
        frame = Frame(
            0, stamp + round(late_s * 1e9), None, (ScanInBase("/scan", scan, Pose3.identity()),), Pose2()
        )
        robot = Pose2(0.0, 0.0, SPIN * (0.3 + late_s))  # the robot at the frame stamp, odometry frame
        for twist, bent in ((spin, False), ((0.0, 0.0, 0.0), True)):
            (sib,) = moving_on(frame, twist).scans
            world = robot.apply(sib.points_base()[:, :2])
            err = np.abs(world[:, 1] - WALL_Y)
            assert (err.max() > 0.3) if bent else (err.max() < 0.01), (late_s, twist)
    # the twist that takes one pose to the next is the one _moved goes with
    twist = (0.8, -0.2, 0.7)
    step = _moved(twist, 0.1).to_pose2()
    start = Pose2(1.0, 2.0, 0.3)
    got = _twist((0, start), (100_000_000, start.compose(step)))
    np.testing.assert_allclose(got, twist, atol=1e-9)


def test_odometry_messages_that_cannot_be_decoded_are_counted_with_the_first_reason(tmp_path: Path) -> None:
    path = tmp_path / "bad-odom.mcap"
    with RecordingWriter(path) as w:
        for k in range(51):
            x = float("nan") if k in (10, 30) else 0.0  # two messages with no position
            w.write_odometry("/odom", Odometry(T0 + k * 20_000_000, "odom", "base_link", Pose2(x, 0.0, 0.0)))
        for k in range(1, 8):
            w.write_scan("/scan", _wall_scan(T0 + k * 100_000_000, 0.0))
    rig = parse_rig(
        {
            "base_frame": "base_link",
            "odometry": {"topic": "/odom"},
            "lasers": [{"topic": "/scan", "pose": {}}],
        }
    )
    report = SyncReport()
    with open_recording(path) as rec:
        frames = list(iter_frames(rec, rig, report=report))
    assert len(frames) == 7  # the other 49 messages carry the motion
    (warning,) = [w for w in report.warnings if "odometry" in w]
    assert warning.startswith("2 odometry messages on /odom could not be decoded (the first: ")
    assert "non-finite position" in warning
