"""``studio label`` laser-only on real scans: the labels against leg_tracker's labelled legs.

    .venv/bin/python bench/bench_real_labels.py
    .venv/bin/python bench/bench_real_labels.py --every 2     # as a scanner with 0.70° beams would see it

Data: ``../shared/data/leg_tracker/legs_labelled/*.bag`` (Leigh et al., ICRA 2015; BSD-3-Clause): a static
robot's scans (``/training_scan``, no TF, no odometry) with the legs of the people walking in a ±15° / 5 m
wedge in front of it labelled in every scan (``/leg_cluster_positions``). Each bag is labelled as a user
would (a rig naming the scan's own frame as ``base_frame``, laser only) and compared, scan by scan, with
the people made from the labelled legs (the closest legs within 0.6 m pair into their midpoint, else the
leg alone), inside a ±17° / 5.3 m wedge (the labels' wedge with a margin), one-to-one within 0.3 m (the
labels are leg clusters, so a person's true centre is known to ~0.1 m) and within 0.2 m (the thesis's
radius).

Printed per bag and for all: recall and precision of the labels in the wedge, the same for the fused
per-scan detections before tracking (what tracking adds), and the labelled people per scan outside the
wedge. Nobody was labelled outside the wedge, but people walking in it also step out of it near the robot
(the wedge is 0.5 m wide at 1 m), so that last count is an upper bound of the clutter labelled, not a
false-positive count. Identities are not labelled, so no MOTA here.

``--every K`` labels a copy of each bag whose scans keep every K-th beam (:func:`thinned_bag`): the same
people as a scanner with K times coarser beams (0.70° for 2, 1.05° for 3) sees them.
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_laser_detector import PERSON_MATCH, in_wedge, match_count, persons_from_legs
from laser_data import DATA, labelled_scans

from studio.io import decode_scan, load_rig, open_recording
from studio.pipeline import LabelOptions
from studio.pipeline.label import label_recording

TOPIC = "/training_scan"
RADII = (PERSON_MATCH, 0.2)


def scan_frame(bag: Path) -> str:
    """The frame_id of the bag's first labelled scan (these bags have no TF)."""
    with open_recording(bag) as rec:
        for raw in rec.messages([TOPIC]):
            return decode_scan(rec.decode(raw), raw.log_ns).frame_id
    raise SystemExit(f"{bag}: no {TOPIC}")


def thinned_bag(src: Path, dst: Path, every: int = 1, *, step_deg: float | None = None) -> Path:
    """A copy of the ROS1 bag ``src`` at ``dst`` whose ``LaserScan`` messages keep every ``every``-th beam
    (the first, the ``every + 1``-th, …), or with ``step_deg`` the beam nearest to each multiple of
    ``step_deg`` from the first (as a scanner with beams that far apart sees the scene, to within half the
    recorded step); all else is copied as it is."""
    from rosbags.rosbag1 import Reader, Writer
    from rosbags.typesys import Stores, get_typestore

    store = get_typestore(Stores.ROS1_NOETIC)
    with Reader(src) as reader, Writer(dst) as writer:
        out = {
            c.id: writer.add_connection(c.topic, c.msgtype, msgdef=c.msgdef.data, md5sum=c.digest)
            for c in reader.connections
        }
        for c, t, raw in reader.messages():
            if c.msgtype.endswith("LaserScan"):
                m = store.deserialize_ros1(raw, c.msgtype)
                n = len(m.ranges)
                step = every * m.angle_increment if step_deg is None else np.radians(step_deg)
                keep = np.round(np.arange(0.0, m.angle_increment * (n - 1) + 1e-9, step) / m.angle_increment)
                keep = keep.astype(np.int64)
                m = replace(
                    m,
                    ranges=np.ascontiguousarray(m.ranges[keep]),
                    intensities=np.ascontiguousarray(m.intensities[keep])
                    if len(m.intensities) == n
                    else m.intensities,
                    angle_increment=float(step),
                    angle_max=float(m.angle_min + step * (len(keep) - 1)),
                )
                raw = store.serialize_ros1(m, c.msgtype)
            writer.write(out[c.id], t, raw)
    return dst


def score(pred: list[np.ndarray], gt: list[np.ndarray], radius: float) -> tuple[int, int, int]:
    """TP, FP, FN of per-scan predictions (in the wedge) against per-scan ground truth."""
    tp = fp = fn = 0
    for p, g in zip(pred, gt, strict=True):
        m = match_count(p, g, radius)
        tp, fp, fn = tp + m, fp + len(p) - m, fn + len(g) - m
    return tp, fp, fn


def pr(tp: int, fp: int, fn: int) -> str:
    r, p = tp / max(tp + fn, 1), tp / max(tp + fp, 1)
    return f"R {r:.3f} P {p:.3f} F1 {2 * p * r / max(p + r, 1e-9):.3f}"


def label_and_score(
    bag: Path, tmp: Path, every: int = 1
) -> tuple[dict[tuple[str, float], np.ndarray], int, int, int, float]:
    """Label ``bag`` (thinned to every ``every``-th beam) laser-only and score it: ``{("labels" |
    "detections", radius): [tp, fp, fn]}``, the scans scored, the tracks, the labelled people outside the
    wedge and the seconds it took."""
    rig_path = tmp / "rig.yaml"
    rig_path.write_text(f"base_frame: {scan_frame(bag)}\nlasers:\n  - topic: {TOPIC}\n")
    src = bag if every == 1 else thinned_bag(bag, tmp / f"{bag.stem}-every{every}.bag", every)
    t = time.perf_counter()
    run = label_recording(src, load_rig(rig_path), options=LabelOptions(sources="laser"))
    dt = time.perf_counter() - t
    legs_of = {s.stamp_ns: legs for s, legs in labelled_scans(bag)}
    gt, labels, fused = [], [], []
    outside = 0
    for lf, fr in zip(run.labels, run.detections, strict=True):
        if lf.stamp_ns not in legs_of:
            continue
        g = persons_from_legs(legs_of[lf.stamp_ns])
        gt.append(g[in_wedge(g, deg=17.0, rmax=5.3)])
        xy = np.array([[p.x, p.y] for p in lf.people], dtype=np.float64).reshape(-1, 2)
        w = in_wedge(xy, deg=17.0, rmax=5.3)
        labels.append(xy[w])
        outside += int((~w).sum())
        fxy = fr.observations.xy.reshape(-1, 2)
        fused.append(fxy[in_wedge(fxy, deg=17.0, rmax=5.3)])
    counts = {}
    for r in RADII:
        counts["labels", r] = np.array(score(labels, gt, r))
        counts["detections", r] = np.array(score(fused, gt, r))
    n_tracks = len({p.id for lf in run.labels for p in lf.people})
    return counts, len(gt), n_tracks, outside, dt


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--every", type=int, default=1, help="label copies whose scans keep every K-th beam")
    args = ap.parse_args()
    if args.every < 1:
        raise SystemExit("--every must be >= 1")
    bags = sorted((DATA / "legs_labelled").glob("*.bag"))
    if not bags:
        raise SystemExit(f"no bags in {DATA / 'legs_labelled'}")
    total = {(k, r): np.zeros(3, int) for k in ("labels", "detections") for r in RADII}
    outside = scans_all = 0
    with tempfile.TemporaryDirectory() as tmp:
        for bag in bags:
            counts, n, n_tracks, out_here, dt = label_and_score(bag, Path(tmp), args.every)
            line = [f"{bag.stem}: {n} scans, {n_tracks} tracks, {dt:.1f} s"]
            for r in RADII:
                line.append(
                    f"@{r} m labels {pr(*counts['labels', r])} | detections {pr(*counts['detections', r])}"
                )
            line.append(f"labelled people outside the wedge {out_here / max(n, 1):.2f} per scan")
            print("\n  ".join(line), flush=True)
            total = {k: v + counts[k] for k, v in total.items()}
            outside += out_here
            scans_all += n
    print(f"all {len(bags)} bags, {scans_all} scans:")
    for r in RADII:
        print(f"  @{r} m labels {pr(*total['labels', r])} | detections {pr(*total['detections', r])}")
    per_scan = outside / max(scans_all, 1)
    print(f"  labelled people outside the wedge {per_scan:.2f} per scan (an upper bound of the clutter)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
