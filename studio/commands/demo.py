"""``studio demo``: the main job on the bundled default recording, end to end."""

from __future__ import annotations

import argparse
import json
from pathlib import Path

__all__ = ["run"]


def run(args: argparse.Namespace) -> int:
    from tqdm import tqdm

    from studio.atomic import atomic_write_text
    from studio.commands.label import run_label
    from studio.evaluate import evaluate
    from studio.pipeline import LabelOptions
    from studio.sim import DEFAULT_RECORDING, default_recording

    scenario, seconds, seed = DEFAULT_RECORDING
    bar = tqdm(
        total=None,
        unit="frame",
        desc="simulating the default recording",
        leave=False,
        disable=None,
        mininterval=0.5,
    )

    def progress(done: int, total: int) -> None:
        bar.total = total
        bar.update(done - bar.n)

    try:
        folder = default_recording(progress=progress)
    finally:
        bar.close()
    print(f"recording: {folder} ({scenario} scenario, {seconds:g} s, seed {seed}; exact ground truth)")
    out = Path(args.out)
    gt = folder / "ground_truth.jsonl"
    info = run_label(
        folder / "recording.mcap", folder / "rig.yaml", out, options=LabelOptions(), ground_truth=gt
    )
    result = evaluate(out / "labels.jsonl", gt)
    atomic_write_text(out / "metrics.json", json.dumps(result.to_json(), indent=2))
    c = info["counts"]
    fps = c["frames"] / max(info["wall_s"], 1e-9)
    print(
        f"labeled {c['frames']} frames in {info['wall_s']:.1f} s ({fps:.1f} frames/s): {c['tracks']} tracks"
    )
    print(result.table())
    print(f"\nrun directory: {out}  (labels.yaml, labels.jsonl, boxes_coco.json, metrics.json, ...)")
    if info.get("rrd"):
        print(f"open it in the viewer:  studio view {out}   (or: studio view {out} --web)")
    n = c.get("review_points", 0)
    print(
        f"check and correct it:   studio annotate {out}   (key c: the {n} moment{'s' * (n != 1)} where "
        "identities are worth checking, review.jsonl; key x: the most doubtful first)"
    )
    return 0
