"""What de-skewing sweeping scans is worth: label a recording whose scanners sweep, with and without it.

    .venv/bin/python bench/bench_deskew.py                                 # laser-only, 10 Hz, 0.075 s
    .venv/bin/python bench/bench_deskew.py --camera --seconds 60 --seed 1
    .venv/bin/python bench/bench_deskew.py --rate 10 --sweep 0             # the same scanners, instant

Simulates the ``moving`` scenario with both scanners at ``--rate`` Hz whose beams leave one after another
over ``--sweep`` seconds (``LaserSpec.sweep_s``; a 10 Hz scanner over 270°: 0.075 s), written as the scans'
``time_increment``, while the robot drives and turns (up to 0.6 rad/s). Then labels it twice as ``studio
label`` does: as recorded (each beam placed from where the scanner was at its time), and with every scan's
``time_increment`` read as 0, as from a driver that leaves it out (every beam placed from where the scanner
was at the stamp). Prints detection and tracking metrics at 0.2 m for both. Recordings are kept in
``bench/out/sim/``.
"""

from __future__ import annotations

import argparse
import time
from dataclasses import replace
from pathlib import Path

import studio.io.sync as sync
from studio.evaluate import evaluate
from studio.io import load_rig
from studio.io.decode import decode_scan
from studio.labels import LabelSet, read_labels
from studio.pipeline import LabelOptions
from studio.pipeline.label import label_recording
from studio.sim import simulate
from studio.sim.base import SimRig

OUT = Path(__file__).resolve().parent / "out" / "sim"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--seconds", type=float, default=60.0)
    ap.add_argument("--rate", type=float, default=10.0, help="scan rate of both scanners, Hz")
    ap.add_argument("--sweep", type=float, default=0.075, help="time from first to last beam, s")
    ap.add_argument("--camera", action="store_true", help="label with the camera too (default: laser only)")
    args = ap.parse_args()
    base = SimRig()
    rig = replace(base, lasers=tuple(replace(s, rate_hz=args.rate, sweep_s=args.sweep) for s in base.lasers))
    rec = OUT / f"moving-{args.seconds:g}s-seed{args.seed}-laser{args.rate:g}hz-sweep{args.sweep:g}s"
    if not (rec / "recording.mcap").exists():
        t = time.perf_counter()
        simulate("moving", out=rec, seconds=args.seconds, seed=args.seed, rig=rig)
        print(f"simulated {rec.name} in {time.perf_counter() - t:.0f} s", flush=True)
    gt = read_labels(rec / "ground_truth.jsonl")
    label_rig = load_rig(rec / "rig.yaml")
    if not args.camera:
        label_rig = replace(label_rig, camera=None)
    options = LabelOptions(sources="both" if args.camera else "laser")
    try:
        for deskew in (True, False):
            sync.decode_scan = (  # type: ignore[assignment]
                decode_scan if deskew else (lambda m, t: replace(decode_scan(m, t), time_increment=0.0))
            )
            t = time.perf_counter()
            run = label_recording(rec / "recording.mcap", label_rig, options=options)
            m = evaluate(LabelSet.from_frames(run.labels), gt).metrics()
            how = "de-skewed (as recorded)" if deskew else "time_increment read as 0"
            print(
                f"{how:>24}: F1 {m['f1']:.3f} (P {m['precision']:.3f} R {m['recall']:.3f}) "
                f"MOTA {m['mota']:.3f} IDF1 {m['idf1']:.3f} switches {m['id_switches']} "
                f"({time.perf_counter() - t:.0f} s)",
                flush=True,
            )
    finally:
        sync.decode_scan = decode_scan


if __name__ == "__main__":
    main()
