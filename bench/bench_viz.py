"""Cost of the Rerun recording: logging time per frame and ``.rrd`` size per minute of 10 Hz data.

Synthetic sequence: 1920×960 panoramas (pink-noise texture plus flat shapes, JPEG quality 90 like a 360°
camera's output, ~250–400 KB each) and two 1081-beam scans per frame, a few image boxes with keypoints,
laser detections, fused people and tracks. Run::

    .venv/bin/python bench/bench_viz.py [--frames 300] [--faces-every 5] [--image-width 1280]
    .venv/bin/python bench/bench_viz.py --recording SIM/recording.mcap --rig SIM/rig.yaml   # real frames

With ``--recording`` the frames (images and scans) come from a recording, e.g. one written by
``studio simulate``; detections are left out there (only the per-frame logging cost and size of images and
scans is measured, plus robot poses).

Targets (issue 5): ≤ 30 MB per minute of 10 Hz data; logging ≤ 15 % of labeling time (labeling runs at
about 5 frames/s, so ≤ ~30 ms per frame).
"""

from __future__ import annotations

import argparse
import os
import sys
import tempfile
import time
from pathlib import Path

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
from studio.pipeline.base import FrameResult
from studio.pipeline.label import LabelRun, PerceptionFrame
from studio.pipeline.perceive import compact_beams

W, H = 1920, 960
N_BEAMS = 1081
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


def _pink(rng: np.random.Generator, h: int, w: int, beta: float = 1.4) -> np.ndarray:
    f = np.fft.fftfreq(h)[:, None] ** 2 + np.fft.rfftfreq(w)[None] ** 2
    f[0, 0] = 1.0
    spec = (rng.normal(size=f.shape) + 1j * rng.normal(size=f.shape)) / f ** (beta / 2)
    spec[0, 0] = 0.0
    x = np.fft.irfft2(spec, s=(h, w))
    return (x - x.min()) / (x.max() - x.min())


def make_panoramas(n_distinct: int, rng: np.random.Generator) -> list[tuple[np.ndarray, bytes]]:
    out = []
    for _ in range(n_distinct):
        img = (np.stack([_pink(rng, H, W) for _ in range(3)], -1) * 255).astype(np.uint8)
        for _ in range(25):
            x0, y0 = int(rng.integers(0, W - 300)), int(rng.integers(0, H - 300))
            color = tuple(int(c) for c in rng.integers(0, 255, 3))
            cv2.rectangle(
                img, (x0, y0), (x0 + int(rng.integers(30, 300)), y0 + int(rng.integers(30, 300))), color, -1
            )
        noise = rng.normal(0.0, 1.5, img.shape)
        img = np.clip(img + noise, 0, 255).astype(np.uint8)
        ok, buf = cv2.imencode(".jpg", img, [cv2.IMWRITE_JPEG_QUALITY, 90])
        assert ok
        out.append((img, buf.tobytes()))
    return out


def make_sequence(n: int, rng: np.random.Generator) -> tuple[list[Frame], list[PerceptionFrame], LabelRun]:
    panos = make_panoramas(4, rng)
    cam = EquirectCamera(W, H, RIG.camera.pose)  # type: ignore[union-attr]
    t0, dt = 1_700_000_000_000_000_000, 100_000_000
    frames, percs, results, labels = [], [], [], []
    angles = -0.75 * np.pi + np.deg2rad(0.25) * np.arange(N_BEAMS)
    for k in range(n):
        stamp = t0 + k * dt
        pose = Pose2(0.05 * k, 0.01 * k, 0.002 * k)
        img, enc = panos[k % len(panos)]
        scans = []
        for laser in RIG.lasers:
            r = (4.0 + 1.5 * np.sin(3 * angles + 0.01 * k) + rng.normal(0, 0.01, N_BEAMS)).astype(np.float32)
            r[rng.random(N_BEAMS) < 0.1] = np.nan
            scans.append(
                ScanInBase(
                    laser.topic, LaserScan(stamp, "l", angles[0], np.deg2rad(0.25), r, 0.05, 20.0), laser.pose
                )
            )  # type: ignore[arg-type]
        frame = Frame(k, stamp, Panorama(stamp, "cam", img, enc, "jpeg"), tuple(scans), pose)
        pts, owner = [], []
        for j, s in enumerate(scans):
            p2 = s.scan.points()
            p3 = s.sensor_pose.apply(np.c_[np.nan_to_num(p2), np.zeros(len(p2))])
            p3[~s.scan.valid()] = np.nan
            pts.append(p3.astype(np.float32))
            owner.append(np.full(len(p3), j, np.int16))
        people = np.array([[2.0 + 0.01 * k, 0.5], [-1.5, 2.0], [3.0, -1.0], [1.0, -2.5]])
        laser = LaserDetections(people, np.full(4, 0.8), np.zeros(4), np.full(4, 0.2))
        u, _ = cam.project(np.c_[people, np.full(4, 1.0)])
        boxes = np.c_[u[:, 0] - 40, np.full(4, 380.0), u[:, 0] + 40, np.full(4, 620.0)]
        boxes[:, [0, 2]] -= np.floor(boxes[:, [0]] / W) * W
        kp = np.zeros((4, 17, 3))
        kp[:, :, 0] = (boxes[:, [0]] + np.linspace(10, 70, 17)[None]) % W
        kp[:, :, 1] = np.linspace(390, 610, 17)[None]
        kp[:, :, 2] = 0.8
        det = ImageDetections(boxes, np.full(4, 0.7), kp, W, H)
        percs.append(
            PerceptionFrame(
                k,
                stamp,
                pose,
                det,
                None,
                laser,
                np.full(4, 0.3),
                np.array([s.sensor_pose.t[:2] for s in scans]),
                *compact_beams(np.concatenate(pts), np.concatenate(owner), len(scans)),
            )
        )
        frames.append(frame)
        obs = PersonObservations(
            people,
            np.repeat(np.eye(2)[None] * 0.01, 4, 0),
            np.full(4, 0.8),
            ("fused",) * 4,
            ("laser-detection",) * 4,
            boxes,
            np.arange(4),
            np.arange(4),
        )
        results.append(FrameResult(k, stamp, pose, obs))
        labels.append(
            LabelFrame(
                k, tuple(LabelPerson(i + 1, *people[i], source="fused") for i in range(4)), stamp, pose
            )
        )
    return frames, percs, LabelRun(labels, results, (W, H), cam)


def frames_from_recording(
    recording: Path, rig_path: Path, n: int
) -> tuple[list[Frame], list[PerceptionFrame], LabelRun, object]:
    """Up to ``n`` frames of a recording, with pass-one perception reduced to the scan points."""
    from studio.io import iter_frames, load_rig, open_recording
    from studio.pipeline.perceive import NoLaserDetector, laser_in_base

    rig = load_rig(rig_path)
    frames, percs, results, labels = [], [], [], []
    with open_recording(recording) as rec:
        for frame in iter_frames(rec, rig):
            laser, lz, pts, origins, owner = laser_in_base(frame, NoLaserDetector())
            frames.append(frame)
            percs.append(
                PerceptionFrame(
                    frame.index,
                    frame.stamp_ns,
                    frame.robot_pose,
                    None,
                    None,
                    laser,
                    lz,
                    origins,
                    *compact_beams(pts, owner, len(origins)),
                )
            )
            results.append(
                FrameResult(frame.index, frame.stamp_ns, frame.robot_pose, PersonObservations.empty())
            )
            labels.append(LabelFrame(frame.index, (), frame.stamp_ns, frame.robot_pose))
            if len(frames) >= n:
                break
    return frames, percs, LabelRun(labels, results, None, None), rig


def _breakdown(rrd: Path) -> dict[str, int]:
    import rerun as rr

    groups = {"panorama image": 0, "3D scans": 0, "panorama overlays": 0, "faces": 0, "other": 0}
    for chunk in rr.chunk.RrdReader(rrd).stream():
        p = chunk.entity_path
        key = (
            "panorama image"
            if p == "/camera/panorama"
            else "3D scans"
            if p.startswith("/world/odom/robot/scan")
            else "panorama overlays"
            if p.startswith("/camera/panorama/")
            else "faces"
            if p.startswith("/camera/faces")
            else "other"
        )
        groups[key] += chunk.to_record_batch().nbytes
    return groups


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--frames", type=int, default=300, help="frames of 10 Hz data (default 300 = 30 s)")
    ap.add_argument("--faces-every", type=int, default=None)
    ap.add_argument("--image-width", type=int, default=None)
    ap.add_argument("--recording", default=None, help="take frames from this recording (needs --rig)")
    ap.add_argument("--rig", default=None)
    args = ap.parse_args(argv)
    from studio.viz.log import RunLogger

    rng = np.random.default_rng(0)
    t = time.perf_counter()
    rig = RIG
    if args.recording:
        frames, percs, run, rig = frames_from_recording(Path(args.recording), Path(args.rig), args.frames)
        args.frames = len(frames)
        print(
            f"{args.recording}: {len(frames)} frames, source JPEG "
            f"{np.mean([len(f.panorama.encoded) for f in frames]) / 1e3:.0f} KB on average"
        )  # type: ignore[union-attr]
    else:
        frames, percs, run = make_sequence(args.frames, rng)
        print(
            f"synthetic sequence: {args.frames} frames, source JPEG "
            f"{len(frames[0].panorama.encoded) / 1e3:.0f} KB "  # type: ignore[union-attr]
            f"({time.perf_counter() - t:.1f} s to build)"
        )
    kw = {}
    if args.faces_every is not None:
        kw["faces_every"] = args.faces_every
    if args.image_width is not None:
        kw["image_width"] = args.image_width
    with tempfile.TemporaryDirectory() as tmp:
        rrd = Path(tmp) / "recording.rrd"
        logger = RunLogger(rrd, rig=rig, **kw)
        per = []
        c0 = time.process_time()
        for f, pf in zip(frames, percs, strict=True):
            s0 = logger.seconds
            logger.on_frame(f, pf)
            per.append(logger.seconds - s0)
        cpu = time.process_time() - c0
        t = time.perf_counter()
        logger.finish(run)
        t_fin = time.perf_counter() - t
        size = rrd.stat().st_size
        groups = _breakdown(rrd)
    per_ms = np.array(per) * 1e3
    minutes = args.frames / 10.0 / 60.0
    print(
        f"on_frame: median {np.median(per_ms):.1f} ms, mean {per_ms.mean():.1f} ms, p90 "
        f"{np.percentile(per_ms, 90):.1f} ms per frame (budget ~30 ms: 15 % of 200 ms); CPU time "
        f"{cpu / args.frames * 1e3:.1f} ms per frame, all threads (wall times grow on a loaded machine: "
        f"load average {os.getloadavg()[0]:.1f} on {os.cpu_count()} cores)"
    )
    print(f"finish: {t_fin:.2f} s for {args.frames} frames ({t_fin / args.frames * 1e3:.2f} ms per frame)")
    print(
        "arrow bytes per frame: "
        + ", ".join(f"{k} {v / args.frames / 1e3:.1f} KB" for k, v in groups.items())
    )
    print(
        f"recording: {size / 1e6:.1f} MB for {args.frames} frames = {size / 1e6 / minutes:.1f} MB per minute "
        f"of 10 Hz data (target ≤ 30), {size / args.frames / 1e3:.1f} KB per frame"
    )
    return 0


if __name__ == "__main__":
    sys.exit(main())
