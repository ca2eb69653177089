"""RecordingWriter → open_recording → iter_frames on a synthetic camera + 2 lasers + odometry + TF bag."""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np
import pytest
from io_testdata import BACK, FRONT, N_IMAGES, T0, make_scan, robot_pose, write_synthetic

from studio.geometry.se import Pose2, Pose3
from studio.io import (
    Odometry,
    RecordingError,
    RecordingWriter,
    SyncReport,
    TfBuffer,
    TfError,
    count_frames,
    decode_odometry,
    decode_panorama,
    decode_scan,
    decode_tf,
    iter_frames,
    open_recording,
    parse_rig,
)

RIG = {
    "base_frame": "base_link",
    "odometry": {"topic": "/odom"},
    "camera": {"topic": "/camera/image/compressed"},
    "lasers": [{"topic": "/scan_front"}, {"topic": "/scan_back"}],
    "sync": {"max_dt_s": 0.02},
}


def _image_index(frame_pano_mean: float) -> int:
    return round(frame_pano_mean / 5)


def test_written_file_opens_with_rosbags_anyreader(synthetic: Path) -> None:
    from rosbags.highlevel import AnyReader

    with AnyReader([synthetic]) as reader:
        counts = {c.topic: c.msgcount for c in reader.connections}
    assert counts["/camera/image/compressed"] == N_IMAGES
    assert counts["/scan_front"] == 160
    assert counts["/odom"] == 201
    assert counts["/tf_static"] == 1
    assert synthetic.is_file()
    assert not any(p.name.endswith(".tmp") for p in synthetic.parent.iterdir())


def test_messages_decode_back(synthetic: Path) -> None:
    with open_recording(synthetic) as rec:
        assert rec.kind == "ros2"
        assert rec.start_ns == T0
        assert rec.end_ns == T0 + 4_000_000_000
        raws = {}
        for raw in rec.messages():
            raws.setdefault(raw.topic, raw)
        scan = decode_scan(rec.decode(raws["/scan_back"]))
        ref = make_scan(T0 + 15_000_000, "back_laser")
        assert scan.frame_id == "back_laser"
        assert scan.stamp_ns == ref.stamp_ns
        np.testing.assert_array_equal(scan.ranges, ref.ranges)
        assert scan.angle_increment == pytest.approx(ref.angle_increment)
        pano = decode_panorama(rec.decode(raws["/camera/image/compressed"]))
        assert pano.image.shape == (32, 64, 3)
        assert pano.encoding == "jpeg"
        assert pano.encoded is not None
        assert pano.encoded[:2] == b"\xff\xd8"
        odo = decode_odometry(rec.decode(raws["/odom"]))
        assert (odo.frame_id, odo.child_frame_id, odo.stamp_ns) == ("odom", "base_link", T0)
        tfs = decode_tf(rec.decode(raws["/tf_static"]))
        assert {(p, c) for p, c, _, _ in tfs} == {
            ("base_link", "front_laser"),
            ("base_link", "back_laser"),
            ("base_link", "camera"),
        }
        tf = TfBuffer.from_recording(rec)
        np.testing.assert_allclose(
            tf.lookup("base_link", "back_laser", 0).matrix(), BACK.matrix(), atol=1e-12
        )


@pytest.mark.parametrize("odometry", [{"topic": "/odom"}, {"tf": "odom"}])
def test_frames_with_camera_two_lasers_odometry(synthetic: Path, odometry: dict) -> None:
    rig = parse_rig({**RIG, "odometry": odometry})
    report = SyncReport()
    with open_recording(synthetic) as rec:
        frames = list(iter_frames(rec, rig, report=report))
        assert count_frames(rec, rig) == N_IMAGES
    assert len(frames) == N_IMAGES == report.frames
    assert not report.dropped
    assert not report.warnings
    for k, f in enumerate(frames):
        assert f.index == k
        assert f.stamp_ns == T0 + k * 100_000_000
        assert f.panorama is not None
        assert _image_index(float(f.panorama.image.mean())) == k
        truth = robot_pose((f.stamp_ns - T0) / 1e9)
        assert f.robot_pose.x == pytest.approx(truth.x, abs=1e-9)
        assert f.robot_pose.yaw == pytest.approx(truth.yaw, abs=1e-9)
        front = f.scan("/scan_front")
        assert front is not None
        assert front.scan.stamp_ns - f.stamp_ns == 3_000_000
        # motion compensation: the laser pose at the frame stamp = T_f⁻¹ ∘ T_s ∘ T_base_laser
        ts = robot_pose((front.scan.stamp_ns - T0) / 1e9)
        T_f = Pose3.from_xyz_rpy(truth.x, truth.y, 0, 0, 0, truth.yaw)
        T_s = Pose3.from_xyz_rpy(ts.x, ts.y, 0, 0, 0, ts.yaw)
        expect = T_f.inverse().compose(T_s).compose(FRONT)
        np.testing.assert_allclose(front.sensor_pose.matrix(), expect.matrix(), atol=1e-5)  # chord vs arc
    # back scans are 15 ms after frame k and 10 ms before it: the nearest is taken (only +15 ms for frame 0)
    first = frames[0].scan("/scan_back")
    assert first is not None
    assert first.scan.stamp_ns - frames[0].stamp_ns == 15_000_000
    back = frames[5].scan("/scan_back")
    assert back is not None
    assert back.scan.stamp_ns - frames[5].stamp_ns == -10_000_000
    assert report.lasers["/scan_back"].missing == 0
    assert report.lasers["/scan_back"].max_dt_ns == 15_000_000
    # a point straight ahead of the back laser lands behind the robot in the base frame
    pts = back.points_base()
    assert pts.shape[1] == 3
    assert (pts[:, 0] < -0.35).sum() > 0


def test_camera_latency_shifts_frame_stamps(tmp_path: Path) -> None:
    p = write_synthetic(tmp_path / "late.mcap", latency_ns=30_000_000)
    rig = parse_rig({**RIG, "sync": {"max_dt_s": 0.02, "camera_latency_s": 0.03}})
    with open_recording(p) as rec:
        frames = list(iter_frames(rec, rig))
    assert [f.stamp_ns for f in frames[:3]] == [T0, T0 + 100_000_000, T0 + 200_000_000]
    assert frames[1].panorama is not None
    assert frames[1].panorama.stamp_ns == T0 + 130_000_000
    front = frames[1].scan("/scan_front")
    assert front is not None
    assert front.scan.stamp_ns == T0 + 103_000_000


def test_laser_poses_from_rig_when_no_tf(tmp_path: Path) -> None:
    p = write_synthetic(tmp_path / "notf.mcap", tf_lasers=False)
    with open_recording(p) as rec:
        with pytest.raises(TfError, match=r"laser /scan_front \(frame 'front_laser'\)"):
            next(iter_frames(rec, parse_rig(RIG)))
        rig = parse_rig(
            {
                **RIG,
                "lasers": [
                    {"topic": "/scan_front", "pose": {"x": 0.35, "z": 0.3}},
                    {"topic": "/scan_back", "pose": {"x": -0.35, "z": 0.3, "yaw": float(np.pi)}},
                ],
            }
        )
        frames = list(iter_frames(rec, rig))
    assert len(frames) == N_IMAGES
    s = frames[3].scan("/scan_back")
    assert s is not None
    assert s.sensor_pose.t[2] == pytest.approx(0.3)


def test_laser_only_rig_on_synthetic(synthetic: Path) -> None:
    rig = parse_rig({"base_frame": "base_link", "odometry": {"topic": "/odom"}, "lasers": RIG["lasers"]})
    with open_recording(synthetic) as rec:
        frames = list(iter_frames(rec, rig))
    assert len(frames) == 160
    assert all(f.panorama is None and f.scans[0].topic == "/scan_front" for f in frames)
    assert sum(1 for f in frames if f.scan("/scan_back") is not None) == 160  # back is 12 ms after front


def test_no_odometry_at_frame_stamp_is_dropped(tmp_path: Path) -> None:
    """Odometry only for the first second: later frames are dropped and counted."""
    p = tmp_path / "short_odom.mcap"
    with RecordingWriter(p) as w:
        for k in range(21):
            stamp = T0 + k * 50_000_000
            w.write_odometry("/odom", Odometry(stamp, "odom", "base_link", Pose2(0.1 * k, 0.0, 0.0)))
        for k in range(20):
            stamp = T0 + k * 100_000_000
            w.write_scan("/scan", make_scan(stamp, "laser"))
    rig = parse_rig({"base_frame": "laser", "odometry": {"topic": "/odom"}, "lasers": [{"topic": "/scan"}]})
    report = SyncReport()
    with open_recording(p) as rec:
        frames = list(iter_frames(rec, rig, report=report))
    # odometry covers 0–1.0 s, clamped up to 0.1 s beyond: frames at 0.0 … 1.1 s
    assert len(frames) == 12
    assert report.dropped["no odometry at the frame stamp"] == 8
    assert frames[3].robot_pose.x == pytest.approx(0.6)
    assert "dropped: 8" in report.summary()
    assert any("child frame 'base_link'" in w for w in report.warnings)


def test_duplicate_and_out_of_order_frames_are_dropped(tmp_path: Path) -> None:
    """Each scan written twice (a topic recorded twice, merged bags) and one logged late with an earlier
    stamp: every frame stamp comes once and in order (the tracker needs increasing stamps), the rest is
    counted, and a label run says so."""
    p = tmp_path / "dup.mcap"
    stamps = [T0 + k * 100_000_000 for k in range(20)]
    stamps[10], stamps[11] = stamps[11], stamps[10]  # logged in swapped order
    with RecordingWriter(p) as w:
        for k, stamp in enumerate(stamps):
            for j in range(2):
                w.write_scan("/scan", make_scan(stamp, "laser"), log_ns=T0 + k * 100_000_000 + j * 1000)
    rig = parse_rig({"base_frame": "laser", "lasers": [{"topic": "/scan"}]})
    report = SyncReport()
    with open_recording(p) as rec:
        frames = list(iter_frames(rec, rig, report=report))
    got = [f.stamp_ns for f in frames]
    assert got == sorted(set(got))
    assert len(got) == 19  # the late one of the swapped pair is dropped
    assert report.dropped["a duplicate or out-of-order stamp"] == 21
    assert report.dropped_note() == "21 of 40 frames dropped (a duplicate or out-of-order stamp: 21)"


def test_why_no_frame_is_one_line_naming_the_cause(tmp_path: Path) -> None:
    """Odometry stamped by another clock (1000 s off) and a recording without the anchor's messages: the
    reason, on one line."""
    p = tmp_path / "clock.mcap"
    with RecordingWriter(p) as w:
        for k in range(20):
            stamp = T0 + k * 100_000_000
            w.write_odometry("/odom", Odometry(stamp - 1000 * 10**9, "odom", "laser", Pose2(0.0, 0.0, 0.0)))
            w.write_scan("/scan", make_scan(stamp, "laser"))
    rig = parse_rig({"base_frame": "laser", "odometry": {"topic": "/odom"}, "lasers": [{"topic": "/scan"}]})
    report = SyncReport()
    with open_recording(p) as rec:
        assert list(iter_frames(rec, rig, report=report)) == []
    why = report.why_empty()
    assert "\n" not in why
    assert why.startswith("no odometry at any frame stamp: the odometry's stamps span 1699999000.000")
    assert "different clocks" in why
    empty = SyncReport(anchor="scans of /scan")
    assert empty.why_empty() == "there are no scans of /scan in the recording"


def test_upside_down_base_frame_is_refused(tmp_path: Path) -> None:
    """A base frame upside down in the odometry frame (a scanner mounted upside down named as base_frame):
    its 2-D pose would mirror every odom position, so it is one clear error."""
    p = tmp_path / "ud.mcap"
    flipped = Pose3.from_xyz_rpy(0.3, 0.0, 0.4, np.pi, 0.0, 0.0)
    with RecordingWriter(p) as w:
        w.write_tf([("base_link", "laser", T0, flipped)], static=True, log_ns=T0)
        for k in range(10):
            stamp = T0 + k * 100_000_000
            w.write_odometry("/odom", Odometry(stamp, "odom", "base_link", Pose2(0.1 * k, 0.0, 0.0)))
            w.write_scan("/scan", make_scan(stamp, "laser"))
    for base in ("laser", "base_link"):
        rig = parse_rig({"base_frame": base, "odometry": {"topic": "/odom"}, "lasers": [{"topic": "/scan"}]})
        with open_recording(p) as rec:
            if base == "laser":
                with pytest.raises(TfError, match="base_frame 'laser' is tilted 180° from upright"):
                    list(iter_frames(rec, rig))
            else:
                assert len(list(iter_frames(rec, rig))) == 10


def test_lasers_on_another_clock_than_the_camera_are_named(tmp_path: Path) -> None:
    path = write_synthetic(tmp_path / "r.mcap", latency_ns=3600 * 10**9)  # images stamped an hour late
    rig = parse_rig({k: v for k, v in RIG.items() if k != "odometry"})
    report = SyncReport()
    with open_recording(path) as rec:
        frames = list(iter_frames(rec, rig, report=report))
    assert frames
    assert all(not f.scans for f in frames)
    lines = report.unsynced()
    assert len(lines) == 2
    assert lines[0].startswith(
        "laser /scan_front: no scan within max_dt of any frame: the scans' stamps span "
    )
    assert lines[0].endswith("(are they stamped by different clocks?)")
    synced = SyncReport()
    with open_recording(write_synthetic(tmp_path / "ok.mcap")) as rec:
        list(iter_frames(rec, rig, report=synced))
    assert synced.unsynced() == []


def test_undecodable_image_is_dropped(tmp_path: Path) -> None:
    p = tmp_path / "badimg.mcap"
    _ok, jpg = cv2.imencode(".jpg", np.zeros((8, 16, 3), np.uint8))
    with RecordingWriter(p) as w:
        w.write_compressed_image("/cam", T0, "camera", jpg.tobytes())
        w.write_compressed_image("/cam", T0 + 100_000_000, "camera", b"not a jpeg at all")
        w.write_image("/cam_raw", T0, "camera", np.full((4, 8, 3), 7, np.uint8))
        w.write_compressed_image("/bad", T0, "camera", b"\xff\xd8 truncated")
        w.write_compressed_image("/bad", T0 + 100_000_000, "camera", b"")
    report, bad = SyncReport(), SyncReport()
    with open_recording(p) as rec:
        frames = list(
            iter_frames(rec, parse_rig({"base_frame": "camera", "camera": {"topic": "/cam"}}), report=report)
        )
        raw_frames = list(
            iter_frames(rec, parse_rig({"base_frame": "camera", "camera": {"topic": "/cam_raw"}}))
        )
        assert not list(
            iter_frames(rec, parse_rig({"base_frame": "camera", "camera": {"topic": "/bad"}}), report=bad)
        )
    assert bad.why_empty().startswith("none of the 2 camera images on /bad decodes (")
    assert len(frames) == 1
    assert report.dropped["undecodable image"] == 1
    why = report.first_error["undecodable image"]  # the decoder's reason is kept, and said
    assert "does not decode" in why
    assert f"1 of 2 frames dropped (undecodable image: 1 (first: {why}))" == report.dropped_note()
    assert raw_frames[0].panorama is not None
    assert raw_frames[0].panorama.encoded is None
    assert int(raw_frames[0].panorama.image[0, 0, 0]) == 7


def _write_then_fail(path: Path) -> None:
    with RecordingWriter(path) as w:
        w.write_scan("/scan", make_scan(T0, "laser"))
        raise RuntimeError("boom")


def test_writer_refuses_existing_and_leaves_nothing_on_error(tmp_path: Path) -> None:
    p = tmp_path / "x.mcap"
    p.write_bytes(b"")
    with pytest.raises(RecordingError, match="exists already"):
        RecordingWriter(p)
    q = tmp_path / "y.mcap"
    with pytest.raises(RuntimeError, match="boom"):
        _write_then_fail(q)
    assert not q.exists()
    assert sorted(x.name for x in tmp_path.iterdir()) == ["x.mcap"]
    with RecordingWriter(p, overwrite=True) as w:
        w.write_scan("/scan", make_scan(T0, "laser"))
        with pytest.raises(RecordingError, match="was written as"):
            w.write_odometry("/scan", Odometry(T0, "odom", "base", Pose2()))
    with open_recording(p) as rec:
        assert rec.topics["/scan"].count == 1


def test_rosbag2_directory_output(tmp_path: Path) -> None:
    d = tmp_path / "bagdir"
    with RecordingWriter(d) as w:
        w.write_scan("/scan", make_scan(T0, "laser"))
    assert (d / "metadata.yaml").exists()
    with open_recording(d) as rec:
        assert rec.kind == "ros2"
        assert rec.topics["/scan"].count == 1


def test_resolve_sensor_poses_from_tf(synthetic: Path) -> None:
    from io_testdata import CAMERA

    from studio.io import resolve_sensor_poses

    rig = parse_rig(RIG)
    with open_recording(synthetic) as rec:
        full = resolve_sensor_poses(rec, rig)
    assert full.camera is not None
    assert full.camera.pose is not None
    np.testing.assert_allclose(full.camera.pose.matrix(), CAMERA.matrix(), atol=1e-12)
    assert full.lasers[1].pose is not None
    np.testing.assert_allclose(full.lasers[1].pose.matrix(), BACK.matrix(), atol=1e-12)
    assert rig.camera is not None
    assert rig.camera.pose is None


def test_a_camera_tf_cannot_place_is_refused_with_the_reason(tmp_path: Path) -> None:
    from io_testdata import CAMERA

    from studio.io import LaserConfig, resolve_sensor_poses, unplaced_reason
    from studio.pipeline import LabelOptions
    from studio.pipeline.perceive import perceive

    path = write_synthetic(tmp_path / "r.mcap", tf_lasers=False)  # no static TF: 'camera' is nowhere
    rig = parse_rig(RIG)
    rig = type(rig)(**{**rig.__dict__, "lasers": (LaserConfig("/scan_front", FRONT),)})
    with open_recording(path) as rec:
        assert resolve_sensor_poses(rec, rig).camera.pose is None  # type: ignore[union-attr]
        moving, why = unplaced_reason(rec, rig, "/camera/image/compressed")
        assert not moving
        assert why == "its frame 'camera' is not connected to base_frame 'base_link' in the recording's TF"
        arm = TfBuffer()  # the camera on a joint that moves
        for k, z in enumerate((1.0, 1.2)):
            arm.add(
                "base_link", "camera", T0 + k * 10**9, Pose3(CAMERA.R, np.array([0.0, 0.0, z])), static=False
            )
        moving, why = unplaced_reason(rec, rig, "/camera/image/compressed", tf=arm)
        assert moving
        assert "'camera' moves relative to base_frame 'base_link'" in why
        from studio.commands.inspect import _pose_lines

        assert (
            "camera /camera/image/compressed: cannot be placed: its frame 'camera' is not"
            in _pose_lines(rec, rig)[0]
        )
    with pytest.raises(TfError, match=r"camera \(/camera/image/compressed\) cannot be placed: its frame"):
        perceive(path, rig, LabelOptions())
    # the laser-only path needs no camera pose
    frames, _ = perceive(path, rig, LabelOptions(sources="laser"))
    assert frames


@pytest.mark.parametrize("definitions", [True, False])
def test_ros2_sqlite3_bag(tmp_path: Path, definitions: bool) -> None:
    """A ROS2 bag in sqlite3 storage (directory and the bare .db3 file) reads like the MCAP one; without
    message definitions in the bag (as ``ros2 bag`` wrote them before Iron) the Humble types are used."""
    import sqlite3

    from rosbags.rosbag2 import StoragePlugin, Writer
    from rosbags.typesys import Stores, get_typestore

    store = get_typestore(Stores.ROS2_HUMBLE)
    d = tmp_path / "sq"
    scan = make_scan(T0, "laser")
    with Writer(d, version=9, storage_plugin=StoragePlugin.SQLITE3) as w:
        conn = w.add_connection("/scan", "sensor_msgs/msg/LaserScan", typestore=store)
        T = store.types
        for k in range(3):
            msg = T["sensor_msgs/msg/LaserScan"](
                header=T["std_msgs/msg/Header"](
                    stamp=T["builtin_interfaces/msg/Time"](sec=T0 // 10**9, nanosec=k * 100_000_000),
                    frame_id="laser",
                ),
                angle_min=scan.angle_min, angle_max=1.0, angle_increment=scan.angle_increment,
                time_increment=0.0, scan_time=0.0, range_min=scan.range_min, range_max=scan.range_max,
                ranges=scan.ranges, intensities=np.zeros(0, np.float32),
            )  # fmt: skip
            w.write(conn, T0 + k * 100_000_000, store.serialize_cdr(msg, "sensor_msgs/msg/LaserScan"))
    if not definitions:
        db = sqlite3.connect(next(d.glob("*.db3")))
        db.execute("DELETE FROM message_definitions")
        db.commit()
        db.close()
    rig = parse_rig({"base_frame": "laser", "lasers": [{"topic": "/scan"}]})
    for path in (d, next(d.glob("*.db3"))):
        with open_recording(path) as rec:
            assert rec.kind == "ros2"
            frames = list(iter_frames(rec, rig))
        assert [f.stamp_ns - T0 for f in frames] == [0, 100_000_000, 200_000_000]


def _camera_and_lasers(path: Path, *, cam_log_delay_ns: int, b_until_ns: int) -> Path:
    """Camera 10 Hz whose messages are logged ``cam_log_delay_ns`` after their stamp; laser A 40 Hz
    throughout; laser B 40 Hz only until ``T0 + b_until_ns``."""
    ok, jpg = cv2.imencode(".jpg", np.zeros((8, 16, 3), np.uint8))
    assert ok
    events: list[tuple[int, int, str]] = []
    events += [(T0 + k * 100_000_000 + cam_log_delay_ns, 0, "cam") for k in range(40)]
    events += [(T0 + k * 25_000_000 + 2_000_000, 1, "a") for k in range(160)]
    events += [(T0 + k * 25_000_000 + 4_000_000, 2, "b") for k in range(160) if k * 25_000_000 < b_until_ns]
    with RecordingWriter(path) as w:
        for log_ns, _, kind in sorted(events):
            if kind == "cam":
                w.write_compressed_image(
                    "/cam", log_ns - cam_log_delay_ns, "camera", jpg.tobytes(), log_ns=log_ns
                )
            else:
                w.write_scan(f"/{kind}", make_scan(log_ns, kind))
    return path


def test_late_logged_images_still_find_their_scans(tmp_path: Path) -> None:
    """Images logged 0.5 s after their stamp: scans for them must still be in the window."""
    p = _camera_and_lasers(tmp_path / "late.mcap", cam_log_delay_ns=500_000_000, b_until_ns=10**10)
    rig = parse_rig(
        {
            "base_frame": "a",
            "camera": {"topic": "/cam"},
            "lasers": [{"topic": "/a", "pose": {}}, {"topic": "/b", "pose": {}}],
        }
    )
    report = SyncReport()
    with open_recording(p) as rec:
        frames = list(iter_frames(rec, rig, report=report))
    assert len(frames) == 40
    assert report.lasers["/a"].missing == 0
    assert report.lasers["/b"].missing == 0
    assert all(f.scans[0].scan.stamp_ns - f.stamp_ns == 2_000_000 for f in frames)


def test_laser_that_stops_does_not_hold_frames_back(tmp_path: Path) -> None:
    """Laser B stops after 1 s: later frames come out after the window, without a B scan."""
    p = _camera_and_lasers(tmp_path / "stop.mcap", cam_log_delay_ns=0, b_until_ns=1_000_000_000)
    rig = parse_rig(
        {
            "base_frame": "a",
            "camera": {"topic": "/cam"},
            "lasers": [{"topic": "/a", "pose": {}}, {"topic": "/b", "pose": {}}],
        }
    )
    report = SyncReport()
    with open_recording(p) as rec:
        it = iter_frames(rec, rig, report=report, window_s=0.5)
        first = [next(it) for _ in range(15)]  # frames come out while reading, not only at the end
        rest = list(it)
    frames = first + rest
    assert len(frames) == 40
    with_b = [f.index for f in frames if f.scan("/b") is not None]
    assert with_b == list(range(11))  # B's last scan is at 0.979 s: within 50 ms of frames 0 … 1.0 s
    assert report.lasers["/b"].missing == 29


def test_frames_stream_while_reading(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """The first frame comes out after a few records, not after the whole recording was read."""
    p = _camera_and_lasers(tmp_path / "s.mcap", cam_log_delay_ns=0, b_until_ns=10**10)
    rig = parse_rig(
        {
            "base_frame": "a",
            "camera": {"topic": "/cam"},
            "lasers": [{"topic": "/a"}, {"topic": "/b", "pose": {}}],
        }
    )
    with open_recording(p) as rec:
        seen = 0
        orig = rec.messages

        def counting(*args: object, **kwargs: object):  # type: ignore[no-untyped-def]
            nonlocal seen
            for raw in orig(*args, **kwargs):  # type: ignore[arg-type]
                seen += 1
                yield raw

        monkeypatch.setattr(rec, "messages", counting)
        it = iter_frames(rec, rig)
        next(it)
        assert seen < 20  # of 360 records (2 more for the laser frame ids)


def test_rerun_mcap_loader_reads_the_written_file(synthetic: Path, tmp_path: Path) -> None:
    import subprocess
    import sys

    exe = Path(sys.executable).parent / "rerun"
    if not exe.exists():
        pytest.skip("rerun CLI not installed")
    out = tmp_path / "x.rrd"
    proc = subprocess.run(
        [str(exe), "mcap", "convert", str(synthetic), "-o", str(out)],
        capture_output=True, text=True, timeout=120, check=False,
    )  # fmt: skip
    assert proc.returncode == 0, proc.stderr[-2000:]
    assert out.stat().st_size > 10_000


def test_studio_label_stops_when_no_laser_scan_meets_a_frame(tmp_path: Path) -> None:
    from studio.errors import StudioError
    from studio.pipeline.label import label_recording

    path = write_synthetic(tmp_path / "r.mcap", latency_ns=3600 * 10**9)
    rig = parse_rig({k: v for k, v in RIG.items() if k != "odometry"})
    with pytest.raises(
        StudioError, match=r"no scan within max_dt of any frame.*--sources camera labels without"
    ):
        label_recording(path, rig)


def test_sources_laser_labels_a_recording_without_the_rigs_camera(tmp_path: Path) -> None:
    from studio.errors import StudioError
    from studio.pipeline import LabelOptions
    from studio.pipeline.label import label_recording

    path = write_synthetic(tmp_path / "r.mcap")
    rig = parse_rig({**RIG, "camera": {"topic": "/not/recorded"}})
    run = label_recording(path, rig, options=LabelOptions(sources="laser"))
    assert (
        "the rig's camera topic /not/recorded is not in the recording: a frame is a scan of /scan_front"
        in (" ".join(run.notes))
    )
    with open_recording(path) as rec:
        assert len(run.labels) == rec.topics["/scan_front"].count  # a frame per scan, as without a camera
    with pytest.raises(StudioError, match="camera topic '/not/recorded' is not in the recording"):
        label_recording(path, rig)  # with the camera it is needed


@pytest.mark.parametrize("mode", ["MESSAGE", "FILE"])
def test_a_compressed_ros2_bag_reads_as_its_folder_not_as_its_file(tmp_path: Path, mode: str) -> None:
    from rosbags.rosbag2 import Writer
    from rosbags.rosbag2.writer import CompressionFormat, CompressionMode
    from rosbags.typesys import Stores, get_typestore

    from studio.io import LaserScan

    store = get_typestore(Stores.ROS2_HUMBLE)
    out = tmp_path / "bag"
    w = Writer(out, version=8)
    w.set_compression(getattr(CompressionMode, mode), CompressionFormat.ZSTD)
    w.open()
    conn = w.add_connection("/scan", "sensor_msgs/msg/LaserScan", typestore=store)
    for k in range(3):
        scan = make_scan(T0 + k * 100_000_000, "laser")
        Time, Header = store.types["builtin_interfaces/msg/Time"], store.types["std_msgs/msg/Header"]
        msg = store.types["sensor_msgs/msg/LaserScan"](
            Header(Time(sec=scan.stamp_ns // 10**9, nanosec=scan.stamp_ns % 10**9), "laser"),
            scan.angle_min, 0.0, scan.angle_increment, 0.0, 0.0, scan.range_min, scan.range_max,
            scan.ranges, np.zeros(0, np.float32),
        )  # fmt: skip
        w.write(conn, scan.stamp_ns, store.serialize_cdr(msg, conn.msgtype))
    w.close()
    with open_recording(out) as rec:
        scans = [decode_scan(rec.decode(m)) for m in rec.messages(["/scan"])]
    assert [s.stamp_ns for s in scans] == [T0 + k * 100_000_000 for k in range(3)]
    assert isinstance(scans[0], LaserScan)
    (inner,) = [p for p in out.iterdir() if p.name != "metadata.yaml"]
    with pytest.raises(
        RecordingError, match=rf"is one file of the compressed ROS 2 bag .*: pass the folder {out}$"
    ):
        open_recording(inner)
