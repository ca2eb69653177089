"""Decoders (raw image encodings, Foxglove/JSON shapes) and plain (non-ROS) MCAP reading."""

from __future__ import annotations

import base64
import json
from pathlib import Path
from types import SimpleNamespace as NS  # noqa: N814 — short name keeps the message tables readable

import cv2
import numpy as np
import pytest
from io_testdata import T0

from studio.geometry.se import Pose2
from studio.io import (
    Frame,
    LaserScan,
    Panorama,
    RecordingError,
    ScanInBase,
    SyncReport,
    decode_odometry,
    decode_panorama,
    decode_scan,
    decode_tf,
    iter_frames,
    open_recording,
    parse_rig,
)

BGR = np.zeros((4, 6, 3), np.uint8)
BGR[..., 0], BGR[..., 1], BGR[..., 2] = 10, 20, 30  # B, G, R


def _stamp(ns: int) -> NS:
    return NS(sec=ns // 10**9, nanosec=ns % 10**9)


def _raw(encoding: str, data: np.ndarray, *, step: int = 0, bigendian: bool = False) -> NS:
    h, w = data.shape[:2]
    flat = np.ascontiguousarray(data).view(np.uint8).reshape(h, -1)
    if step:
        flat = np.concatenate([flat, np.zeros((h, step - flat.shape[1]), np.uint8)], axis=1)
    return NS(
        header=NS(stamp=_stamp(T0), frame_id="/cam"),
        height=h, width=w, encoding=encoding, is_bigendian=int(bigendian), step=flat.shape[1],
        data=flat.reshape(-1),
    )  # fmt: skip


@pytest.mark.parametrize(
    ("encoding", "pixels", "step", "expect"),
    [
        ("bgr8", BGR, 0, (10, 20, 30)),
        ("rgb8", BGR[..., ::-1], 0, (10, 20, 30)),
        ("rgb8", BGR[..., ::-1], 24, (10, 20, 30)),  # padded rows
        ("bgra8", np.dstack([BGR, np.full((4, 6), 255, np.uint8)]), 0, (10, 20, 30)),
        ("rgba8", np.dstack([BGR[..., ::-1], np.full((4, 6), 255, np.uint8)]), 0, (10, 20, 30)),
        ("mono8", np.full((4, 6), 77, np.uint8), 0, (77, 77, 77)),
        ("8UC1", np.full((4, 6), 77, np.uint8), 0, (77, 77, 77)),
        ("mono16", np.full((4, 6), 0x4D00, "<u2"), 0, (77, 77, 77)),
    ],
)
def test_raw_image_encodings(encoding: str, pixels: np.ndarray, step: int, expect: tuple) -> None:
    pano = decode_panorama(_raw(encoding, pixels, step=step))
    assert pano.image.shape == (4, 6, 3)
    assert pano.image.dtype == np.uint8
    assert tuple(int(v) for v in pano.image[2, 3]) == expect
    assert pano.frame_id == "cam"
    assert pano.stamp_ns == T0
    assert pano.encoded is None
    assert pano.encoding == ""


def test_big_endian_mono16() -> None:
    pano = decode_panorama(_raw("mono16", np.full((4, 6), 0x4D00, ">u2"), bigendian=True))
    assert int(pano.image[0, 0, 0]) == 77


@pytest.mark.parametrize(
    ("msg", "match"),
    [
        (_raw("32FC1", np.zeros((4, 6), np.float32)), "unsupported raw image encoding"),
        (
            NS(
                header=NS(stamp=_stamp(0), frame_id=""),
                height=4,
                width=6,
                encoding="rgb8",
                step=18,
                data=np.zeros(10, np.uint8),
            ),
            "too short",
        ),
        (
            NS(header=NS(stamp=_stamp(0), frame_id=""), format="jpeg", data=np.zeros(10, np.uint8)),
            "does not decode",
        ),
        (
            NS(header=NS(stamp=_stamp(0), frame_id=""), format="jpeg", data=np.zeros(0, np.uint8)),
            r"compressed image \(jpeg\) with no data",  # was OpenCV's assertion text
        ),
        (NS(header=NS(stamp=_stamp(0), frame_id="")), "cannot decode image"),
    ],
)
def test_bad_images(msg: NS, match: str) -> None:
    with pytest.raises(RecordingError, match=match):
        decode_panorama(msg)


def test_png_keeps_encoded_bytes() -> None:
    ok, png = cv2.imencode(".png", BGR)
    assert ok
    pano = decode_panorama(NS(header=NS(stamp=_stamp(5), frame_id="c"), format="png", data=png.reshape(-1)))
    assert pano.encoding == "png"
    assert pano.encoded == png.tobytes()
    np.testing.assert_array_equal(pano.image, BGR)


def test_zero_stamp_uses_fallback_and_scan_checks() -> None:
    msg = NS(
        header=NS(stamp=_stamp(0), frame_id="/laser"), angle_min=-1.0, angle_max=1.0, angle_increment=0.5,
        range_min=0.1, range_max=5.0, ranges=[1.0, np.nan, np.inf, 0.05, 6.0], intensities=[],
    )  # fmt: skip
    scan = decode_scan(msg, 1234)
    assert scan.stamp_ns == 1234
    assert scan.frame_id == "laser"
    assert scan.intensities is None
    assert scan.valid().tolist() == [True, False, False, False, False]
    # +inf (REP 117) and beyond range_max met nothing; NaN and below range_min say nothing
    assert scan.open().tolist() == [False, False, True, False, True]
    with pytest.raises(RecordingError, match="not a decodable laser scan"):
        decode_scan(NS(header=msg.header))


def test_ranges_over_more_than_a_full_turn_are_refused() -> None:
    """Twice the ranges of a 270° scanner would put every beam at a wrong bearing, over 540°."""
    n = 1081
    da = np.radians(270.0) / (n - 1)
    msg = NS(
        header=NS(stamp=_stamp(2), frame_id="laser"), angle_min=-np.radians(135.0),
        angle_max=np.radians(135.0), angle_increment=da, range_min=0.1, range_max=5.0, ranges=[1.0] * n,
    )  # fmt: skip
    assert len(decode_scan(msg)) == n
    msg.ranges = [1.0] * (2 * n)
    with pytest.raises(RecordingError, match=r"2162 ranges .* span 540\.2°, more than a full turn"):
        decode_scan(msg)
    msg.ranges = [1.0] * (n // 2)  # half: as ROS's tools would, beams at angle_min + i · increment
    assert len(decode_scan(msg)) == n // 2
    full = 2 * np.pi / 360
    msg.angle_increment, msg.ranges = -full, [1.0] * 361  # a full turn and its first beam again: fine
    assert len(decode_scan(msg)) == 361


def test_low_cost_scanner_conventions() -> None:
    # RPLidar-like drivers: 0.0 for "no return" with range_min 0; a range_max that cannot hold (0 or below
    # range_min) means no known limit
    msg = NS(
        header=NS(stamp=_stamp(1), frame_id="laser"), angle_min=-1.0, angle_max=1.0, angle_increment=0.5,
        range_min=0.0, range_max=0.0, ranges=[1.0, 0.0, 12.0, -1.0, np.inf],
    )  # fmt: skip
    scan = decode_scan(msg)
    assert scan.valid().tolist() == [True, False, True, False, False]
    assert scan.open().tolist() == [False, False, False, False, True]
    msg.range_min, msg.range_max = 0.2, 0.1
    assert decode_scan(msg).valid().tolist() == [True, False, True, False, False]


def test_base_types_are_checked() -> None:
    with pytest.raises(TypeError, match="stamp_ns must be an int"):
        LaserScan(1.5, "l", 0.0, 0.1, np.zeros(3), 0.0, 1.0)  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="intensities"):
        LaserScan(1, "l", 0.0, 0.1, np.zeros(3), 0.0, 1.0, np.zeros(2))
    with pytest.raises(ValueError, match="uint8"):
        Panorama(1, "c", np.zeros((2, 2), np.uint8))
    with pytest.raises(TypeError, match="robot_pose"):
        Frame(0, 1, None, (), None)  # type: ignore[arg-type]
    scan = LaserScan(1, "l", 0.0, np.pi / 2, np.array([1.0, 2.0, np.nan]), 0.0, 10.0)
    np.testing.assert_allclose(scan.points()[:2], [[1, 0], [0, 2]], atol=1e-7)
    from studio.geometry.se import Pose3

    sib = ScanInBase("/s", scan, Pose3.from_xyz_rpy(1.0, 0.0, 0.5, 0.0, 0.0, np.pi))
    np.testing.assert_allclose(sib.points_base(), [[0, 0, 0.5], [1, -2, 0.5]], atol=1e-7)


@pytest.mark.parametrize("roll", [0.0, np.pi, -np.pi + 0.05, 0.05])
@pytest.mark.parametrize("step", [0.01, -0.01])
def test_a_scanner_upside_down_is_turned_upright(roll: float, step: float) -> None:
    """Its points, mapped with the planar pose of :meth:`ScanInBase.upright`, land where the 3-D pose puts
    them, counter-clockwise whichever way the scanner was mounted and turned."""
    from studio.geometry.se import Pose3

    rng = np.random.default_rng(1)
    ranges = rng.uniform(0.5, 5.0, 300).astype(np.float32)
    ranges[::7] = np.nan
    scan = LaserScan(1, "l", -1.5 * np.sign(step), step, ranges, 0.1, 10.0)
    sib = ScanInBase("/s", scan, Pose3.from_xyz_rpy(0.3, -0.2, 0.4, roll, 0.0, 2.0))
    pose, pts, valid = sib.upright()
    assert pose.R[2, 2] > 0.9
    flat = pose.to_pose2().apply(pts[valid])
    reverse = (abs(roll) > 1) != (step < 0)
    np.testing.assert_allclose(flat, sib.points_base()[:, :2][:: -1 if reverse else 1], atol=0.03)
    (x0, y0), (x1, y1) = pts[valid][:2]
    assert x0 * y1 - y0 * x1 > 0  # counter-clockwise


def test_odometry_and_tf_shapes() -> None:
    q = NS(x=0.0, y=0.0, z=np.sin(0.25), w=np.cos(0.25))
    ros = NS(header=NS(stamp=_stamp(7), frame_id="/odom"), child_frame_id="/base_link",
             pose=NS(pose=NS(position=NS(x=1.0, y=2.0, z=0.0), orientation=q)))  # fmt: skip
    od = decode_odometry(ros)
    assert (od.frame_id, od.child_frame_id, od.stamp_ns) == ("odom", "base_link", 7)
    assert od.pose == Pose2(1.0, 2.0, pytest.approx(0.5))
    fox = NS(timestamp=NS(sec=1, nsec=5), frame_id="odom",
             pose=NS(position=NS(x=1.0, y=2.0, z=0.0), orientation=q))  # fmt: skip
    assert decode_odometry(fox).stamp_ns == 1_000_000_005
    tfm = NS(transforms=[
        NS(header=NS(stamp=_stamp(9), frame_id="/a"), child_frame_id="b",
           transform=NS(translation=NS(x=1.0, y=0.0, z=0.0), rotation=q)),
        NS(header=NS(stamp=_stamp(9), frame_id="a"), child_frame_id="c",  # zero quaternion: left out
           transform=NS(translation=NS(x=1.0, y=0.0, z=0.0), rotation=NS(x=0.0, y=0.0, z=0.0, w=0.0))),
        NS(timestamp=NS(sec=0, nsec=3), parent_frame_id="a", child_frame_id="d",
           translation=NS(x=0.0, y=1.0, z=0.0), rotation=q),
    ])  # fmt: skip
    out = decode_tf(tfm)
    assert [(p, c, s) for p, c, s, _ in out] == [("a", "b", 9), ("a", "d", 3)]


def _write_json_mcap(path: Path, sizes: list[tuple[int, int]] | None = None) -> None:
    """Five frames of a laser, a camera (``sizes``: each image's width × height, 16 × 8 by default) and TF."""
    from mcap.writer import Writer

    with path.open("wb") as f:
        w = Writer(f)
        w.start(profile="", library="studio-tests")
        ids = {}
        for topic, schema in [("/scan", "foxglove.LaserScan"), ("/cam", "foxglove.CompressedImage"),
                              ("/tf", "foxglove.FrameTransforms"), ("/other", "my.Proto")]:  # fmt: skip
            sid = w.register_schema(name=schema, encoding="jsonschema", data=b"{}")
            enc = "protobuf" if topic == "/other" else "json"
            ids[topic] = w.register_channel(topic=topic, message_encoding=enc, schema_id=sid)
        for k in range(5):
            w_px, h_px = sizes[k] if sizes else (16, 8)
            ok, jpg = cv2.imencode(".jpg", np.full((h_px, w_px, 3), 100, np.uint8))
            assert ok
            t = T0 + k * 100_000_000
            ts = {"sec": t // 10**9, "nsec": t % 10**9}
            scan = {"timestamp": ts, "frame_id": "laser", "start_angle": -1.0, "end_angle": 1.0,
                    "ranges": [1.0, 2.0, 3.0, None], "intensities": []}  # fmt: skip
            scan["ranges"][3] = 4.0
            img = {
                "timestamp": ts,
                "frame_id": "cam",
                "format": "jpeg",
                "data": base64.b64encode(jpg.tobytes()).decode(),
            }
            tf = {"transforms": [{"timestamp": ts, "parent_frame_id": "base", "child_frame_id": "laser",
                                  "translation": {"x": 0.2, "y": 0.0, "z": 0.1},
                                  "rotation": {"x": 0.0, "y": 0.0, "z": 0.0, "w": 1.0}}]}  # fmt: skip
            for topic, doc in (("/tf", tf), ("/scan", scan), ("/cam", img)):
                w.add_message(ids[topic], log_time=t, data=json.dumps(doc).encode(), publish_time=t)
            w.add_message(ids["/other"], log_time=t, data=b"\x08\x01", publish_time=t)
        w.finish()


def test_plain_json_mcap(tmp_path: Path) -> None:
    p = tmp_path / "plain.mcap"
    _write_json_mcap(p)
    rig = parse_rig({"base_frame": "base", "camera": {"topic": "/cam"}, "lasers": [{"topic": "/scan"}]})
    with open_recording(p) as rec:
        assert rec.kind == "mcap"
        assert rec.topics["/scan"].msgtype == "foxglove.LaserScan"
        assert rec.topics["/scan"].count == 5
        assert rec.start_ns == T0
        report = SyncReport()
        frames = list(iter_frames(rec, rig, report=report))
        other = next(iter(rec.messages(["/other"])))
        with pytest.raises(RecordingError, match="protobuf"):
            rec.decode(other)
    assert len(frames) == 5
    assert frames[0].panorama is not None
    s = frames[2].scans[0]
    assert len(s.scan) == 4
    assert s.scan.angle_increment == pytest.approx(2 / 3)
    np.testing.assert_allclose(s.sensor_pose.t, (0.2, 0.0, 0.1))


@pytest.mark.parametrize(
    ("sizes", "match"),
    [
        ([(16, 9)] * 5, r"16×9 px; an equirectangular panorama is twice as wide as high \(2:1\)"),
        ([(16, 8)] * 3 + [(32, 16)] * 2, "32×16 px, the first one was 16×8 px"),
    ],
    ids=["not 2:1", "size changes"],
)
def test_panoramas_that_are_not_2_to_1_or_change_size_are_an_error(
    tmp_path: Path, sizes: list[tuple[int, int]], match: str
) -> None:
    p = tmp_path / "bad_size.mcap"
    _write_json_mcap(p, sizes)
    rig = parse_rig({"base_frame": "base", "camera": {"topic": "/cam"}, "lasers": [{"topic": "/scan"}]})
    with open_recording(p) as rec, pytest.raises(RecordingError, match=match):
        list(iter_frames(rec, rig))


def test_inspect_says_when_the_camera_is_not_a_panorama(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    from studio.cli import main

    p = tmp_path / "not_pano.mcap"
    _write_json_mcap(p, [(16, 9)] * 5)
    assert main(["inspect", str(p)]) == 0
    assert "16×9, jpeg (not 2:1: studio needs an equirectangular panorama" in capsys.readouterr().out
    _write_json_mcap(p)
    assert main(["inspect", str(p)]) == 0
    out = capsys.readouterr().out
    assert "16×8, jpeg\n" in out
    assert "not 2:1" not in out


def test_studio_label_refuses_a_camera_topic_that_is_not_a_panorama(tmp_path: Path) -> None:
    import subprocess
    import sys

    p = tmp_path / "not_pano.mcap"
    _write_json_mcap(p, [(16, 9)] * 5)
    rig = tmp_path / "rig.yaml"
    rig.write_text("base_frame: base\ncamera:\n  topic: /cam\n  pose: {z: 1.0}\nlasers:\n  - topic: /scan\n")
    cmd = ["label", str(p), "--rig", str(rig), "--out", str(tmp_path / "run")]
    res = subprocess.run(
        [sys.executable, "-m", "studio.cli", *cmd],
        capture_output=True,
        text=True,
        timeout=300,
        check=False,
    )
    assert res.returncode == 2
    assert res.stderr.count("\n") == 1
    assert "2:1" in res.stderr
    assert "Traceback" not in res.stderr
    assert not (tmp_path / "run").exists()


def test_mcap_without_summary(tmp_path: Path) -> None:
    """An MCAP without statistics or chunk index: counted and read by a linear scan."""
    from mcap.writer import Writer

    p = tmp_path / "nosummary.mcap"
    with p.open("wb") as f:
        w = Writer(f, use_chunking=False, use_statistics=False, repeat_channels=False, repeat_schemas=False)
        w.start(profile="", library="t")
        sid = w.register_schema(name="x", encoding="jsonschema", data=b"{}")
        cid = w.register_channel(topic="/j", message_encoding="json", schema_id=sid)
        for k in range(3):
            w.add_message(cid, log_time=T0 + k, data=b'{"a": 1}', publish_time=T0 + k)
        w.finish()
    with open_recording(p) as rec:
        assert rec.topics["/j"].count == 3
        assert rec.end_ns == T0 + 2
        assert rec.decode(next(iter(rec.messages(["/j"])))).a == 1


def _cloud_msg(points: np.ndarray, *, big: bool = False, f8: bool = False, pad: int = 0, rows: int = 1) -> NS:
    """A PointCloud2-shaped message of ``points`` (N, 3): x, y, z at offsets 0/… plus an intensity field,
    ``rows`` rows each padded by ``pad`` bytes, either byte order, float32 or float64 coordinates."""
    code = ">" if big else "<"
    ftype = f"{code}f8" if f8 else f"{code}f4"
    size = 8 if f8 else 4
    dtype = np.dtype(
        {"names": ["x", "y", "z", "i"], "formats": [ftype] * 3 + [f"{code}f4"],
         "offsets": [0, size, 2 * size, 3 * size + 4], "itemsize": 3 * size + 12}
    )  # fmt: skip
    n = len(points) // rows
    rec = np.zeros(len(points), dtype)
    for k, c in enumerate("xyz"):
        rec[c] = points[:, k]
    row_bytes = [rec[r * n : (r + 1) * n].tobytes() + b"\0" * pad for r in range(rows)]
    fields = [
        NS(name=c, offset=o, datatype=8 if f8 else 7, count=1)
        for c, o in zip("xyz", [0, size, 2 * size], strict=True)
    ]
    fields.append(NS(name="intensity", offset=3 * size + 4, datatype=7, count=1))
    return NS(
        header=NS(stamp=_stamp(T0), frame_id="/lidar"), height=rows, width=n, fields=fields,
        is_bigendian=big, point_step=dtype.itemsize, row_step=n * dtype.itemsize + pad,
        data=b"".join(row_bytes), is_dense=False,
    )  # fmt: skip


@pytest.mark.parametrize(
    ("big", "f8", "pad", "rows"), [(False, False, 0, 1), (True, True, 0, 1), (False, False, 6, 2)]
)
def test_a_point_cloud_is_sliced_into_a_planar_scan(big: bool, f8: bool, pad: int, rows: int) -> None:
    from studio.io.base import CloudSlice

    pts = np.array(
        [
            [2.0, 0.0, 0.0],  # ahead, in the band
            [3.0, 0.0, 0.1],  # the same bearing, farther: the nearer one is the beam's range
            [1.0, 0.0, 0.5],  # nearer but above the band
            [0.0, -1.5, -0.2],  # right, in the band
            [0.05, 0.0, 0.0],  # on the robot (inside range_min)
            [np.nan, np.nan, np.nan],  # an organised cloud's ray without a return
        ]
    )
    msg = _cloud_msg(pts, big=big, f8=f8, pad=pad, rows=rows)
    scan = decode_scan(msg, cloud=CloudSlice(min_z=-0.3, max_z=0.3, step_deg=1.0))
    assert scan.frame_id == "lidar"
    assert scan.stamp_ns == T0
    assert len(scan) == 360
    assert scan.time_increment == 0.0
    got = scan.points()[scan.valid()]
    np.testing.assert_allclose(np.hypot(*got.T), [1.5, 2.0], atol=1e-6)  # bearings -90° and 0°
    bearings = np.degrees(np.arctan2(got[:, 1], got[:, 0]))
    np.testing.assert_allclose(bearings, [-89.5, 0.5], atol=1e-6)  # centres of the 1° beams they fall in
    assert np.isnan(scan.ranges[~scan.valid()]).all()  # an empty beam says nothing (not free space)


def test_bad_point_clouds_are_one_clear_error() -> None:
    from studio.io.base import CloudSlice

    band = CloudSlice(min_z=-0.3, max_z=0.3)
    msg = _cloud_msg(np.zeros((4, 3)))
    with pytest.raises(RecordingError, match="needs 'cloud: \\{min_z, max_z\\}'"):
        decode_scan(msg)
    short = NS(**{**msg.__dict__, "data": msg.data[:-1]})
    with pytest.raises(RecordingError, match="not a decodable point cloud: data holds"):
        decode_scan(short, cloud=band)
    no_z = NS(**{**msg.__dict__, "fields": [f for f in msg.fields if f.name != "z"]})
    with pytest.raises(RecordingError, match="no z field"):
        decode_scan(no_z, cloud=band)
    odd = NS(
        **{
            **msg.__dict__,
            "fields": [NS(name=f.name, offset=f.offset, datatype=9, count=1) for f in msg.fields],
        }
    )
    with pytest.raises(RecordingError, match="unknown datatype 9"):
        decode_scan(odd, cloud=band)
    with pytest.raises(ValueError, match="min_z must be below max_z"):
        CloudSlice(min_z=0.3, max_z=-0.3)


def _spinning_cloud(times: np.ndarray, az: np.ndarray, field: str, datatype: int, fmt: str) -> NS:
    """A cloud of one return per bearing ``az`` (3 m away, in the band) timed ``times`` (raw field values)."""
    dtype = np.dtype({"names": ["x", "y", "z", field], "formats": ["<f4", "<f4", "<f4", fmt],
                      "offsets": [0, 4, 8, 16], "itemsize": 24})  # fmt: skip
    rec = np.zeros(len(az), dtype)
    rec["x"], rec["y"], rec[field] = 3 * np.cos(az), 3 * np.sin(az), times
    fields = [NS(name=c, offset=o, datatype=7, count=1) for c, o in (("x", 0), ("y", 4), ("z", 8))]
    fields.append(NS(name=field, offset=16, datatype=datatype, count=1))
    return NS(
        header=NS(stamp=_stamp(T0), frame_id="lidar"), height=1, width=len(az), fields=fields,
        is_bigendian=False, point_step=24, row_step=24 * len(az), data=rec.tobytes(), is_dense=True,
    )  # fmt: skip


@pytest.mark.parametrize(
    ("field", "datatype", "fmt", "unit"),
    [("t", 6, "<u4", "ns"), ("time", 7, "<f4", "s"), ("timestamp", 8, "<f8", "epoch")],
)
@pytest.mark.parametrize("turn", [1.0, -1.0])
def test_a_spinning_lidar_s_cloud_is_timed_beam_by_beam(
    field: str, datatype: int, fmt: str, unit: str, turn: float
) -> None:
    """Ouster (``t``, ns), Velodyne (``time``, s; stamped at the sweep's end) and Hesai (``timestamp``,
    epoch s) clouds: the scan starts where the lidar did, turns its way, each beam at its time."""
    from studio.io.base import CloudSlice

    k = np.arange(1800)
    az = np.mod(1.0 + turn * k * 2 * np.pi / 1800 + np.pi, 2 * np.pi) - np.pi  # one turn from 57° on
    t = (k - (1800 if unit == "s" else 0)) * (0.1 / 1800)  # 10 Hz; a Velodyne stamps the sweep's end
    raw = {"ns": np.round(t * 1e9), "s": t, "epoch": T0 * 1e-9 + t}[unit]
    scan = decode_scan(
        _spinning_cloud(raw, az, field, datatype, fmt), cloud=CloudSlice(-0.3, 0.3, step_deg=0.5)
    )
    assert np.sign(scan.angle_increment) == turn
    assert scan.time_increment == pytest.approx(0.1 / 720, rel=1e-3)
    beam_t = scan.stamp_ns * 1e-9 + np.arange(len(scan)) * scan.time_increment
    beam_a = scan.angles()
    # a point's beam lies at its bearing and was measured at its time: at the start and halfway through the
    # turn; its last returns, a full turn after the first and half a beam short of its bearing, make one
    # beam more, at the first one's bearing
    assert len(scan) == 721
    for j in (0, 450):
        i = int(np.argmin(np.abs(np.angle(np.exp(1j * (beam_a - az[j]))))))
        assert abs(beam_t[i] - (T0 * 1e-9 + t[j])) < 0.1 / 720
        assert scan.valid()[i]
    assert abs(np.angle(np.exp(1j * (beam_a[-1] - beam_a[0])))) < 1e-9
    assert abs(beam_t[-1] - (T0 * 1e-9 + t[1799])) < 0.1 / 720
    assert scan.valid()[-1]
    # times that do not follow the bearing (a non-repetitive pattern): untimed, from -180°
    rng = np.random.default_rng(1)
    shuffled = decode_scan(
        _spinning_cloud(rng.permutation(raw), az, field, datatype, fmt),
        cloud=CloudSlice(-0.3, 0.3, step_deg=0.5),
    )
    assert shuffled.time_increment == 0.0
    assert shuffled.stamp_ns == T0
    assert shuffled.angle_min == pytest.approx(-np.pi + np.radians(0.25))


def test_a_cloud_s_beams_follow_its_columns_and_holes_in_a_surface_are_filled() -> None:
    """An organised cloud's rows are rings: its beams are its columns (0.4° here); an unorganised one written
    column by column tells its spacing too. One in no order is sliced at 0.25°, and the empty beams a 0.4°
    lidar leaves in a wall are filled in; a gap between two surfaces at different ranges is not."""
    from studio.io.base import CloudSlice

    az = np.radians(np.arange(900) * 0.4 - 180.0)
    r = np.where(np.abs(np.degrees(az) - 30) < 5, 2.0, 4.0)  # a wall at 4 m, a post at 2 m from 25° to 35°
    ring = np.stack([r * np.cos(az), r * np.sin(az), np.zeros_like(az)], axis=1)
    above = ring + np.array([0.0, 0.0, 1.0])  # a second ring, above the band
    organised = _cloud_msg(np.concatenate([ring, above]), rows=2)
    band = CloudSlice(min_z=-0.3, max_z=0.3)
    scan = decode_scan(organised, cloud=band)
    assert len(scan) == 900
    assert scan.angle_increment == pytest.approx(np.radians(0.4))
    assert scan.valid().all()
    in_order = decode_scan(_cloud_msg(ring), cloud=band)  # unorganised, written column by column
    assert in_order.angle_increment == pytest.approx(np.radians(0.4))
    shuffled = ring[np.random.default_rng(2).permutation(len(ring))]  # no order to read the columns off
    loose = decode_scan(_cloud_msg(shuffled), cloud=band)
    assert len(loose) == 1440
    assert loose.valid().all()  # every 0.25° beam: returns, or filled in between two
    np.testing.assert_allclose(loose.ranges[np.abs(np.degrees(loose.angles()) - 30) < 4.5], 2.0, atol=1e-6)
    rng = np.hypot(*loose.points().T)
    near_edge = np.abs(np.abs(np.degrees(loose.angles()) - 30) - 5) < 0.3
    assert ((np.abs(rng[near_edge] - 2) < 1e-6) | (np.abs(rng[near_edge] - 4) < 1e-6)).all()  # no ramp
    fixed = decode_scan(_cloud_msg(shuffled), cloud=CloudSlice(min_z=-0.3, max_z=0.3, step_deg=0.1))
    assert (~fixed.valid()).sum() > 1000  # 0.1° beams: holes of three are not filled


def test_cloud_times_far_from_the_stamp_leave_the_beams_untimed() -> None:
    """Times more than a second off the stamp (a driver's other clock) leave the beams untimed at the stamp
    rather than stamp the scan elsewhere; times since the epoch are told by their size."""
    from studio.io.base import CloudSlice

    k = np.arange(720)
    az = np.mod(k * 2 * np.pi / 720 + np.pi, 2 * np.pi) - np.pi
    t = k * (0.1 / 720)
    band = CloudSlice(-0.3, 0.3, step_deg=0.5)
    off = decode_scan(_spinning_cloud(t + 5.0, az, "time", 7, "<f4"), cloud=band)
    assert off.time_increment == 0.0
    assert off.stamp_ns == T0
    late = decode_scan(_spinning_cloud(T0 * 1e-9 + 3600 + t, az, "timestamp", 8, "<f8"), cloud=band)
    assert late.time_increment == 0.0
    assert late.stamp_ns == T0


def test_an_unorganised_cloud_written_column_by_column_tells_its_column_spacing() -> None:
    """16 rings fired 0.008° apart within each 0.4° column (a VLP-16 at 20 Hz), written column by column."""
    from studio.io.base import CloudSlice

    cols = np.arange(900) * 0.4 - 180.0
    bearings = np.radians((cols[:, None] + np.arange(16)[None, :] * 0.008).reshape(-1))
    el = np.tile(np.radians(np.linspace(-15, 15, 16)), 900)
    pts = np.stack(
        [4 * np.cos(el) * np.cos(bearings), 4 * np.cos(el) * np.sin(bearings), 4 * np.sin(el)], axis=1
    )
    scan = decode_scan(_cloud_msg(pts), cloud=CloudSlice(min_z=-0.5, max_z=0.5))
    assert scan.angle_increment == pytest.approx(np.radians(0.4), rel=0.01)


def test_clouds_in_no_order_with_no_return_points_or_odd_fields_are_read_sensibly() -> None:
    """A large cloud in no order is sliced at 0.25° (not at a spacing read off chance neighbours); (0, 0, 0)
    points, many drivers' "no return", are never returns even with range_min 0 and do not spoil the timing;
    a time field of an unknown type leaves the cloud untimed; a byte list out of range is one clear error."""
    from studio.io.base import CloudSlice

    band = CloudSlice(-5.0, 5.0)
    for seed in range(3):
        az = np.random.default_rng(seed).uniform(-np.pi, np.pi, 20000)
        pts = np.stack([3 * np.cos(az), 3 * np.sin(az), np.zeros_like(az)], axis=1)
        assert decode_scan(_cloud_msg(pts), cloud=band).angle_increment == pytest.approx(np.radians(0.25))
    k = np.arange(1024)
    az = np.mod(k * 2 * np.pi / 1024 + np.pi, 2 * np.pi) - np.pi
    t = np.round(k * (0.1 / 1024) * 1e9)
    msg = _spinning_cloud(t, az, "t", 6, "<u4")
    rec = np.frombuffer(
        msg.data,
        np.dtype({"names": ["x", "y"], "formats": ["<f4", "<f4"], "offsets": [0, 4], "itemsize": 24}),
    ).copy()
    rec["x"][::3] = rec["y"][::3] = 0.0  # a third of the rays without a return
    holes = NS(**{**msg.__dict__, "data": rec.tobytes()})
    scan = decode_scan(holes, cloud=CloudSlice(-0.3, 0.3, range_min=0.0))
    assert scan.time_increment > 0
    assert np.nanmin(scan.ranges) == pytest.approx(3.0)  # the wall, never 0
    odd = NS(**{**msg.__dict__, "fields": [*msg.fields[:3], NS(name="t", offset=16, datatype=11, count=1)]})
    assert decode_scan(odd, cloud=band).time_increment == 0.0
    with pytest.raises(RecordingError, match="not a decodable point cloud"):
        decode_scan(NS(**{**msg.__dict__, "data": [300] * len(msg.data)}), cloud=band)
