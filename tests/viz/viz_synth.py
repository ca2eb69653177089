"""A tiny synthetic labeling run built by hand (frames, pass-one perception, LabelRun) for the viz tests."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

import cv2
import numpy as np

from studio.detect.image.base import ImageDetections
from studio.detect.laser.base import LaserDetections
from studio.fuse.base import PersonObservations
from studio.geometry import EquirectCamera
from studio.geometry.se import Pose2
from studio.io.base import Frame, LaserScan, Panorama, ScanInBase
from studio.io.rig import parse_rig
from studio.labels.base import LabelFrame, LabelPerson
from studio.labels.formats import write_labels
from studio.pipeline.base import FrameResult
from studio.pipeline.label import LabelRun, PerceptionFrame
from studio.pipeline.perceive import compact_beams

W, H = 128, 64
N_FRAMES = 6
N_BEAMS = 90
T0 = 1_700_000_000_000_000_000
DT = 100_000_000  # 10 Hz

RIG = parse_rig(
    {
        "base_frame": "base_link",
        "odometry": {"topic": "/odom"},
        "camera": {"topic": "/cam", "pose": {"z": 1.15}},
        "lasers": [
            {"topic": "/scan_front", "pose": {"x": 0.3, "z": 0.3}},
            {"topic": "/scan_rear", "pose": {"x": -0.3, "z": 0.3, "yaw": 3.14159}},
        ],
    }
)


@dataclass
class Synthetic:
    frames: list[Frame]
    perception: list[PerceptionFrame]
    run: LabelRun
    gt_path: Path


def _pano(k: int) -> Panorama:
    img = np.zeros((H, W, 3), np.uint8)
    img[:, :, 0] = np.linspace(0, 255, W, dtype=np.uint8)[None]
    img[:, :, 1] = np.linspace(0, 255, H, dtype=np.uint8)[:, None]
    cv2.rectangle(img, (10 + 5 * k, 20), (20 + 5 * k, 50), (255, 255, 255), -1)
    ok, buf = cv2.imencode(".jpg", img)
    assert ok
    return Panorama(T0 + k * DT, "cam", img, buf.tobytes(), "jpeg")


def _scan(topic: str, k: int) -> ScanInBase:
    r = np.full(N_BEAMS, 3.0, np.float32)
    r[::7] = np.nan  # some beams return nothing
    scan = LaserScan(T0 + k * DT, topic.strip("/"), -np.pi / 2, np.pi / N_BEAMS, r, 0.05, 10.0)
    laser = next(x for x in RIG.lasers if x.topic == topic)
    return ScanInBase(topic, scan, laser.pose)


def build(tmp: Path, *, with_gt: bool = True) -> Synthetic:
    cam = EquirectCamera(W, H, RIG.camera.pose)  # type: ignore[union-attr]
    frames, percs, results, labels, gt = [], [], [], [], []
    for k in range(N_FRAMES):
        pose = Pose2(0.2 * k, 0.0, 0.05 * k)
        scans = (_scan("/scan_front", k),) if k == 3 else (_scan("/scan_front", k), _scan("/scan_rear", k))
        frame = Frame(k, T0 + k * DT, _pano(k), scans, pose)
        pts, owner = [], []
        for j, s in enumerate(scans):
            p2 = s.scan.points()
            p3 = s.sensor_pose.apply(np.c_[np.nan_to_num(p2), np.zeros(len(p2))])
            p3[~s.scan.valid()] = np.nan
            pts.append(p3.astype(np.float32))
            owner.append(np.full(len(p3), j, np.int16))
        laser = LaserDetections(
            np.array([[2.0, 0.5], [-1.0, 1.0]]),
            np.array([0.9, 0.4]),
            np.array([0, 1]),
            np.array([0.2, 0.1]),
            (np.array([0, 1]), np.array([2])),
        )
        boxes = np.array([[120.0, 20.0, 136.0, 50.0], [40.0, 22.0, 50.0, 48.0]])  # the first crosses the seam
        kp = np.zeros((2, 17, 3))
        kp[:, :, 0] = np.linspace(0, 8, 17)[None] + np.array([[122.0], [42.0]])
        kp[:, :, 0] %= W
        kp[:, :, 1] = np.linspace(22, 48, 17)[None]
        kp[:, :, 2] = 0.9
        image = ImageDetections(boxes, np.array([0.8, 0.6]), kp, W, H)
        pf = PerceptionFrame(
            k,
            T0 + k * DT,
            pose,
            image,
            None,
            laser,
            np.array([0.3, 0.3]),
            np.array([s.sensor_pose.t[:2] for s in scans]),
            *compact_beams(np.concatenate(pts), np.concatenate(owner), len(scans)),
        )
        frames.append(frame)
        percs.append(pf)
        obs = PersonObservations(
            np.array([[2.0, 0.5], [-1.0, 1.0]]),
            np.array([np.eye(2) * 0.01, np.diag([0.04, 0.01])]),
            np.array([0.9, 0.4]),
            ("fused", "laser"),
            ("laser-detection", "laser-only"),
            np.array([[40.0, 22.0, 50.0, 48.0], [np.nan] * 4]),
            np.array([1, -1]),
            np.array([0, 1]),
        )
        results.append(FrameResult(k, T0 + k * DT, pose, obs))
        people = [LabelPerson(1, 2.0, 0.5, *pose.apply(np.array([2.0, 0.5])), source="fused", score=0.9)]
        if k >= 2:
            people.append(LabelPerson(2, -1.0, 1.0, source="laser", score=0.4))  # no odom position: derived
        labels.append(LabelFrame(k, tuple(people), T0 + k * DT, pose))
        g = [LabelPerson(11, 2.05, 0.5), LabelPerson(12, 4.0, -2.0)]
        gt.append(LabelFrame(k, tuple(g), T0 + k * DT, pose))
    run = LabelRun(labels, results, (W, H), cam)
    gt_path = tmp / "ground_truth.jsonl"
    if with_gt:
        write_labels(gt_path, gt)
    return Synthetic(frames, percs, run, gt_path)


def log_run(rrd: Path, syn: Synthetic, *, ground_truth: Path | None = None, **kw: Any) -> Any:
    from studio.viz.log import RunLogger

    logger = RunLogger(rrd, rig=RIG, **kw)
    for f, pf in zip(syn.frames, syn.perception, strict=True):
        logger.on_frame(f, pf)
    logger.finish(syn.run, ground_truth=ground_truth)
    return logger
