"""Follow people through the offline tracker's stages on a simulated recording: which stage made a switch.

    .venv/bin/python bench/trace_tracking.py --scenario moving --seed 36 --frames 550 700 --persons 4 6
    .venv/bin/python bench/trace_tracking.py --scenario moving --seed 3 --frames 300 400 --laser-only
    .venv/bin/python bench/trace_tracking.py --seed 11 --seconds 60 --camera-rate 30 --frames 780 830

It runs what ``bench/replay_tracking.py --laser-again`` runs on one recording (the stored pass one, the laser
detector again on the stored scans, fusion, ``studio label``'s tracking; ``--laser-only`` as there) and
prints, after every stage of the last offline tracking pass (:func:`studio.track.offline.track_offline`,
``on_stage``) and for the output, each track that holds an observation in the frames asked for: per
ground-truth person, the runs of frames in which the track held an observation of that person (the nearest
person within ``--radius``; ``?``: of nobody). A stage's track ids are its own; the output's are the labels'.
A switch that ``replay_tracking.py --switches`` lists shows at the first stage where a track holds two
people in turn, or a person's runs go to another track.
"""

from __future__ import annotations

import argparse
from dataclasses import replace
from typing import Any

import numpy as np
from replay_tracking import capture, laser_again, perception
from run_table import recording

from studio.labels import read_labels
from studio.pipeline import LabelOptions
from studio.pipeline.label import fuse_all, track_all
from studio.track.offline import track_offline

Hits = dict[int, list[tuple[int, int]]]


def runs(frames: list[int], gap: int) -> str:
    """Sorted frame numbers as runs, ``a-b`` where no step is longer than ``gap`` frames."""
    out, start, prev = [], frames[0], frames[0]
    for f in frames[1:]:
        if f - prev > gap:
            out.append(f"{start}-{prev}" if prev > start else f"{start}")
            start = f
        prev = f
    out.append(f"{start}-{prev}" if prev > start else f"{start}")
    return ",".join(out)


def people_of(fused: list[Any], obs: list[Any], gt: Any, radius: float) -> dict[tuple[int, int], int]:
    """Each observation ``(index, row)`` of the tracker's → the ground-truth person nearest to it within
    ``radius`` m (-1: nobody)."""
    by_frame = {f.frame: f for f in gt.frames}
    out = {}
    for i, fr in enumerate(fused):
        f = by_frame.get(fr.index)
        people = f.people if f is not None else ()
        where = (
            fr.world_pose.apply(np.array([[p.x, p.y] for p in people], dtype=np.float64))
            if people
            else np.zeros((0, 2))
        )
        for r, xy in enumerate(np.asarray(obs[i].xy, dtype=np.float64).reshape(-1, 2)):
            d = np.hypot(*(where - xy).T) if len(where) else np.zeros(0)
            k = int(np.argmin(d)) if len(d) else -1
            out[(i, r)] = people[k].id if k >= 0 and d[k] <= radius else -1
    return out


def describe(tracks: Hits, fused: list[Any], who: dict[tuple[int, int], int], args: Any) -> list[str]:
    """One line per track with an observation in the frames asked for (of the persons asked for)."""
    lo, hi = args.frames
    lines = []
    for tid in sorted(tracks):
        per: dict[int, list[int]] = {}
        for i, r in tracks[tid]:
            frame = fused[i].index
            if lo <= frame <= hi:
                per.setdefault(who.get((i, r), -1), []).append(frame)
        if not per or (args.persons and not set(per) & set(args.persons)):
            continue
        parts = [
            f"{'?' if p < 0 else f'P{p}'} {runs(sorted(fs), args.gap)}"
            for p, fs in sorted(per.items(), key=lambda kv: min(kv[1]))
        ]
        lines.append(f"  T{tid}: " + "; ".join(parts))
    return lines


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scenario", default="moving")
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--seconds", type=float, default=None, help="recording length, as in replay_tracking")
    ap.add_argument("--camera-rate", type=float, default=None, metavar="HZ", help="as in replay_tracking")
    ap.add_argument("--frames", nargs=2, type=int, default=[0, 10**9], metavar=("FIRST", "LAST"))
    ap.add_argument("--persons", nargs="+", type=int, default=[], help="only tracks that held these people")
    ap.add_argument("--radius", type=float, default=0.5, help="an observation of a person lies this near, m")
    ap.add_argument("--gap", type=int, default=5, help="frames without a hit that end a run")
    ap.add_argument("--laser-only", action="store_true", help="as --sources laser")
    args = ap.parse_args()
    options = LabelOptions()
    rec = recording(args.scenario, args.seconds, args.seed, camera_rate_hz=args.camera_rate)
    frames, cam = perception(rec, replace(options, sources="laser") if args.laser_only else options)
    frames = laser_again(frames)
    if args.laser_only:
        frames = [replace(f, image=None, appearance=None) for f in frames]
        cam, options = None, replace(options, sources="laser")
    fused = fuse_all(frames, cam, options)
    stages: list[list[tuple[str, Hits]]] = []

    def tracker(observations: Any, *, config: Any) -> Any:
        stages.append([])
        return track_offline(
            observations,
            config=config,
            on_stage=lambda name, tracks: stages[-1].append((name, {t: list(h) for t, h in tracks.items()})),
        )

    traced, seen = capture(tracker)
    track_all(frames, fused, options, has_camera=cam is not None, tracker=traced)
    obs, output, _ = seen["last"]
    who = people_of(fused, obs, read_labels(rec / "ground_truth.jsonl"), args.radius)
    print(f"{rec.name}: frames {args.frames[0]}-{args.frames[1]}, the last of {len(stages)} tracking passes")
    for name, tracks in [*stages[-1], ("output", output)]:
        print(f"{name}:")
        print("\n".join(describe(tracks, fused, who, args)) or "  (no track)")


if __name__ == "__main__":
    main()
