"""``studio simulate --scenario {static,moving,rooms} [--seconds S] [--seed N] --out DIR`` (DESIGN.md §2)."""

from __future__ import annotations

import argparse

__all__ = ["run"]


def run(args: argparse.Namespace) -> int:
    from tqdm import tqdm

    from studio.sim import simulate

    bar: tqdm | None = None

    def progress(done: int, total: int) -> None:
        nonlocal bar
        if bar is None:
            bar = tqdm(total=total, unit="frame", desc=f"simulate {args.scenario}", leave=False)
        bar.update(done - bar.n)

    try:
        res = simulate(args.scenario, out=args.out, seconds=args.seconds, seed=args.seed, progress=progress)
    finally:
        if bar is not None:
            bar.close()
    mb = res.bytes / 1e6
    if res.scenario.startswith("calib-"):
        print(f"studio simulate: scenario '{res.scenario}', seed {res.seed}, {res.seconds:.1f} s")
        print(f"  {res.recording}  ({mb:.1f} MB; {res.num_images} images, {res.num_scans} scans)")
        print(f"  {res.rig}  (nominal camera pose)")
        print(
            f"  {res.ground_truth_yaml}, {res.ground_truth_jsonl.name}  (true camera pose, latency, targets)"
        )
        return 0
    head = f"studio simulate: scenario '{res.scenario}', seed {res.seed}, {res.seconds:.1f} s"
    print(f"{head}, {res.num_people} people")
    print(f"  {res.recording}  ({mb:.1f} MB, {mb / res.seconds * 60:.0f} MB/min; {res.num_images} images, "
          f"{res.num_scans} scans, {res.num_odometry} odometry)")  # fmt: skip
    print(f"  {res.rig}")
    print(f"  {res.ground_truth_yaml}, {res.ground_truth_jsonl.name}  ({res.num_gt} person labels)")
    print(f"  odometry drift at the end: {res.odom_drift_m:.3f} m; took {res.wall_s:.1f} s")
    return 0
