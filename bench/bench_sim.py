"""Simulator throughput and output size: wall and CPU time per scenario, MB per minute of recording.

.venv/bin/python bench/bench_sim.py                       # moving, full length (96 s)
.venv/bin/python bench/bench_sim.py --scenario static rooms --seconds 20
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

from studio.sim import SCENARIOS, simulate


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--scenario", nargs="+", default=["moving"], choices=list(SCENARIOS))
    ap.add_argument("--seconds", type=float, default=None, help="duration (default: each scenario's own)")
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--out", type=Path, default=None, help="keep the outputs here (default: a temp dir)")
    args = ap.parse_args()
    root = args.out or Path(tempfile.mkdtemp(prefix="bench_sim."))
    cols = (
        ("sim s", 6),
        ("wall s", 7),
        ("cpu s", 7),
        ("x real", 7),
        ("MB", 7),
        ("MB/min", 7),
        ("people", 6),
        ("GT", 6),
    )
    print(f"{'scenario':8} " + " ".join(f"{c:>{w}}" for c, w in cols))
    for name in args.scenario:
        t0, c0 = time.perf_counter(), time.process_time()
        res = simulate(name, out=root / name, seconds=args.seconds, seed=args.seed)
        wall, cpu = time.perf_counter() - t0, time.process_time() - c0
        mb = res.bytes / 1e6
        print(
            f"{name:8} {res.seconds:6.0f} {wall:7.1f} {cpu:7.1f} {res.seconds / wall:7.2f} {mb:7.1f} "
            f"{mb / res.seconds * 60:7.1f} {res.num_people:6d} {res.num_gt:6d}"
        )


if __name__ == "__main__":
    main()
