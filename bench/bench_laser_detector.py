"""Benchmark of the classical laser people detector and the static-world filter on real scans.

    .venv/bin/python bench/bench_laser_detector.py [--threshold 0.5] [--png bench/laser_detector_sweep.png]

Data: ``../shared/data/leg_tracker`` (Leigh et al., ICRA 2015; BSD-3-Clause).

* legs_labelled/*: leg-level recall / precision of the leg candidates (before pairing), matched one-to-one
  (Hungarian) to the labelled legs within 0.15 m. The labels are automatically extracted clusters inside a
  ±15° / 5 m wedge, so they are imperfect (two touching legs are sometimes one label). Precision is given
  for the whole scan (no people outside the wedge in these recordings) and for the wedge alone.
* negative_2.bag: 3 scanners, rooms without people: every person detection is a false positive. The robot
  moves and the bag has no odometry or TF, so the odom frame comes from scan matching (ICP, bench only).
  Filters: "body" = static map in the laser frame (returns from the robot itself), "world" = static map in
  odom, "both" (the StaticMap defaults), "aggressive" (both, occupied 0.5 / min_share 0.5 / dilate 2).
* positive/*.bag: static robot, people walk inside a ±15° / 5 m wedge: detections outside it are clutter
  (false-positive proxy), inside it people are present most of the time.
* ms per scan of the detector (and of the map building, per scan).

Writes a threshold sweep (TP / FP / FN vs score, like the thesis' Figure 4.5) to ``--png``.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np
from scipy.optimize import linear_sum_assignment

sys.path.insert(0, str(Path(__file__).resolve().parent))
from laser_data import DATA, Scan, icp_odometry, labelled_scans, read_scans

from studio.detect.laser import LaserDetections, get_laser_detector
from studio.detect.laser.classical import ClassicalLaserDetector
from studio.detect.laser.static_map import StaticMap

MATCH = 0.15
PERSON_MATCH = 0.3
THRESHOLDS = np.round(np.arange(0.05, 1.0, 0.05), 2)


def in_wedge(xy: np.ndarray, *, deg: float = 15.0, rmax: float = 5.0) -> np.ndarray:
    ang = np.degrees(np.arctan2(xy[:, 1], xy[:, 0]))
    return (np.abs(ang) <= deg) & (np.hypot(xy[:, 0], xy[:, 1]) <= rmax)


def match_count(det: np.ndarray, gt: np.ndarray, radius: float) -> int:
    """One-to-one matches within ``radius`` (Hungarian on distances)."""
    if len(det) == 0 or len(gt) == 0:
        return 0
    d = np.hypot(*(det[:, None, :] - gt[None, :, :]).transpose(2, 0, 1))
    cost = np.where(d <= radius, d, 1e6)
    r, c = linear_sum_assignment(cost)
    return int((cost[r, c] <= radius).sum())


def persons_from_legs(legs: np.ndarray, *, max_gap: float = 0.6) -> np.ndarray:
    """Person positions from labelled legs: closest leg pairs within ``max_gap`` → midpoint, else the leg."""
    n = len(legs)
    used = np.zeros(n, dtype=bool)
    out = []
    d = np.hypot(*(legs[:, None, :] - legs[None, :, :]).transpose(2, 0, 1))
    a, b = np.triu_indices(n, 1)
    for k in np.argsort(d[a, b], kind="stable"):
        i, j = a[k], b[k]
        if d[i, j] <= max_gap and not used[i] and not used[j]:
            used[i] = used[j] = True
            out.append((legs[i] + legs[j]) / 2.0)
    out += [legs[i] for i in np.flatnonzero(~used)]
    return np.array(out, dtype=np.float64).reshape(-1, 2)


def bench_labelled(det: ClassicalLaserDetector) -> tuple[dict[str, np.ndarray], dict[str, np.ndarray]]:
    """Leg level: TP / FP (whole scan) / FP (wedge) / FN per threshold; person level: the same (wedge)."""
    tp, fp, fpw, ptp, pfp = (np.zeros(len(THRESHOLDS)) for _ in range(5))
    n_gt = n_people = n_scans = 0
    for bag in sorted((DATA / "legs_labelled").glob("*.bag")):
        for scan, legs in labelled_scans(bag):
            n_scans += 1
            n_gt += len(legs)
            people_gt = persons_from_legs(legs)
            n_people += len(people_gt)
            cand = det.legs(scan.points, valid=scan.valid)
            people = det.people(cand)
            wedge = in_wedge(cand.xy, deg=17.0, rmax=5.3)
            pwedge = in_wedge(people.xy, deg=17.0, rmax=5.3)
            for k, t in enumerate(THRESHOLDS):
                keep = cand.scores >= t
                m = match_count(cand.xy[keep], legs, MATCH)
                tp[k] += m
                fp[k] += keep.sum() - m
                fpw[k] += (keep & wedge).sum() - m
                pk = (people.scores >= t) & pwedge
                pm = match_count(people.xy[pk], people_gt, PERSON_MATCH)
                ptp[k] += pm
                pfp[k] += pk.sum() - pm
    legs_res = {"tp": tp, "fp": fp, "fp_wedge": fpw, "fn": n_gt - tp, "n_gt": np.array(n_gt)}
    legs_res["n_scans"] = np.array(n_scans)
    people_res = {"tp": ptp, "fp": pfp, "fn": n_people - ptp, "n_gt": np.array(n_people)}
    return legs_res, people_res


def detect_all(det: ClassicalLaserDetector, scans: list[Scan]) -> tuple[list[LaserDetections], float]:
    t0 = time.perf_counter()
    out = [det.detect(s.points, valid=s.valid) for s in scans]
    return out, (time.perf_counter() - t0) / max(1, len(scans)) * 1e3


PRESETS: dict[str, dict[str, Any]] = {
    "both": {"occupied": 0.7, "min_share": 0.7, "dilate": 1},  # the StaticMap defaults
    "aggressive": {"occupied": 0.5, "min_share": 0.5, "dilate": 2},
}
FILTERS = ("none", "body", "world", "both", "aggressive")


def filtered(
    dets: list[LaserDetections], scans: list[Scan], poses: list[np.ndarray] | None
) -> tuple[dict[str, list[LaserDetections]], float]:
    """Detections after the static filters: "body" (laser-frame map), "world" (odom map), "both", and
    "aggressive" (both, with the aggressive preset); and the ms per scan to build the maps."""
    out: dict[str, list[LaserDetections]] = {k: [] for k in FILTERS}
    out["none"] = dets
    t0 = time.perf_counter()
    if poses is None:
        odom = [s.points for s in scans]
        origins = [np.zeros(2) for _ in scans]
    else:
        odom = [s.points @ p[:2, :2].T + p[:2, 2] for s, p in zip(scans, poses, strict=True)]
        origins = [p[:2, 2] for p in poses]
    maps = {}
    for name, pre in PRESETS.items():
        body = StaticMap.build(((s.points, np.zeros(2)) for s in scans), dilate=pre["dilate"])
        world = (
            body if poses is None else StaticMap.build(zip(odom, origins, strict=True), dilate=pre["dilate"])
        )
        maps[name] = (body, world)
    ms = (time.perf_counter() - t0) / max(1, len(scans)) * 1e3 / len(PRESETS)
    for d, s, o in zip(dets, scans, odom, strict=True):
        for name, pre in PRESETS.items():
            kw = {"occupied": pre["occupied"], "min_share": pre["min_share"]}
            body, world = maps[name]
            sb = body.is_static(d, s.points, **kw)
            sw = world.is_static(d, o, **kw)
            out[name].append(d.select(~(sb | sw)))
            if name == "both":
                out["body"].append(d.select(~sb))
                out["world"].append(d.select(~sw))
    return out, ms


def bench_labelled_static(det: ClassicalLaserDetector, thr: float) -> dict[str, tuple[float, float]]:
    """Person recall (wedge) and clutter per scan (outside the wedge) on legs_labelled with each filter.

    The maps are built from the labelled scans alone (static robot): those are the scans *with* people,
    so the people's cells look more occupied than over the full recording (a pessimistic test).
    """
    acc = {k: [0, 0, 0, 0] for k in ("none", "both", "aggressive")}
    for bag in sorted((DATA / "legs_labelled").glob("*.bag")):
        lab = labelled_scans(bag)
        scans = [s for s, _ in lab]
        dets = [det.detect(s.points, valid=s.valid).above(thr) for s in scans]
        fl, _ = filtered(dets, scans, None)
        for k, a in acc.items():
            for d, (_, legs) in zip(fl[k], lab, strict=True):
                gt = persons_from_legs(legs)
                w = in_wedge(d.xy, deg=17.0, rmax=5.3)
                a[0] += match_count(d.xy[w], gt, PERSON_MATCH)
                a[1] += len(gt)
                a[2] += int((~w).sum())
                a[3] += 1
    return {k: (a[0] / a[1], a[2] / a[3]) for k, a in acc.items()}


def main() -> int:
    ap = argparse.ArgumentParser(description="classical laser detector benchmark")
    ap.add_argument("--threshold", type=float, default=0.5, help="person score threshold for the tables")
    ap.add_argument("--png", type=Path, default=Path(__file__).resolve().parent / "laser_detector_sweep.png")
    args = ap.parse_args()
    det = get_laser_detector("classical")
    assert isinstance(det, ClassicalLaserDetector)
    thr = args.threshold

    # -- leg level ---------------------------------------------------------------------------------
    legs, people = bench_labelled(det)
    print(f"legs_labelled: {int(legs['n_scans'])} scans, {int(legs['n_gt'])} labelled legs, match {MATCH} m")
    print(
        f"{'thr':>5} {'TP':>6} {'FP':>6} {'FP wedge':>8} {'FN':>6} {'recall':>7} {'prec':>6} "
        f"{'prec wedge':>10}"
    )
    for ki, t in enumerate(THRESHOLDS):
        if round(t * 20) % 2 == 0 or abs(t - thr) < 1e-9:
            tp, fp, fpw, fn = legs["tp"][ki], legs["fp"][ki], legs["fp_wedge"][ki], legs["fn"][ki]
            print(
                f"{t:5.2f} {tp:6.0f} {fp:6.0f} {fpw:8.0f} {fn:6.0f} {tp / (tp + fn):7.3f} "
                f"{tp / max(1, tp + fp):6.3f} {tp / max(1, tp + fpw):10.3f}"
            )

    print(
        f"\npersons on legs_labelled (labelled legs ≤ 0.6 m apart = one person; {int(people['n_gt'])} "
        f"persons; inside the wedge; match {PERSON_MATCH} m)"
    )
    print(f"{'thr':>5} {'TP':>6} {'FP':>6} {'FN':>6} {'recall':>7} {'prec':>6}")
    for ki, t in enumerate(THRESHOLDS):
        if round(t * 20) % 2 == 0 or abs(t - thr) < 1e-9:
            tp, fp, fn = people["tp"][ki], people["fp"][ki], people["fn"][ki]
            print(f"{t:5.2f} {tp:6.0f} {fp:6.0f} {fn:6.0f} {tp / (tp + fn):7.3f} {tp / max(1, tp + fp):6.3f}")

    # -- negative_2: false positives per scan ------------------------------------------------------
    print("\nnegative_2.bag (no people; odom from ICP scan matching):")
    neg_counts: dict[str, list[np.ndarray]] = {k: [] for k in FILTERS}
    ms_det, ms_map, n_neg = [], [], 0
    for topic in ("/left_scan", "/rear_scan", "/right_scan"):
        scans = list(read_scans(DATA / "negative_2.bag", [topic]))
        poses = icp_odometry(scans)
        dets, ms = detect_all(det, scans)
        fl, msm = filtered(dets, scans, poses)
        ms_det.append(ms)
        ms_map.append(msm)
        n_neg += len(scans)
        for k, v in fl.items():
            neg_counts[k].append(np.array([[(d.scores >= t).sum() for t in THRESHOLDS] for d in v]))
    neg = {k: np.concatenate(v).mean(0) for k, v in neg_counts.items()}
    ti = int(np.argmin(np.abs(THRESHOLDS - thr)))
    print(f"  {n_neg} scans, person detections/scan at score >= {thr}:")
    for k in FILTERS:
        print(f"    filter {k:10s}: {neg[k][ti]:6.2f}")

    # -- positive: inside vs outside the wedge -----------------------------------------------------
    print(f"\npositive/*.bag (static robot, people in the ±15°/5 m wedge), score >= {thr}:")
    print(f"{'bag':>12} {'scans':>5} {'filter':>10} {'in/scan':>7} {'scans w/ in':>11} {'out/scan (FP)':>13}")
    shown = ("none", "both", "aggressive")
    pos_out: dict[str, list[np.ndarray]] = {k: [] for k in shown}
    pos_in: dict[str, list[np.ndarray]] = {k: [] for k in shown}
    for bag in sorted((DATA / "positive").glob("*.bag")):
        scans = list(read_scans(bag))
        dets, ms = detect_all(det, scans)
        fl, msm = filtered(dets, scans, None)
        ms_det.append(ms)
        ms_map.append(msm)
        for k in shown:
            ins = np.array([[(in_wedge(d.xy) & (d.scores >= t)).sum() for t in THRESHOLDS] for d in fl[k]])
            outside = [~in_wedge(d.xy, deg=17.0, rmax=5.3) for d in fl[k]]
            outs = np.array(
                [
                    [(o & (d.scores >= t)).sum() for t in THRESHOLDS]
                    for o, d in zip(outside, fl[k], strict=True)
                ]
            )
            pos_in[k].append(ins)
            pos_out[k].append(outs)
            print(
                f"{bag.stem:>12} {len(scans):5d} {k:>10} {ins[:, ti].mean():7.2f} "
                f"{(ins[:, ti] > 0).mean():11.2f} {outs[:, ti].mean():13.2f}"
            )
    pin = {k: np.concatenate(v) for k, v in pos_in.items()}
    pout = {k: np.concatenate(v) for k, v in pos_out.items()}
    for k in shown:
        print(
            f"{'all':>12} {len(pin[k]):5d} {k:>10} {pin[k][:, ti].mean():7.2f} "
            f"{(pin[k][:, ti] > 0).mean():11.2f} {pout[k][:, ti].mean():13.2f}"
        )
    print(f"\nstatic filter vs people (legs_labelled, maps from the labelled scans), score >= {thr}:")
    for k, (rec, clutter) in bench_labelled_static(det, thr).items():
        print(f"    filter {k:10s}: person recall {rec:.3f}, detections outside the wedge/scan {clutter:.2f}")
    print(
        f"\nms per scan: detector {np.mean(ms_det):.2f} (768 beams), "
        f"static maps (body+world, per preset) {np.mean(ms_map):.2f}"
    )
    save_png(args.png, legs, people, neg, pin, pout)
    print(f"sweep plot: {args.png}")
    return 0


def save_png(
    path: Path,
    legs: dict[str, np.ndarray],
    people: dict[str, np.ndarray],
    neg: dict[str, np.ndarray],
    pin: dict[str, np.ndarray],
    pout: dict[str, np.ndarray],
) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(1, 2, figsize=(13, 5))
    a = ax[0]
    a.plot(THRESHOLDS, legs["tp"], "g-o", ms=3, label="TP")
    a.plot(THRESHOLDS, legs["fp"], "r-o", ms=3, label="FP (whole scan)")
    a.plot(THRESHOLDS, legs["fp_wedge"], "r--", label="FP (labelled wedge)")
    a.plot(THRESHOLDS, legs["fn"], "b-o", ms=3, label="FN")
    a.set_xlabel("leg score threshold")
    a.set_ylabel("legs")
    a.set_yscale("log")
    a.set_title(f"legs_labelled: {int(legs['n_scans'])} scans, {int(legs['n_gt'])} legs (match 0.15 m)")
    a.grid(alpha=0.3)
    a.legend()
    a = ax[1]
    for k, st in (("none", "-"), ("both", "--"), ("aggressive", ":")):
        a.plot(THRESHOLDS, neg[k], "r" + st, label=f"negative_2 FP/scan (filter {k})")
        a.plot(THRESHOLDS, pout[k].mean(0), "m" + st, label=f"positive outside wedge /scan ({k})")
        a.plot(
            THRESHOLDS,
            (pin[k] > 0).mean(0),
            "g" + st,
            label=f"positive: share of scans with a person in wedge ({k})",
        )
    a.plot(THRESHOLDS, people["tp"] / people["n_gt"], "k-", label="legs_labelled: person recall (wedge)")
    a.set_xlabel("person score threshold")
    a.set_title("person level")
    a.set_yscale("symlog", linthresh=0.1)
    a.grid(alpha=0.3)
    a.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(path, dpi=90)


if __name__ == "__main__":
    raise SystemExit(main())
