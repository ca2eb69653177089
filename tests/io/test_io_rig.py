"""rig.yaml: load, validate (clear messages naming the file and key), save round trip."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from studio.geometry.se import Pose3
from studio.io import CameraConfig, LaserConfig, OdometryConfig, Rig, RigError, SyncConfig, load_rig, save_rig

DESIGN_EXAMPLE = """\
base_frame: base_link            # any frame of the TF tree in the bag; labels are expressed in it
odometry: {topic: /odom}         # or {tf: odom}; absent → static robot, with a warning
camera:
  topic: /theta_camera/image/compressed     # sensor_msgs/CompressedImage or Image, equirectangular
  pose: {x: 0.0, y: 0.0, z: 1.15, roll: 0.0, pitch: 0.0, yaw: 0.0}   # in base_frame, from calibration
lasers:
  - topic: /scan_front                       # sensor_msgs/LaserScan; one or more
    pose: {x: 0.35, y: 0.0, z: 0.30, yaw: 0.0}  # optional: else from /tf_static or /tf in the bag
sync: {max_dt_s: 0.05, camera_latency_s: 0.0}
"""


def test_numbers_written_with_an_exponent_are_numbers(tmp_path: Path) -> None:
    """YAML 1.1 (PyYAML) read ``5e-2`` as a string, and the rig was refused as "not a number"."""
    p = tmp_path / "rig.yaml"
    text = DESIGN_EXAMPLE.replace("max_dt_s: 0.05", "max_dt_s: 5e-2").replace("z: 1.15", "z: 115e-2")
    assert "5e-2" in text
    assert "115e-2" in text
    p.write_text(text)
    rig = load_rig(p)
    assert rig.sync.max_dt_s == pytest.approx(0.05)
    assert rig.camera is not None
    assert rig.camera.pose is not None
    np.testing.assert_allclose(rig.camera.pose.t, (0, 0, 1.15))


def test_a_key_given_twice_is_refused(tmp_path: Path) -> None:
    p = tmp_path / "rig.yaml"
    p.write_text(DESIGN_EXAMPLE + "base_frame: laser\n")
    with pytest.raises(RigError, match=r"\(line 10, column 1\): the key 'base_frame' is given twice"):
        load_rig(p)


def test_design_example_loads(tmp_path: Path) -> None:
    p = tmp_path / "rig.yaml"
    p.write_text(DESIGN_EXAMPLE)
    rig = load_rig(p)
    assert rig.base_frame == "base_link"
    assert rig.odometry == OdometryConfig(topic="/odom")
    assert rig.camera is not None
    assert rig.camera.topic == "/theta_camera/image/compressed"
    assert rig.camera.pose is not None
    np.testing.assert_allclose(rig.camera.pose.t, (0, 0, 1.15))
    assert len(rig.lasers) == 1
    assert rig.lasers[0].pose is not None
    np.testing.assert_allclose(rig.lasers[0].pose.t, (0.35, 0, 0.3))
    assert rig.sync == SyncConfig(0.05, 0.0)
    assert rig.topics() == ["/theta_camera/image/compressed", "/scan_front", "/odom"]


def test_save_load_round_trip(tmp_path: Path) -> None:
    rig = Rig(
        base_frame="/base_link",
        odometry=OdometryConfig(tf="odom"),
        camera=CameraConfig("/cam", Pose3.from_xyz_rpy(0.1, 0.2, 1.1, 0.01, -0.02, 0.3)),
        lasers=(LaserConfig("/front", Pose3.from_xyz_rpy(0.35, 0, 0.3, 0, 0, 0)), LaserConfig("/back")),
        sync=SyncConfig(max_dt_s=0.03, camera_latency_s=0.02),
    )
    p = tmp_path / "rig.yaml"
    save_rig(rig, p)
    text = p.read_text()
    assert "odometry: {tf: odom}" in text
    assert "pose: {x: 0.1, y: 0.2, z: 1.1, roll: 0.01" in text
    back = load_rig(p)
    assert back.base_frame == "base_link"
    assert back.to_dict() == rig.to_dict()
    assert back.lasers[1].pose is None
    assert back.camera is not None
    assert back.camera.pose is not None
    assert rig.camera is not None
    np.testing.assert_allclose(back.camera.pose.matrix(), rig.camera.pose.matrix(), atol=1e-12)


def test_a_point_cloud_laser_round_trips_with_its_height_band(tmp_path: Path) -> None:
    p = tmp_path / "rig.yaml"
    p.write_text(
        "base_frame: base_link\nlasers:\n  - topic: /points\n    cloud: {min_z: -0.6, max_z: -0.2}\n"
    )
    rig = load_rig(p)
    cloud = rig.lasers[0].cloud
    assert cloud is not None
    assert (cloud.min_z, cloud.max_z, cloud.step_deg, cloud.range_min) == (-0.6, -0.2, None, 0.1)
    save_rig(rig, tmp_path / "again.yaml")
    assert load_rig(tmp_path / "again.yaml").lasers[0].cloud == cloud
    p.write_text(
        "base_frame: b\nlasers:\n  - topic: /points\n    cloud: {min_z: -0.6, max_z: -0.2, step_deg: null}\n"
    )
    assert load_rig(p).lasers[0].cloud == cloud  # null: the lidar's own columns, as left out
    plain = Rig(base_frame="b", lasers=(LaserConfig("/scan"),))
    assert plain.lasers[0].cloud is None
    assert "cloud" not in plain.to_dict()["lasers"][0]


def test_laser_only_rig_and_defaults(tmp_path: Path) -> None:
    p = tmp_path / "rig.yaml"
    p.write_text("base_frame: laser\nlasers:\n  - topic: /scan\n")
    rig = load_rig(p)
    assert rig.camera is None
    assert rig.odometry is None
    assert rig.sync == SyncConfig()
    assert rig.sync.max_dt_ns == 50_000_000


@pytest.mark.parametrize(
    ("text", "match"),
    [
        ("", "is empty"),
        ("[1, 2]", "must be a mapping"),
        ("base_frame: b\nlasers: [{topic: /s}]\ncolour: red\n", "key 'colour' is not a known key"),
        ("lasers: [{topic: /s}]\n", "key 'base_frame' is required"),
        ("base_frame: 3\nlasers: [{topic: /s}]\n", "key 'base_frame' must be a non-empty string"),
        ("base_frame: b\n", "needs at least one laser or a camera"),
        ("base_frame: b\nlasers: []\n", "needs at least one laser or a camera"),
        ("base_frame: b\nlasers: {topic: /s}\n", "key 'lasers' must be a list"),
        ("base_frame: b\nlasers: [{pose: {x: 1}}]\n", r"key 'lasers\[0\].topic' is required"),
        (
            "base_frame: b\nlasers: [{topic: /s, pose: {x: one}}]\n",
            r"key 'lasers\[0\].pose.x' must be a finite number",
        ),
        (
            "base_frame: b\nlasers: [{topic: /s, pose: {x: 1, q: 2}}]\n",
            r"key 'lasers\[0\].pose.q' is not a known key",
        ),
        ("base_frame: b\nlasers: [{topic: /s}, {topic: /s}]\n", "listed twice"),
        ("base_frame: b\nlasers: [{topic: /s}]\nodometry: {topic: /o, tf: odom}\n", "exactly one of"),
        ("base_frame: b\nlasers: [{topic: /s}]\nodometry: {}\n", "exactly one of"),
        (
            "base_frame: b\nlasers: [{topic: /s}]\nodometry: {topc: /o}\n",
            "key 'odometry.topc' is not a known key",
        ),
        ("base_frame: b\ncamera: {pose: {x: 0}}\n", "key 'camera.topic' is required"),
        ("base_frame: b\ncamera: /cam\n", "key 'camera' must be a mapping"),
        ("base_frame: b\nlasers: [{topic: /s}]\nsync: {max_dt_s: -1}\n", "key 'sync.max_dt_s' must be >= 0"),
        ("base_frame: b\nlasers: [{topic: /s}]\nsync: {max_dt_s: .nan}\n", "must be a finite number"),
        (
            "base_frame: b\nlasers: [{topic: /s}]\nsync: {latency: 1}\n",
            "key 'sync.latency' is not a known key",
        ),
        ("base_frame: b\nlasers: [{topic: /s}\n", "not valid YAML"),
        ("base_frame: b\nlasers: [{topic: /s, pose: {yaw: true}}]\n", "must be a finite number"),
        ("base_frame: b\ncamera: {topic: /c, lens_offset: .inf}\n", "'camera.lens_offset' must be a finite"),
        ("base_frame: b\ncamera: {topic: /c, lens_offset: '1cm'}\n", "'camera.lens_offset' must be a finite"),
        ("base_frame: b\ncamera: {topic: /c, lens_offset: 0.25}\n", "'camera.lens_offset' must be within"),
        ("base_frame: b\ncamera: {topic: /c, lens_offset: -0.2}\n", "'camera.lens_offset' must be within"),
        (
            "base_frame: b\nlasers: [{topic: /v, cloud: {max_z: 0}}]\n",
            r"'lasers\[0\].cloud.min_z' is required",
        ),
        ("base_frame: b\nlasers: [{topic: /v, cloud: {min_z: 0, max_z: 0}}]\n", "min_z must be below max_z"),
        (
            "base_frame: b\nlasers: [{topic: /v, cloud: {min_z: 0, max_z: 1, step_deg: 0}}]\n",
            r"step_deg must be in \(0.05, 5\]",
        ),
        ("base_frame: b\nlasers: [{topic: /v, cloud: {min_z: 0, max_z: 1, rings: 16}}]\n", "not a known key"),
        ("base_frame: b\nlasers: [{topic: /v, cloud: -0.3}]\n", r"'lasers\[0\].cloud' must be a mapping"),
        (
            "base_frame: b\nlasers: [{topic: /v, cloud: {min_z: null, max_z: 1}}]\n",
            "cloud.min_z' must be a finite",
        ),
    ],
)
def test_bad_rigs(tmp_path: Path, text: str, match: str) -> None:
    p = tmp_path / "bad_rig.yaml"
    p.write_text(text)
    with pytest.raises(RigError, match=match) as info:
        load_rig(p)
    msg = str(info.value)
    assert str(p) in msg
    assert "\n" not in msg


def test_missing_rig_file(tmp_path: Path) -> None:
    with pytest.raises(RigError, match="rig file not found"):
        load_rig(tmp_path / "nope.yaml")


def test_calibration_block_of_studio_calibrate_is_accepted(tmp_path: Path) -> None:
    p = tmp_path / "rig.yaml"
    p.write_text(DESIGN_EXAMPLE + "calibration: {method: extrinsics, n: 40, col_px_mean: 1.2}\n")
    assert load_rig(p).camera is not None
    p.write_text(DESIGN_EXAMPLE + "calibratoin: {}\n")
    with pytest.raises(RigError, match="calibratoin"):
        load_rig(p)


def test_lens_offset_default_round_trip_and_saved_only_when_set(tmp_path: Path) -> None:
    p = tmp_path / "rig.yaml"
    p.write_text(DESIGN_EXAMPLE)
    rig = load_rig(p)
    assert rig.camera is not None
    assert rig.camera.lens_offset == 0.0
    save_rig(rig, tmp_path / "plain.yaml")
    assert "lens_offset" not in (tmp_path / "plain.yaml").read_text()
    p.write_text(DESIGN_EXAMPLE.replace("   # in base_frame", "\n  lens_offset: -0.013  #"))
    rig = load_rig(p)
    assert rig.camera is not None
    assert rig.camera.lens_offset == -0.013
    save_rig(rig, tmp_path / "dual.yaml")
    assert "lens_offset: -0.013" in (tmp_path / "dual.yaml").read_text()
    back = load_rig(tmp_path / "dual.yaml")
    assert back.camera is not None
    assert back.camera.lens_offset == -0.013
    assert back.to_dict() == rig.to_dict()


@pytest.mark.parametrize("bad", [float("nan"), 0.2, -1.0, True])
def test_camera_config_rejects_bad_lens_offset(bad: float) -> None:
    with pytest.raises(ValueError, match="lens_offset"):
        CameraConfig("/cam", None, bad)
