"""``studio label`` laser-only in an empty room: false people per frame, at several beam steps.

    .venv/bin/python bench/bench_empty_room.py
    .venv/bin/python bench/bench_empty_room.py --steps 0.5 --min-walk 0

Data: leg_tracker's ``negative_2.bag`` (Leigh et al., ICRA 2015; BSD-3-Clause): a robot without odometry or
TF drives ~10 m through a furnished room with nobody in it; its left scanner (0.35° beams, 270°). It is
labelled as a user would (a rig naming the scan's own frame as ``base_frame``, laser only: the motion comes
from scan matching), as recorded and as copies whose scans keep the beam nearest to each multiple of a
coarser step (:func:`bench_real_labels.thinned_bag`; 0.7° and 1.05° are every 2nd / 3rd beam). Everyone
labelled is furniture: printed per step are the false tracks, the false people per frame, and scan
matching's registered / rejected frames (a coarse scan gives it too few points on straight surfaces).
"""

from __future__ import annotations

import argparse
import sys
import tempfile
from dataclasses import replace
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_real_labels import thinned_bag
from laser_data import DATA

from studio.io import load_rig
from studio.pipeline import LabelOptions
from studio.pipeline.label import label_recording

RECORDED_STEP_DEG = 0.35


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    steps = [0.35, 0.5, 0.7, 1.05]
    ap.add_argument("--steps", type=float, nargs="+", default=steps, help="beam steps, degrees")
    ap.add_argument("--min-walk", type=float, default=None, help="the walk gate, m (default as studio label)")
    args = ap.parse_args()
    bag = DATA / "negative_2.bag"
    if not bag.exists():
        raise SystemExit(f"{bag} is missing (../shared/data/leg_tracker)")
    options = LabelOptions(sources="laser")
    if args.min_walk is not None:
        options = replace(options, min_walk_m=args.min_walk)
    with tempfile.TemporaryDirectory() as tmp_dir:
        tmp = Path(tmp_dir)
        rig = tmp / "rig.yaml"
        rig.write_text("base_frame: left_laser\nlasers:\n  - topic: /left_scan\n")
        for step in args.steps:
            src = bag
            if abs(step - RECORDED_STEP_DEG) > 0.01:
                every = step / RECORDED_STEP_DEG
                near = round(every)
                src = thinned_bag(
                    bag,
                    tmp / f"step{step:g}.bag",
                    near,
                    step_deg=None if abs(every - near) < 0.01 else step,
                )
            run = label_recording(src, load_rig(rig), options=options)
            people = sum(len(f.people) for f in run.labels)
            tracks = len({p.id for f in run.labels for p in f.people})
            sm = run.counts["scan_matching"] or {}
            print(
                f"{step:g}°: {tracks} false tracks, {people / len(run.labels):.3f} false people per frame "
                f"({len(run.labels)} frames); scan matching registered {sm.get('matched', 0)}, "
                f"rejected {sm.get('rejected', 0)}",
                flush=True,
            )


if __name__ == "__main__":
    main()
