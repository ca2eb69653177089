"""Test data of the studio.io tests: real bags and a small synthetic recording (imported by the tests)."""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np
import pytest

from studio.geometry.se import Pose2, Pose3
from studio.io import LaserScan, Odometry, RecordingWriter

DATA = Path(__file__).resolve().parents[2] / ".." / "shared" / "data" / "leg_tracker"

# synthetic rig: camera 10 Hz, front/back lasers 40 Hz (45 beams), odometry 50 Hz, 4 s
T0 = 1_700_000_000_000_000_000
SECONDS = 4.0
FRONT = Pose3.from_xyz_rpy(0.35, 0.0, 0.3, 0.0, 0.0, 0.0)
BACK = Pose3.from_xyz_rpy(-0.35, 0.0, 0.3, 0.0, 0.0, np.pi)
CAMERA = Pose3.from_xyz_rpy(0.0, 0.0, 1.15, 0.0, 0.0, 0.0)
N_IMAGES = int(SECONDS * 10)


def bag(name: str) -> Path:
    """A real bag of ../shared/data/leg_tracker (the test is skipped when the data is absent)."""
    p = DATA / name
    if not p.exists():
        pytest.skip(f"real data not available: {p}")
    return p


def robot_pose(t_s: float) -> Pose2:
    """True T_odom_base: a slow arc (0.5 m/s, 0.3 rad/s)."""
    yaw = 0.3 * t_s
    return Pose2(0.5 * np.sin(yaw) / 0.3, 0.5 * (1 - np.cos(yaw)) / 0.3, yaw)


def make_scan(stamp_ns: int, frame: str, *, n: int = 45, nan_every: int = 7) -> LaserScan:
    ranges = np.linspace(1.0, 5.0, n, dtype=np.float32)
    ranges[::nan_every] = np.nan
    return LaserScan(stamp_ns, frame, -np.pi / 2, np.pi / (n - 1), ranges, 0.05, 10.0)


def write_synthetic(path: Path, *, tf_lasers: bool = True, latency_ns: int = 0) -> Path:
    """Write the synthetic recording (images are small JPEGs whose grey level encodes the image index)."""
    with RecordingWriter(path) as w:
        if tf_lasers:
            w.write_tf(
                [
                    ("base_link", "front_laser", T0, FRONT),
                    ("base_link", "back_laser", T0, BACK),
                    ("base_link", "camera", T0, CAMERA),
                ],
                static=True,
                log_ns=T0,
            )
        events: list[tuple[int, int, str]] = []
        events += [(T0 + k * 100_000_000, 0, "image") for k in range(N_IMAGES)]
        events += [(T0 + k * 25_000_000 + 3_000_000, 1, "front") for k in range(int(SECONDS * 40))]
        events += [(T0 + k * 25_000_000 + 15_000_000, 2, "back") for k in range(int(SECONDS * 40))]
        events += [(T0 + k * 20_000_000, 3, "odom") for k in range(int(SECONDS * 50) + 1)]
        for stamp, _, kind in sorted(events):
            t_s = (stamp - T0) / 1e9
            if kind == "image":
                k = (stamp - T0) // 100_000_000
                img = np.full((32, 64, 3), int(k) * 5, np.uint8)
                ok, jpg = cv2.imencode(".jpg", img)
                assert ok
                w.write_compressed_image(
                    "/camera/image/compressed", stamp + latency_ns, "camera", jpg.tobytes()
                )
            elif kind == "front":
                w.write_scan("/scan_front", make_scan(stamp, "front_laser"))
            elif kind == "back":
                w.write_scan("/scan_back", make_scan(stamp, "/back_laser"))
            else:
                p = robot_pose(t_s)
                w.write_odometry("/odom", Odometry(stamp, "odom", "base_link", p), vx=0.5, wz=0.3)
                w.write_tf(
                    [("odom", "base_link", stamp, Pose3.from_xyz_rpy(p.x, p.y, 0.0, 0.0, 0.0, p.yaw))],
                    static=False,
                )
    return path


def split_bag(
    src: Path, folder: Path, part_of: str = "time", parts: int = 3, seconds: float | None = None
) -> list[Path]:
    """Write ``src``'s messages (those of its first ``seconds``, or all) into ``parts`` ROS1 bags in
    ``folder``, raw bytes unchanged: by ``time`` (consecutive stretches, as ``rosbag record --split``), or by
    ``topic and time`` (each bag holds some topics over some stretches, so every bag ends at a different
    time)."""
    from rosbags.rosbag1 import Reader, Writer

    folder.mkdir(parents=True, exist_ok=True)
    names = [folder / f"rec_{k}.bag" for k in range(parts)]
    writers = [Writer(p) for p in names]
    with Reader(src) as reader:
        topics = sorted({c.topic for c in reader.connections})
        end = reader.end_time if seconds is None else reader.start_time + int(seconds * 1e9)
        span = max(end - reader.start_time, 1)
        for w in writers:
            w.open()
        out = [
            {
                c.id: w.add_connection(c.topic, c.msgtype, msgdef=c.msgdef.data, md5sum=c.digest)
                for c in reader.connections
            }
            for w in writers
        ]
        for c, t, raw in reader.messages(stop=end):
            k = min(parts - 1, (t - reader.start_time) * parts // span)
            if part_of == "topic and time":
                k = (k + topics.index(c.topic)) % parts
            writers[k].write(out[k][c.id], t, raw)
        for w in writers:
            w.close()
    return names
