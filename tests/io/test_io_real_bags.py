"""Real ROS1 bags of ../shared/data/leg_tracker: reading, decoding, laser-only sync, bad input."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from io_testdata import DATA, bag

from studio.io import (
    RecordingError,
    SyncReport,
    TfBuffer,
    TfError,
    count_frames,
    decode_scan,
    iter_frames,
    open_recording,
    parse_rig,
)


def test_decode_scans_demo_stationary() -> None:
    with open_recording(bag("demo_stationary_simple_environment.bag")) as rec:
        assert rec.kind == "ros1"
        assert rec.topics["/scan"].msgtype == "sensor_msgs/msg/LaserScan"
        assert rec.topics["/scan"].count == 1265
        assert rec.start_ns < rec.end_ns
        assert 125e9 < rec.end_ns - rec.start_ns < 127e9
        stamps = []
        for raw in rec.messages(["/scan"]):
            scan = decode_scan(rec.decode(raw), raw.log_ns)
            assert len(scan) == 512
            assert scan.ranges.dtype == np.float32
            assert scan.frame_id == "laser"
            stamps.append(scan.stamp_ns)
        assert len(stamps) == 1265
        assert np.all(np.diff(stamps) > 0)
        np.testing.assert_allclose(scan.angle_min, -np.pi / 2, atol=1e-6)
        np.testing.assert_allclose(scan.angles()[-1], scan.angle_min + 511 * scan.angle_increment)
        pts, ok = scan.points(), scan.valid()
        assert pts.shape == (512, 2)
        assert ok.any()
        assert not ok.all()
        assert np.isfinite(pts[ok]).all()
        assert np.isnan(pts[~ok]).all()
        r = np.hypot(pts[ok, 0], pts[ok, 1])
        np.testing.assert_allclose(r, scan.ranges[ok], rtol=1e-6)


def test_decode_scans_three_scanners_negative_2() -> None:
    with open_recording(bag("negative_2.bag")) as rec:
        topics = ["/left_scan", "/rear_scan", "/right_scan"]
        assert sorted(rec.topics) == topics
        frames: dict[str, set[str]] = {t: set() for t in topics}
        n = 0
        for raw in rec.messages(topics):
            scan = decode_scan(rec.decode(raw))
            assert len(scan) == 768
            np.testing.assert_allclose(scan.angle_min, -3 * np.pi / 4, atol=1e-6)
            frames[raw.topic].add(scan.frame_id)
            n += 1
        assert n == 435 + 435 + 434
        assert frames == {
            "/left_scan": {"left_laser"},
            "/rear_scan": {"rear_laser"},
            "/right_scan": {"right_laser"},
        }


def test_custom_types_decode() -> None:
    """Extracted bags carry PoseArray / MarkerArray with their own definitions; all of it decodes."""
    with open_recording(bag("legs_labelled/positive_2_extracted.bag")) as rec:
        assert rec.topics["/leg_cluster_positions"].msgtype == "geometry_msgs/msg/PoseArray"
        n = 0
        for raw in rec.messages():
            msg = rec.decode(raw)
            if raw.topic == "/leg_cluster_positions":
                assert hasattr(msg, "poses")
            n += 1
        assert n == 3 * 83


def test_laser_only_frames_on_real_bag() -> None:
    rig = parse_rig({"base_frame": "laser", "lasers": [{"topic": "/scan"}]})
    with open_recording(bag("demo_stationary_simple_environment.bag")) as rec:
        report = SyncReport()
        frames = list(iter_frames(rec, rig, report=report))
        assert count_frames(rec, rig) == 1265
    assert len(frames) == 1265
    assert report.frames == 1265
    assert report.candidates == 1265
    assert [f.index for f in frames[:3]] == [0, 1, 2]
    for f in frames[::100]:
        assert f.panorama is None
        assert len(f.scans) == 1
        s = f.scans[0]
        assert s.topic == "/scan"
        assert s.scan.stamp_ns == f.stamp_ns
        np.testing.assert_allclose(s.sensor_pose.matrix(), np.eye(4))
        assert f.robot_pose.x == 0
        assert f.robot_pose.yaw == 0
        pb = s.points_base()
        assert pb.shape == (int(s.scan.valid().sum()), 3)
        assert np.isfinite(pb).all()
    assert any("no odometry" in w for w in report.warnings)
    assert "frames: 1265 yielded of 1265" in report.summary()
    d = report.as_dict()
    assert d["frames"] == 1265
    assert d["lasers"]["/scan"]["attached"] == 1265
    json.dumps(d)


def test_multi_laser_rig_with_poses_and_topic_without_slash() -> None:
    rig = parse_rig(
        {
            "base_frame": "left_laser",
            "lasers": [
                {"topic": "/left_scan"},
                {"topic": "/right_scan", "pose": {"x": 0.0, "y": -0.5, "yaw": -1.57}},
                {"topic": "/rear_scan", "pose": {"x": -0.5, "yaw": 3.14}},
            ],
            "sync": {"max_dt_s": 0.07},
        }
    )
    with open_recording(bag("negative_2.bag")) as rec:
        report = SyncReport()
        frames = list(iter_frames(rec, rig, report=report))
    assert len(frames) == 435
    st = report.lasers
    assert st["/left_scan"].attached == 435
    for t in ("/right_scan", "/rear_scan"):
        assert st[t].attached + st[t].missing == 435
        assert st[t].attached > 300
        assert st[t].max_dt_ns <= 70_000_000
    with_rear = next(f for f in frames if f.scan("/rear_scan") is not None)
    rear = with_rear.scan("/rear_scan")
    assert rear is not None
    np.testing.assert_allclose(rear.sensor_pose.t, (-0.5, 0.0, 0.0))
    # old bag: topic 'right_scan' has no leading '/', the rig may write it either way
    rig1 = parse_rig({"base_frame": "right_laser", "lasers": [{"topic": "/right_scan"}]})
    with open_recording(bag("positive/positive_2.bag")) as rec:
        assert rec.resolve_topic("/right_scan") == "right_scan"
        assert sum(1 for _ in iter_frames(rec, rig1)) == 243


def test_missing_file(tmp_path: Path) -> None:
    with pytest.raises(RecordingError, match="recording not found"):
        open_recording(tmp_path / "nothing.bag")
    (tmp_path / "x.txt").write_text("hi")
    with pytest.raises(RecordingError, match="unknown recording format"):
        open_recording(tmp_path / "x.txt")


def _read_all(path: Path) -> int:
    n = 0
    with open_recording(path) as rec:
        for raw in rec.messages():
            rec.decode(raw)
            n += 1
    return n


def test_an_empty_bag_file_is_one_clear_error(tmp_path: Path) -> None:
    p = tmp_path / "cut.bag"
    p.write_bytes(b"")
    with pytest.raises(RecordingError) as info:
        _read_all(p)
    msg = str(info.value)
    assert str(p) in msg
    assert "\n" not in msg


@pytest.mark.parametrize("fraction", [0.1, 0.5, 0.99])
def test_truncated_bag_reads_as_far_as_it_goes(tmp_path: Path, fraction: float) -> None:
    """A bag cut short has lost its index: its whole messages are read (``studio.io.ros1_unindexed``)."""
    src = bag("negative_2.bag")
    data = src.read_bytes()
    p = tmp_path / "cut.bag"
    p.write_bytes(data[: int(len(data) * fraction)])
    with open_recording(src) as rec:
        whole = [(m.topic, m.log_ns) for m in rec.messages()]
    with open_recording(p) as rec:
        got = [(m.topic, m.log_ns) for m in rec.messages()]
        assert rec.notes
        assert str(p) in rec.notes[0]
    assert 0 < len(got) < len(whole)
    assert set(got) <= set(whole)


def test_corrupt_chunk_reads_as_recording_error(tmp_path: Path) -> None:
    """Garbage in the middle of the data (index intact): an error while reading, still RecordingError."""
    src = bag("positive/positive_2.bag")
    data = bytearray(src.read_bytes())
    mid = len(data) // 2
    data[mid : mid + 4096] = b"\x07" * 4096
    p = tmp_path / "garbled.bag"
    p.write_bytes(bytes(data))
    with pytest.raises(RecordingError, match=r"garbled\.bag"):
        _read_all(p)


def test_wrong_topic_names_list_the_bag_topics() -> None:
    rig = parse_rig({"base_frame": "laser", "lasers": [{"topic": "/scan_front"}]})
    with open_recording(bag("demo_stationary_simple_environment.bag")) as rec:
        with pytest.raises(
            RecordingError, match=r"laser topic '/scan_front' is not in the recording .*/scan"
        ):
            next(iter_frames(rec, rig))
        cam = parse_rig({"base_frame": "laser", "camera": {"topic": "/scan"}})
        with pytest.raises(RecordingError, match="carries sensor_msgs/msg/LaserScan, expected"):
            next(iter_frames(rec, cam))
        odo = parse_rig(
            {"base_frame": "laser", "lasers": [{"topic": "/scan"}], "odometry": {"topic": "/odom"}}
        )
        with pytest.raises(RecordingError, match="odometry topic '/odom'"):
            next(iter_frames(rec, odo))


def test_rig_frame_not_in_tf() -> None:
    with open_recording(bag("negative_2.bag")) as rec:
        assert len(TfBuffer.from_recording(rec)) == 0
        rig = parse_rig({"base_frame": "base_link", "lasers": [{"topic": "/left_scan"}]})
        with pytest.raises(TfError, match=r"laser /left_scan \(frame 'left_laser'\).*base_link"):
            next(iter_frames(rec, rig))
        rig = parse_rig(
            {"base_frame": "left_laser", "lasers": [{"topic": "/left_scan"}], "odometry": {"tf": "odom"}}
        )
        with pytest.raises(TfError, match="frame 'odom' is not in the TF tree"):
            next(iter_frames(rec, rig))


def test_every_real_bag_opens() -> None:
    if not DATA.exists():
        pytest.skip("real data not available")
    bags = sorted(DATA.rglob("*.bag"))
    assert len(bags) >= 10
    for p in bags:
        with open_recording(p) as rec:
            assert rec.topics
            assert all(t.count > 0 for t in rec.topics.values())
