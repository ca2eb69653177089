"""Ground truth matches the rendered scene: GT people land on leg returns in the scans and on person pixels
in the panorama, boxes contain them, odometry drifts a little, a static robot stays put."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import cv2
import numpy as np
import pytest
from rosbags.highlevel import AnyReader
from rosbags.typesys import Stores, get_typestore

from studio.geometry import EquirectCamera, Pose2, Pose3
from studio.io.rig import load_rig
from studio.sim import SimResult, simulate
from studio.sim.base import SimRig
from studio.sim.motion import simulate_motion
from studio.sim.render import PanoramaRenderer
from studio.sim.scenarios import get_scenario
from studio.sim.world import build_world


def read_gt(path: Path) -> list[dict[str, Any]]:
    return [json.loads(line) for line in path.read_text().splitlines()]


def _stamp(msg: Any) -> int:
    return int(msg.header.stamp.sec) * 1_000_000_000 + int(msg.header.stamp.nanosec)


@pytest.fixture(scope="module")
def bag(moving_sim: SimResult) -> dict[str, list[tuple[int, Any]]]:
    out: dict[str, list[tuple[int, Any]]] = {}
    with AnyReader([moving_sim.recording], default_typestore=get_typestore(Stores.ROS2_HUMBLE)) as reader:
        for conn, _, raw in reader.messages():
            if conn.topic.startswith("/tf"):
                continue
            msg = reader.deserialize(raw, conn.msgtype)
            out.setdefault(conn.topic, []).append((_stamp(msg), msg))
    return out


def _nearest(items: list[tuple[int, Any]], stamp: int) -> tuple[int, Any]:
    return min(items, key=lambda it: abs(it[0] - stamp))


def test_gt_people_land_on_leg_returns(moving_sim: SimResult, bag: dict[str, list[tuple[int, Any]]]) -> None:
    rig = load_rig(moving_sim.rig)
    gt = read_gt(moving_sim.ground_truth_jsonl)
    dists = []
    for frame in gt:
        for las in rig.lasers:
            name = las.topic.replace("/scan_", "") + "_laser"
            stamp, scan = _nearest(bag[las.topic], frame["stamp_ns"])
            assert abs(stamp - frame["stamp_ns"]) <= 13_000_000
            r = np.asarray(scan.ranges, dtype=np.float64)
            a = scan.angle_min + scan.angle_increment * np.arange(r.size)
            ok = np.isfinite(r)
            pts = np.stack([r[ok] * np.cos(a[ok]), r[ok] * np.sin(a[ok]), np.zeros(ok.sum())], axis=1)
            assert las.pose is not None
            pts_base = las.pose.apply(pts)[:, :2]
            for p in frame["people"]:
                if p["visible"][name]:
                    d = np.hypot(pts_base[:, 0] - p["x"], pts_base[:, 1] - p["y"]).min()
                    dists.append(d)
                    # legs are up to ~0.25 m from the body centre at full stride (plus motion within 13 ms)
                    assert d < 0.3, (frame["frame"], p["id"], name, d)
    assert len(dists) >= 10
    assert float(np.median(dists)) < 0.15


def test_gt_people_land_on_rendered_person_pixels(
    moving_sim: SimResult, bag: dict[str, list[tuple[int, Any]]]
) -> None:
    rig = SimRig()
    cam = EquirectCamera(rig.width, rig.height, rig.camera_pose)
    renderer = PanoramaRenderer(build_world(), width=rig.width, height=rig.height, zc=1.15)
    gt = read_gt(moving_sim.ground_truth_jsonl)
    checked = 0
    for frame in gt[::4]:
        stamp, msg = _nearest(bag["/theta_camera/image/compressed"], frame["stamp_ns"])
        assert stamp == frame["stamp_ns"]
        img = cv2.imdecode(np.frombuffer(bytes(msg.data), np.uint8), cv2.IMREAD_COLOR)
        rw = frame["robot_world"]
        empty, _ = renderer.render(np.array([rw["x"], rw["y"], rw["yaw"]]), [], np.zeros((0, 2)))
        for p in frame["people"]:
            if not p["visible"]["camera"] or p["visible_frac"] < 0.95 or p["range"] > 8.0:
                continue
            (u, v), _ = cam.project(np.array([p["x"], p["y"], 1.1]))
            iu, iv = int(u), int(v)
            patch = np.s_[iv - 1 : iv + 2, iu - 1 : iu + 2]
            diff = np.abs(img[patch].astype(float) - empty[patch].astype(float)).mean()
            assert diff > 12.0, (frame["frame"], p["id"], diff)
            checked += 1
    assert checked >= 5


def test_gt_boxes_contain_the_projected_person(moving_sim: SimResult) -> None:
    rig = SimRig()
    cam = EquirectCamera(rig.width, rig.height, rig.camera_pose)
    n = 0
    for frame in read_gt(moving_sim.ground_truth_jsonl):
        for p in frame["people"]:
            if not p["visible"]["camera"]:
                assert "box" not in p
                continue
            u1, v1, u2, v2 = p["box"]
            assert 0 <= u1 < rig.width
            assert u1 < u2 <= u1 + rig.width
            assert 0 <= v1 < v2 <= rig.height
            if p["visible_frac"] < 0.95:
                continue
            for z in (0.05, 1.1):
                (u, v), _ = cam.project(np.array([p["x"], p["y"], z]))
                if u < u1:
                    u += rig.width  # box across the seam
                where = (frame["frame"], p["id"], z, u, v, p["box"])
                assert u1 - 3 <= u <= u2 + 3, where
                assert v1 - 3 <= v <= v2 + 3, where
                n += 1
    assert n >= 10


def test_gt_odom_positions_use_the_published_odometry(
    moving_sim: SimResult, bag: dict[str, list[tuple[int, Any]]]
) -> None:
    odom = bag["/odom"]
    for frame in read_gt(moving_sim.ground_truth_jsonl):
        (s0, m0), (s1, m1) = sorted(odom, key=lambda it: abs(it[0] - frame["stamp_ns"]))[:2]
        poses = []
        for m in (m0, m1):
            q = m.pose.pose.orientation
            poses.append(
                Pose3.from_quat(
                    [m.pose.pose.position.x, m.pose.pose.position.y, 0.0], [q.x, q.y, q.z, q.w]
                ).to_pose2()
            )
        w = (frame["stamp_ns"] - s0) / (s1 - s0)
        x = poses[0].x + w * (poses[1].x - poses[0].x)
        y = poses[0].y + w * (poses[1].y - poses[0].y)
        rp = frame["robot_pose"]
        assert (rp["x"], rp["y"]) == pytest.approx((x, y), abs=1e-5)
        T = Pose2(rp["x"], rp["y"], rp["yaw"])
        for p in frame["people"]:
            xo, yo = T.apply(np.array([p["x"], p["y"]]))
            assert (p["x_odom"], p["y_odom"]) == pytest.approx((xo, yo), abs=1e-5)


def test_gt_lists_only_people_seen_by_a_sensor_within_range(moving_sim: SimResult) -> None:
    gt = read_gt(moving_sim.ground_truth_jsonl)
    assert sum(len(f["people"]) for f in gt) == moving_sim.num_gt > 0
    for frame in gt:
        for p in frame["people"]:
            assert p["source"] == "gt"
            assert any(p["visible"].values())
            assert np.hypot(p["x"], p["y"]) <= 10.0


def test_odometry_drift_is_small_but_nonzero() -> None:
    sc = get_scenario("moving")
    m = simulate_motion(sc, build_world(), seconds=30.0, rng=np.random.default_rng(5))
    start = Pose2(*m.robot[0])
    path = float(np.hypot(*np.diff(m.robot[:, :2], axis=0).T).sum())
    assert path > 3.0
    errs = []
    for k in range(0, m.t.shape[0], 50):
        rel = start.inverse().compose(Pose2(*m.robot[k]))
        errs.append(np.hypot(rel.x - m.odom[k, 0], rel.y - m.odom[k, 1]))
    assert 0.001 < max(errs) < 0.05 * path + 0.05


def test_static_scenario_keeps_the_robot_still(tmp_path: Path) -> None:
    res = simulate("static", out=tmp_path / "static", seconds=0.6, seed=2)
    gt = read_gt(res.ground_truth_jsonl)
    assert len(gt) == 6
    assert {(f["robot_pose"]["x"], f["robot_pose"]["y"], f["robot_pose"]["yaw"]) for f in gt} == {
        (0.0, 0.0, 0.0)
    }
    assert res.odom_drift_m == 0.0
