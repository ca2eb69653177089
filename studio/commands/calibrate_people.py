"""``studio calibrate people``: camera latency and camera pose from the people in a recording.

``studio calibrate people --recording REC --rig RIG [--run RUN] [--max-offset-s 2.0] [--max-yaw-deg 30]
[--image-period-s 0.2] [--max-std-s 0.05] [--json OUT] --out calib.yaml``

Writes ``--out`` as a complete rig.yaml (the input rig with the new ``camera.pose`` and
``sync.camera_latency_s``), usable as ``--rig`` of ``studio label``; ``--json`` adds the report (offset,
uncertainty, pose change, pairs, score curves). An unobservable offset (static robot, standing people)
is an error: one line, exit 2, nothing written.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path
from typing import Any

from studio.atomic import atomic_write_text, out_file
from studio.errors import StudioError

__all__ = ["run_people", "sparkline"]

_BARS = " ▁▂▃▄▅▆▇█"


def sparkline(values: list[float], *, width: int = 60) -> str:
    """A one-line text plot of ``values`` (resampled to at most ``width`` characters)."""
    if not values:
        return ""
    n = len(values)
    m = min(width, n)
    pick = [values[round(i * (n - 1) / max(m - 1, 1))] for i in range(m)]
    lo, hi = min(pick), max(pick)
    span = hi - lo or 1.0
    return "".join(_BARS[round((v - lo) / span * (len(_BARS) - 1))] for v in pick)


def run_people(args: argparse.Namespace) -> int:
    """Run the command on parsed ``args`` (attributes named after the options above)."""
    from tqdm import tqdm

    from studio.calibrate.people import calibrate_people, collect_people
    from studio.io import load_rig, save_rig

    recording = Path(args.recording)
    if not recording.exists():
        raise StudioError(f"{recording}: no such recording")
    # --out may be --rig itself (the rig refined in place), never the recording
    out = out_file(args.out, "--out", inputs=[recording])
    json_out = out_file(getattr(args, "json", None), "--json", inputs=[recording, args.rig, args.out])
    for name in ("max_offset_s", "image_period_s", "max_std_s", "max_yaw_deg"):
        value = getattr(args, name, None)
        if value is not None and not float(value) > 0:
            raise StudioError(f"--{name.replace('_', '-')} must be a positive number, got {value}")
    run_dir = getattr(args, "run", None)
    if run_dir is not None and not (Path(run_dir) / "image_detections.jsonl").is_file():
        raise StudioError(f"--run {run_dir}: no image_detections.jsonl (label the recording with a camera)")
    rig = load_rig(args.rig)
    bars: list[Any] = []

    def progress(done: int, total: int) -> None:
        if not bars:
            bars.append(tqdm(total=total, unit="image", desc="detecting people", leave=False, disable=None))
        bars[0].update(done - bars[0].n)

    try:
        data = collect_people(
            recording,
            rig,
            run_dir=run_dir,
            image_period_s=float(getattr(args, "image_period_s", None) or 0.2),
            progress=progress,
        )
    finally:
        for bar in bars:
            bar.close()
    res = calibrate_people(
        data,
        max_offset_s=float(getattr(args, "max_offset_s", None) or 2.0),
        max_yaw_deg=float(getattr(args, "max_yaw_deg", None) or 30.0),
        max_std_s=float(getattr(args, "max_std_s", None) or 0.05),
    )
    print(f"studio calibrate people: {recording}")
    print(res.summary())
    c = res.curve
    print(f"coarse score over latency {c['latency_s'][0]:+.2f} … {c['latency_s'][-1]:+.2f} s (peak = best):")
    print("  " + sparkline(c["score"]))
    if out is not None:
        save_rig(res.rig, out)
        print(f"calibrated rig written to {out} (use it as --rig)")
    if json_out is not None:
        try:
            atomic_write_text(json_out, json.dumps(res.to_json(), indent=2, allow_nan=False) + "\n")
        except (OSError, ValueError) as exc:
            raise StudioError(f"--json {json_out}: cannot write ({exc})") from None
        print(f"report written to {json_out}")
    return 0
