"""Whole-process speed of ``studio label`` against ``--method thesis`` on the same recording, in turn.

    .venv/bin/python bench/speed_vs_thesis.py                              # moving, seed 2, full 96 s, 1 pair
    .venv/bin/python bench/speed_vs_thesis.py --seconds 15 --seed 11 --pairs 3

Each run is a child process (``studio label … --no-rrd``): wall time, CPU time (all threads, from the
kernel's accounting of the child) and peak memory of the whole process, start-up included. The two methods
alternate (studio, thesis, studio, …) so a machine whose speed drifts slows both alike; quote the ratios,
not the seconds, on a shared machine. Prints each run, the medians, the ratios and our per-stage timings
from ``run.json`` (the image detector runs beside reading and the laser, so stages overlap). Recordings
are those of ``bench/run_table.py`` (simulated once into ``bench/out/sim``); 1920 × 960 panoramas at 10 Hz
and two scanners.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from run_table import recording


def run(rec: Path, method: str, out: Path) -> dict[str, float]:
    """One ``studio label`` child: wall s, CPU s, peak MB, frames, and its ``run.json`` timings."""
    cmd = [
        sys.executable,
        "-m",
        "studio.cli",
        "label",
        str(rec / "recording.mcap"),
        "--rig",
        str(rec / "rig.yaml"),
    ]
    cmd += ["--out", str(out), "--no-rrd", "--method", method]
    t = time.perf_counter()
    proc = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    err = proc.stderr.read() if proc.stderr else ""
    _, status, usage = os.wait4(proc.pid, 0)
    wall = time.perf_counter() - t
    if os.waitstatus_to_exitcode(status) != 0:
        raise SystemExit(f"studio label --method {method} failed: {err.strip().splitlines()[-1:]}")
    info = json.loads((out / "run.json").read_text())
    return {
        "wall_s": wall,
        "cpu_s": usage.ru_utime + usage.ru_stime,
        "peak_mb": usage.ru_maxrss / 1024,  # Linux: KiB
        "frames": info["counts"]["frames"],
        "timings_s": info["timings_s"],
    }


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scenario", default="moving")
    ap.add_argument("--seed", type=int, default=2)
    ap.add_argument("--seconds", type=float, default=None, help="shorten the scenario (default: full)")
    ap.add_argument("--pairs", type=int, default=1, help="studio/thesis pairs (medians over them)")
    args = ap.parse_args()
    rec = recording(args.scenario, args.seconds, args.seed)
    results: dict[str, list[dict[str, float]]] = {"studio": [], "thesis": []}
    with tempfile.TemporaryDirectory(prefix="studio-speed-") as tmp:
        for k in range(args.pairs):
            for method in ("studio", "thesis"):
                r = run(rec, method, Path(tmp) / f"{method}-{k}")
                results[method].append(r)
                print(
                    f"{rec.name} {method:6s}: {r['wall_s']:7.1f} s wall, {r['cpu_s']:7.1f} s CPU, "
                    f"{r['frames'] / r['wall_s']:5.1f} frames/s, peak {r['peak_mb']:.0f} MB",
                    flush=True,
                )
    med = {
        m: {k: statistics.median(r[k] for r in rs) for k in ("wall_s", "cpu_s")} for m, rs in results.items()
    }
    frames = results["studio"][0]["frames"]
    print(f"\nmedian of {args.pairs} pair(s), {frames} frames:")
    for m in ("studio", "thesis"):
        print(
            f"  {m:6s} {med[m]['wall_s']:7.1f} s wall ({frames / med[m]['wall_s']:.1f} frames/s), "
            f"{med[m]['cpu_s']:7.1f} s CPU"
        )
    ratio = [t["wall_s"] / s["wall_s"] for s, t in zip(results["studio"], results["thesis"], strict=True)]
    ratio_cpu = [t["cpu_s"] / s["cpu_s"] for s, t in zip(results["studio"], results["thesis"], strict=True)]
    print(
        f"  studio is {statistics.median(ratio):.2f}x faster (wall, pair by pair: "
        f"{', '.join(f'{x:.2f}' for x in ratio)}), {statistics.median(ratio_cpu):.2f}x in CPU time"
    )
    print("\nper stage, studio (s; the image detection overlaps reading, laser and static map):")
    for key in results["studio"][0]["timings_s"]:
        vals = [r["timings_s"][key] for r in results["studio"]]
        print(f"  {key:26s} {statistics.median(vals):7.1f}")


if __name__ == "__main__":
    main()
