"""Results table: simulated scenarios × methods × metrics, plus per-stage detection numbers and speed.

    .venv/bin/python bench/run_table.py                      # static, moving, rooms; seed 1; full length
    .venv/bin/python bench/run_table.py --seconds 30 --scenarios moving --seeds 1 2
    .venv/bin/python bench/run_table.py --markdown docs/results.md
    .venv/bin/python bench/run_table.py --reuse thesis laser   # keep finished runs of unchanged methods

Each run is a child process, so its peak resident memory (``peak MB``) is its own.
Methods: ``studio`` (ours), ``thesis`` (the thesis method, same inputs), ``laser`` (ours, laser only, on
the camera's frames), ``laser-rig`` (ours on the rig without its camera, as a robot without one labels:
a frame per scan of the first laser, 40 Hz; no fused-stage F1, whose ground truth is per camera frame),
``camera`` (ours, camera only). Metrics at 0.2 m (the thesis radius). Recordings are simulated once into
``bench/out/sim`` and reused (their folder names carry the simulator version, so a simulator change makes
them again); runs go to ``bench/out/runs``. Prints a markdown table.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import subprocess
import sys
import time
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np

from studio.commands.label import run_label
from studio.evaluate import box_ap, evaluate
from studio.labels import read_labels
from studio.pipeline import LabelOptions
from studio.sim import SimRig, simulate
from studio.sim.simulate import SIM_VERSION

OUT = Path(__file__).resolve().parent / "out"
METHODS = {
    "studio": LabelOptions(),
    "thesis": LabelOptions(method="thesis"),
    "laser": LabelOptions(sources="laser"),
    "laser-rig": LabelOptions(sources="laser"),
    "camera": LabelOptions(sources="camera"),
}


def recording(
    scenario: str,
    seconds: float | None,
    seed: int,
    *,
    laser_step_deg: float | None = None,
    camera_rate_hz: float | None = None,
) -> Path:
    """The simulated recording (simulated on the first call). ``laser_step_deg``: the rig's scanners with
    this angular step instead of 0.25° (same field of view), e.g. 1.0 for a low-cost lidar.
    ``camera_rate_hz``: the camera at this frame rate instead of 10 Hz (the same people and robot)."""
    name = f"{scenario}-{'full' if seconds is None else f'{seconds:g}s'}-seed{seed}-sim{SIM_VERSION}"
    rig = None
    if camera_rate_hz is not None:
        name += f"-cam{camera_rate_hz:g}hz"
        rig = replace(SimRig(), camera_rate_hz=camera_rate_hz)
    if laser_step_deg is not None:
        name += f"-laser{laser_step_deg:g}deg"
        base = rig or SimRig()
        step = float(np.deg2rad(laser_step_deg))
        rig = replace(
            base,
            lasers=tuple(
                replace(
                    s,
                    angle_increment=step,
                    n_beams=round((s.n_beams - 1) * s.angle_increment / step) + 1,
                )
                for s in base.lasers
            ),
        )
    out = OUT / "sim" / name
    if not (out / "recording.mcap").exists():
        t = time.perf_counter()
        simulate(scenario, out=out, seconds=seconds, seed=seed, rig=rig)
        print(f"simulated {name} in {time.perf_counter() - t:.0f} s", flush=True)
    return out


def image_ap(run: Path, gt_path: Path) -> float:
    """AP@0.5 of the raw image detections against the ground-truth boxes (seam-aware IoU)."""
    path = run / "image_detections.jsonl"
    if not path.exists():
        return math.nan
    gt = {f.stamp_ns: f for f in read_labels(gt_path)}
    g_boxes, p_boxes, p_scores, width = [], [], [], 1920
    for line in path.read_text().splitlines():
        d = json.loads(line)
        f = gt.get(d["stamp_ns"])
        if f is None:
            continue
        width = d["width"]
        b = np.array(d["boxes"], dtype=float).reshape(-1, 5)
        g_boxes.append(np.array([p.box for p in f.people if p.box is not None]).reshape(-1, 4))
        p_boxes.append(b[:, :4])
        p_scores.append(b[:, 4])
    if not g_boxes:
        return math.nan
    return float(box_ap(g_boxes, p_boxes, p_scores, width=width, iou_threshold=0.5).ap)


def run_one(rec: Path, method: str) -> dict[str, Any]:
    """Label ``rec`` with ``method`` in this process and measure it (the child side of :func:`measure`)."""
    run = OUT / "runs" / rec.name / method
    rig = rec / "rig.yaml"
    if method == "laser-rig":
        import yaml

        spec = yaml.safe_load(rig.read_text())
        spec.pop("camera", None)
        rig = OUT / "runs" / rec.name / "rig-without-camera.yaml"
        rig.parent.mkdir(parents=True, exist_ok=True)
        rig.write_text(yaml.safe_dump(spec, sort_keys=False))
    info = run_label(rec / "recording.mcap", rig, run, options=METHODS[method], write_rrd=False, quiet=True)
    gt = rec / "ground_truth.jsonl"
    m = evaluate(run / "labels.jsonl", gt).metrics()
    det = (
        {"f1": math.nan}  # detections.yaml is matched to the ground truth's frames by index
        if method == "laser-rig"
        else evaluate(run / "detections.yaml", rec / "ground_truth.yaml").metrics()
    )
    labels = read_labels(run / "labels.jsonl")
    minutes = (labels.frames[-1].stamp_ns - labels.frames[0].stamp_ns) / 60e9 if len(labels) > 1 else math.nan
    frames = info["counts"]["frames"]
    return {
        **{
            k: m[k]
            for k in ("precision", "recall", "f1", "mota", "idf1", "hota", "id_switches", "mt", "pt", "ml")
        },
        "idsw_per_min": m["id_switches"] / minutes if minutes else math.nan,
        "det_f1": det["f1"],
        "image_ap50": image_ap(run, gt),
        "frames": frames,
        "fps": frames / info["wall_s"],
        "timings_s": info["timings_s"],
    }


def measure(rec: Path, method: str, *, reuse: bool) -> dict[str, Any]:
    """Run :func:`run_one` in a child process; add its peak RSS (MB). Reuses a stored result if asked."""
    stored = OUT / "runs" / rec.name / f"{method}.json"
    if reuse and stored.exists():
        return dict(json.loads(stored.read_text()), reused=True)
    cmd = [sys.executable, __file__, "--child", str(rec), method]
    proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, text=True)
    out = proc.stdout.read() if proc.stdout else ""
    _, status, usage = os.wait4(proc.pid, 0)
    proc.returncode = os.waitstatus_to_exitcode(status)
    if proc.returncode != 0:
        raise SystemExit(f"{rec.name} {method}: the labeling child failed (exit {proc.returncode})")
    r = json.loads(out.strip().splitlines()[-1])
    r["peak_mb"] = usage.ru_maxrss / 1024  # Linux: KiB
    stored.write_text(json.dumps(r, indent=2, default=float))
    return r


def fmt(v: Any, pct: bool = False) -> str:
    if isinstance(v, float) and math.isnan(v):
        return "n/a"
    if pct:
        return f"{100 * v:.0f}"
    return f"{v:.3f}" if isinstance(v, float) else str(v)


def markdown(rows: list[dict[str, Any]]) -> str:
    head = (
        "| scenario | seed | method | F1 | MOTA | IDF1 | HOTA | IDSW/min | MT/PT/ML % | fused-stage F1 |"
        " image AP@0.5 | frames/s | peak MB |"
    )
    lines = [head, "|" + "---|" * 13]
    for r in rows:
        lines.append(
            f"| {r['scenario']} | {r['seed']} | {r['method']} | {fmt(r['f1'])} | {fmt(r['mota'])} | "
            f"{fmt(r['idf1'])} | {fmt(r['hota'])} | {r['idsw_per_min']:.2f} | "
            f"{fmt(r['mt'], True)}/{fmt(r['pt'], True)}/{fmt(r['ml'], True)} | {fmt(r['det_f1'])} | "
            f"{fmt(r['image_ap50'])} | {r['fps']:.1f} | {r.get('peak_mb', math.nan):.0f} |"
        )
    return "\n".join(lines) + "\n"


def seed_means(rows: list[dict[str, Any]]) -> list[dict[str, Any]]:
    """One row per scenario × method with the mean over seeds (seed column "mean of N")."""
    keys = ("f1", "mota", "idf1", "hota", "idsw_per_min", "mt", "pt", "ml", "det_f1", "image_ap50", "fps")
    groups: dict[tuple[str, str], list[dict[str, Any]]] = {}
    for r in rows:
        groups.setdefault((r["scenario"], r["method"]), []).append(r)
    out = []
    for (scenario, method), rs in groups.items():
        if len(rs) < 2:
            continue
        m = {k: float(np.mean([r[k] for r in rs])) for k in keys}
        m["peak_mb"] = float(max(r.get("peak_mb", math.nan) for r in rs))
        out.append({"scenario": scenario, "seed": f"mean of {len(rs)}", "method": method, **m})
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scenarios", nargs="+", default=["static", "moving", "rooms"])
    ap.add_argument("--seeds", nargs="+", type=int, default=[1])
    ap.add_argument("--seconds", type=float, default=None, help="shorten every scenario (default: full)")
    ap.add_argument("--methods", nargs="+", default=list(METHODS), choices=list(METHODS))
    ap.add_argument("--markdown", type=Path, default=None, help="also write the table to this file")
    ap.add_argument(
        "--reuse", nargs="*", default=[], choices=list(METHODS), help="methods whose stored runs to keep"
    )
    ap.add_argument("--child", nargs=2, default=None, help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.child is not None:
        print(json.dumps(run_one(Path(args.child[0]), args.child[1]), default=float))
        return
    rows = []
    for scenario in args.scenarios:
        for seed in args.seeds:
            rec = recording(scenario, args.seconds, seed)
            for method in args.methods:
                t = time.perf_counter()
                r = {
                    "scenario": scenario,
                    "seed": seed,
                    "method": method,
                    **measure(rec, method, reuse=method in args.reuse),
                }
                rows.append(r)
                print(
                    f"{scenario} seed {seed} {method}: F1 {r['f1']:.3f} MOTA {r['mota']:.3f} "
                    f"IDSW {r['id_switches']} ({time.perf_counter() - t:.0f} s)",
                    flush=True,
                )
    OUT.mkdir(parents=True, exist_ok=True)
    (OUT / "results.json").write_text(json.dumps(rows, indent=2, default=float))
    table = markdown(rows + seed_means(rows))
    print()
    print(table)
    if args.markdown is not None:
        args.markdown.write_text(table)


if __name__ == "__main__":
    main()
