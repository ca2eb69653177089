"""Drift correction by scan matching: pose error against the simulator's truth, cost, and a real bag.

    .venv/bin/python bench/bench_scan_matching.py
    .venv/bin/python bench/bench_scan_matching.py --recordings moving:1 rooms:1 --no-real

For each simulated recording (those of ``bench/run_table.py``, made on first use) pass one runs laser-only
(``studio label``'s reader, laser detector and :class:`studio.geometry.scan_match.ScanOdometry`); the
wheel odometry's and the corrected poses are compared with the true robot pose (``robot_world`` in the
ground truth, relative to the first frame): largest and final position and heading errors, and the time
per frame. On leg_tracker's ``negative_2.bag`` (a real robot driving through an empty room, no odometry,
no TF; its left scanner) it draws the scans in the world frame with the robot taken as static (what the
product did before) and with scan matching into ``bench/out/scan_matching_negative_2.png``, and counts
the false tracks ``studio label`` makes (nobody is in that room) with and without scan matching.
"""

from __future__ import annotations

import argparse
import json
import time
from dataclasses import replace
from pathlib import Path

import cv2
import numpy as np
from run_table import OUT, recording

from studio.geometry.se import Pose2
from studio.io import load_rig
from studio.pipeline import LabelOptions
from studio.pipeline.label import label_recording
from studio.pipeline.perceive import perceive

DATA = Path(__file__).resolve().parents[2] / "shared" / "data" / "leg_tracker"


def pose_errors(truth: list[Pose2], est: list[Pose2]) -> tuple[float, float, float, float]:
    """Largest and final position (m) and heading (deg) error of ``est`` against ``truth``."""
    e = []
    for t, p in zip(truth, est, strict=True):
        rel = t.inverse().compose(p)
        e.append((float(np.hypot(rel.x, rel.y)), float(np.degrees(abs(rel.yaw)))))
    a = np.array(e)
    return float(a[:, 0].max()), float(a[-1, 0]), float(a[:, 1].max()), float(a[-1, 1])


def simulated(scenario: str, seed: int) -> None:
    rec = recording(scenario, None, seed)
    options = LabelOptions(sources="laser")
    t = time.perf_counter()
    frames, info = perceive(rec / "recording.mcap", load_rig(rec / "rig.yaml"), options)
    wall = time.perf_counter() - t
    rows = {}
    for line in (rec / "ground_truth.jsonl").read_text().splitlines():
        r = json.loads(line)
        rows[r["frame"]] = r["robot_world"]
    world = [Pose2(rows[f.index]["x"], rows[f.index]["y"], rows[f.index]["yaw"]) for f in frames]
    start = world[0].inverse()
    truth = [start.compose(w) for w in world]
    odo = pose_errors(truth, [f.robot_pose for f in frames])
    sm = pose_errors(truth, [f.world_pose for f in frames])
    ms = 1e3 * info["timings_s"]["scan_matching"] / len(frames)
    print(
        f"{rec.name:22s} odometry max {odo[0]:.2f} m {odo[2]:.2f}° end {odo[1]:.2f} m {odo[3]:.2f}° | "
        f"scan matching max {sm[0]:.3f} m {sm[2]:.2f}° end {sm[1]:.3f} m {sm[3]:.2f}° | "
        f"{ms:.1f} ms/frame ({info['scan_matching']}; pass one {wall:.0f} s)",
        flush=True,
    )


def real() -> None:
    bag = DATA / "negative_2.bag"
    rig_path = OUT / "negative_2_rig.yaml"
    rig_path.parent.mkdir(parents=True, exist_ok=True)
    rig_path.write_text("base_frame: left_laser\nlasers:\n  - topic: /left_scan\n")
    rig = load_rig(rig_path)
    frames, info = perceive(bag, rig, LabelOptions(sources="laser"))
    print(f"\nnegative_2.bag (left scanner, no odometry): {info['scan_matching']}, "
          f"{1e3 * info['timings_s']['scan_matching'] / len(frames):.1f} ms/frame")  # fmt: skip
    img = np.full((800, 1600, 3), 255, np.uint8)
    for k, (name, get) in enumerate(
        (("robot taken as static", lambda f: Pose2()), ("scan matching", lambda f: f.world_pose))
    ):
        for f in frames[::3]:
            p = get(f).apply(f.points[np.isfinite(f.points[:, 0]), :2].astype(np.float64))
            u = (p[:, 0] * 40 + 400 + 800 * k).astype(np.int64)
            v = (250 - p[:, 1] * 40).astype(np.int64)
            ok = (u >= 800 * k) & (u < 800 * (k + 1)) & (v >= 0) & (v < 800)
            img[v[ok], u[ok]] = 0
        cv2.putText(img, name, (20 + 800 * k, 40), cv2.FONT_HERSHEY_SIMPLEX, 1.0, (200, 0, 0), 2)
    out = OUT / "scan_matching_negative_2.png"
    cv2.imwrite(str(out), img)
    print(f"  scans in the world frame (1 px = 2.5 cm, every 3rd scan): {out}")
    for on in (False, True):
        run = label_recording(bag, rig, options=replace(LabelOptions(sources="laser"), scan_matching=on))
        people = sum(len(f.people) for f in run.labels)
        tracks = len({p.id for f in run.labels for p in f.people})
        print(
            f"  studio label, scan matching {'on ' if on else 'off'}: {tracks} false tracks, "
            f"{people / len(run.labels):.2f} false people per frame (the room is empty)"
        )


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument(
        "--recordings",
        nargs="*",
        default=["moving:1", "moving:2", "moving:3", "rooms:1", "static:1"],
        help="simulated recordings as scenario:seed",
    )
    ap.add_argument("--no-real", action="store_true", help="skip leg_tracker's negative_2.bag")
    args = ap.parse_args()
    for spec in args.recordings:
        scenario, seed = spec.split(":")
        simulated(scenario, int(seed))
    if not args.no_real:
        real()


if __name__ == "__main__":
    main()
