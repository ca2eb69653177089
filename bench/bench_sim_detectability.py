"""How many of the simulator's rendered people does the bundled image detector find?

Simulates a scenario (or reads an existing ``studio simulate`` output), runs the image detector on every
``--every``-th panorama and matches its boxes to the ground-truth boxes of camera-visible people
(one-to-one, IoU ≥ ``--iou`` on the unrolled panorama, seam-aware). Prints the recall for people within
6 m (the target is ≥ 80 %), by distance band, and the number of unmatched detections per frame.

    .venv/bin/python bench/bench_sim_detectability.py --scenario moving --seconds 30 --seed 1
    .venv/bin/python bench/bench_sim_detectability.py --dir /tmp/sim --detector centernet
"""

from __future__ import annotations

import argparse
import json
import tempfile
import time
from pathlib import Path
from typing import Any

import cv2
import numpy as np
from rosbags.highlevel import AnyReader
from rosbags.typesys import Stores, get_typestore
from scipy.optimize import linear_sum_assignment

from studio.detect.image import get_image_detector
from studio.sim import simulate

BANDS = ((0.0, 2.0), (2.0, 4.0), (4.0, 6.0), (6.0, 10.0))


def iou_seam(a: np.ndarray, b: np.ndarray, width: int) -> float:
    """IoU of two panorama boxes, trying b shifted by ±W (seam)."""
    best = 0.0
    for shift in (-width, 0, width):
        u1, v1 = max(a[0], b[0] + shift), max(a[1], b[1])
        u2, v2 = min(a[2], b[2] + shift), min(a[3], b[3])
        inter = max(0.0, u2 - u1) * max(0.0, v2 - v1)
        union = (a[2] - a[0]) * (a[3] - a[1]) + (b[2] - b[0]) * (b[3] - b[1]) - inter
        best = max(best, inter / union if union > 0 else 0.0)
    return best


def images(recording: Path, topic: str) -> dict[int, np.ndarray]:
    out = {}
    with AnyReader([recording], default_typestore=get_typestore(Stores.ROS2_HUMBLE)) as reader:
        conns = [c for c in reader.connections if c.topic == topic]
        for conn, _, raw in reader.messages(connections=conns):
            msg = reader.deserialize(raw, conn.msgtype)
            stamp = int(msg.header.stamp.sec) * 1_000_000_000 + int(msg.header.stamp.nanosec)
            out[stamp] = np.frombuffer(bytes(msg.data), np.uint8)
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--dir", type=Path, default=None, help="existing studio simulate output (else simulate)")
    ap.add_argument("--scenario", default="moving")
    ap.add_argument("--seconds", type=float, default=30.0)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--every", type=int, default=5, help="use every N-th panorama")
    ap.add_argument("--detector", default="movenet")
    ap.add_argument("--iou", type=float, default=0.3)
    ap.add_argument("--save", type=Path, default=None, help="write annotated PNGs of the first frames here")
    args = ap.parse_args()

    if args.dir is None:
        tmp = Path(tempfile.mkdtemp(prefix="simdet."))
        t0 = time.perf_counter()
        res = simulate(args.scenario, out=tmp / "sim", seconds=args.seconds, seed=args.seed)
        took = time.perf_counter() - t0
        print(f"simulated {args.scenario} {args.seconds:.0f} s seed {args.seed} in {took:.1f} s")
        sim_dir = res.out
    else:
        sim_dir = args.dir
    gt = [json.loads(line) for line in (sim_dir / "ground_truth.jsonl").read_text().splitlines()]
    pics = images(sim_dir / "recording.mcap", "/theta_camera/image/compressed")
    det = get_image_detector(args.detector)
    found = dict.fromkeys(BANDS, 0)
    total = dict.fromkeys(BANDS, 0)
    mostly = [0, 0]  # found, total among people within 6 m with at least half of the figure visible
    extra = 0
    n_frames = 0
    t_det = 0.0
    for frame in gt[:: args.every]:
        img = cv2.imdecode(pics[frame["stamp_ns"]], cv2.IMREAD_COLOR)
        t0 = time.perf_counter()
        d = det.detect(img)
        t_det += time.perf_counter() - t0
        n_frames += 1
        people = [p for p in frame["people"] if p["visible"]["camera"] and p.get("box")]
        boxes = np.asarray(d.boxes)
        cost = np.ones((len(people), len(boxes)))
        for i, p in enumerate(people):
            for j, b in enumerate(boxes):
                cost[i, j] = 1.0 - iou_seam(np.asarray(p["box"]), b, img.shape[1])
        matched = set()
        if cost.size:
            rows, cols = linear_sum_assignment(cost)
            matched = {(r, c) for r, c in zip(rows, cols, strict=True) if cost[r, c] <= 1.0 - args.iou}
        hit_people = {r for r, _ in matched}
        extra += len(boxes) - len(matched)
        for i, p in enumerate(people):
            if p["range"] < 6.0 and p["visible_frac"] >= 0.5:
                mostly[0] += int(i in hit_people)
                mostly[1] += 1
            for band in BANDS:
                if band[0] <= p["range"] < band[1]:
                    total[band] += 1
                    found[band] += int(i in hit_people)
        if args.save is not None and n_frames <= 6:
            args.save.mkdir(parents=True, exist_ok=True)
            vis = img.copy()
            for p in people:
                u1, v1, u2, v2 = (int(v) for v in p["box"])
                cv2.rectangle(vis, (u1, v1), (u2, v2), (0, 255, 0), 2)
            for b, s in zip(boxes, d.scores, strict=True):
                u1, v1, u2, v2 = (int(v) for v in b)
                cv2.rectangle(vis, (u1, v1), (u2, v2), (0, 0, 255), 1)
                cv2.putText(vis, f"{s:.2f}", (u1, v1 - 3), 0, 0.4, (0, 0, 255), 1)
            cv2.imwrite(str(args.save / f"det_{frame['frame']:05d}.png"), vis)
    print(f"detector {args.detector}: {n_frames} panoramas, {t_det / max(n_frames, 1) * 1000:.0f} ms each")
    for band in BANDS:
        r = found[band] / total[band] if total[band] else float("nan")
        print(f"  range {band[0]:.0f}–{band[1]:.0f} m: {found[band]}/{total[band]} found ({100 * r:.0f} %)")
    near = [b for b in BANDS if b[1] <= 6.0]
    f6, t6 = sum(found[b] for b in near), sum(total[b] for b in near)
    summary: dict[str, Any] = {
        "recall_within_6m": f6 / t6 if t6 else None,
        "visible_within_6m": t6,
        "recall_within_6m_half_visible": mostly[0] / mostly[1] if mostly[1] else None,
        "unmatched_detections_per_frame": extra / max(n_frames, 1),
    }
    print(json.dumps(summary))


if __name__ == "__main__":
    main()
