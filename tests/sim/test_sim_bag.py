"""The simulated recording is a real ROS2 MCAP bag with the expected topics, counts, rates and frames."""

from __future__ import annotations

import math
import os
import stat
from pathlib import Path

import numpy as np
import pytest
from rosbags.highlevel import AnyReader
from rosbags.typesys import Stores, get_typestore

from studio.io.rig import load_rig
from studio.sim import SimResult

EXPECTED = {
    "/theta_camera/image/compressed": ("sensor_msgs/msg/CompressedImage", 10.0),
    "/scan_front": ("sensor_msgs/msg/LaserScan", 40.0),
    "/scan_rear": ("sensor_msgs/msg/LaserScan", 40.0),
    "/odom": ("nav_msgs/msg/Odometry", 50.0),
    "/tf": ("tf2_msgs/msg/TFMessage", 50.0),
    "/tf_static": ("tf2_msgs/msg/TFMessage", None),
}


def _stamp(msg: object) -> int:
    st = msg.header.stamp  # type: ignore[attr-defined]
    return int(st.sec) * 1_000_000_000 + int(st.nanosec)


def test_bag_opens_with_rosbags_with_topics_counts_and_rates(moving_sim: SimResult) -> None:
    stamps: dict[str, list[int]] = {t: [] for t in EXPECTED}
    with AnyReader([moving_sim.recording], default_typestore=get_typestore(Stores.ROS2_HUMBLE)) as reader:
        types = {c.topic: c.msgtype for c in reader.connections}
        assert types == {t: v[0] for t, v in EXPECTED.items()}
        static_children = set()
        for conn, _, raw in reader.messages():
            msg = reader.deserialize(raw, conn.msgtype)
            if conn.topic.startswith("/tf"):
                for tr in msg.transforms:
                    stamps[conn.topic].append(_stamp(tr))
                    if conn.topic == "/tf_static":
                        static_children.add((tr.header.frame_id, tr.child_frame_id))
                    else:
                        assert (tr.header.frame_id, tr.child_frame_id) == ("odom", "base_link")
            else:
                stamps[conn.topic].append(_stamp(msg))
            if conn.topic == "/scan_front":
                assert len(msg.ranges) == 1081
                assert math.isclose(msg.angle_increment, math.radians(0.25), rel_tol=1e-6)
                assert math.isclose(msg.angle_min, -0.75 * math.pi, rel_tol=1e-6)
                assert msg.header.frame_id == "laser_front"
            if conn.topic == "/theta_camera/image/compressed":
                assert msg.format == "jpeg"
                assert bytes(msg.data[:2]) == b"\xff\xd8"
    assert static_children == {
        ("base_link", "laser_front"),
        ("base_link", "laser_rear"),
        ("base_link", "camera_link"),
    }
    assert len(stamps["/theta_camera/image/compressed"]) == moving_sim.num_images == 25
    assert len(stamps["/scan_front"]) + len(stamps["/scan_rear"]) == moving_sim.num_scans == 200
    assert len(stamps["/odom"]) == moving_sim.num_odometry == 126
    assert max(stamps["/tf"]) >= max(max(v) for v in stamps.values())  # TF covers every stamp
    assert min(stamps["/tf"]) <= min(min(v) for k, v in stamps.items() if k != "/tf_static")
    for topic, (_, rate) in EXPECTED.items():
        s = np.array(stamps[topic])
        assert np.all(np.diff(s) >= 0), topic
        if rate is not None:
            assert float(np.median(np.diff(s))) == pytest.approx(1e9 / rate, rel=1e-3), topic


def test_rig_yaml_has_the_true_sensor_poses(moving_sim: SimResult) -> None:
    rig = load_rig(moving_sim.rig)
    assert rig.base_frame == "base_link"
    assert rig.odometry is not None
    assert rig.odometry.topic == "/odom"
    assert rig.camera is not None
    assert rig.camera.topic == "/theta_camera/image/compressed"
    assert rig.camera.pose is not None
    assert rig.camera.pose.t[2] == pytest.approx(1.15)
    topics = [las.topic for las in rig.lasers]
    assert topics == ["/scan_front", "/scan_rear"]
    rear = rig.lasers[1].pose
    assert rear is not None
    assert rear.t[0] < 0
    assert abs(abs(rear.to_pose2().yaw) - math.pi) < 1e-9


def test_output_directory_has_exactly_the_contract_files(moving_sim: SimResult) -> None:
    names = sorted(p.name for p in Path(moving_sim.out).iterdir())
    assert names == [".studio-files", "ground_truth.jsonl", "ground_truth.yaml", "recording.mcap", "rig.yaml"]
    umask = os.umask(0)
    os.umask(umask)
    assert stat.S_IMODE(moving_sim.out.stat().st_mode) == 0o777 & ~umask
    assert stat.S_IMODE(moving_sim.ground_truth_yaml.stat().st_mode) == 0o666 & ~umask
