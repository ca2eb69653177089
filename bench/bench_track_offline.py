"""How offline tracking scales with the length of a recording.

Generated observations (no simulator, no perception): ``--people`` walkers on smooth random walks in a
20 m square at 10 Hz, each missed one frame in ten, positions with 5 cm of noise, half of the observations
with clothing colours (each walker's own, 2 ΔE of noise). ``track_offline`` with the pipeline's settings
runs on recordings of each ``--minutes``; the time per minute of recording should not grow with the
length (a step that compares every observation of a track with every other would show here first).

    .venv/bin/python bench/bench_track_offline.py --minutes 5 30 --people 6
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from studio.pipeline.base import PIPELINE_TRACKING
from studio.track import Observations
from studio.track.offline import track_offline

T0 = 1_700_000_000_000_000_000
FRAME_NS = 100_000_000


def walkers(minutes: float, people: int, seed: int = 0) -> list[Observations]:
    """Per frame, the observations of ``people`` walkers over ``minutes`` (see the module docstring)."""
    rng = np.random.default_rng(seed)
    colours = rng.normal(0, 25, (people, 6)) + np.array([50, 0, 0, 40, 0, 0])
    pos = rng.uniform(-8, 8, (people, 2))
    vel = np.zeros((people, 2))
    out = []
    for i in range(int(minutes * 600)):
        vel = 0.95 * vel + rng.normal(0, 0.1, (people, 2))
        speed = np.hypot(*vel.T)[:, None]
        vel = np.where(speed > 1.2, vel / np.maximum(speed, 1e-9) * 1.2, vel)
        pos = np.clip(pos + 0.1 * vel, -10, 10)
        seen = rng.random(people) > 0.1
        n = int(seen.sum())
        xy = pos[seen] + rng.normal(0, 0.05, (n, 2))
        app = (colours[seen] + rng.normal(0, 2, (n, 6))).astype(np.float32)
        app[rng.random(n) > 0.5] = np.nan
        cov = np.repeat(np.eye(2)[None] * 0.05**2, n, 0)
        out.append(Observations(T0 + i * FRAME_NS, xy, cov, ("fused",) * n, np.ones(n), app, np.arange(n)))
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--minutes", type=float, nargs="+", default=[5.0, 30.0])
    ap.add_argument("--people", type=int, default=6)
    args = ap.parse_args()
    for minutes in args.minutes:
        obs = walkers(minutes, args.people)
        t = time.perf_counter()
        result = track_offline(obs, config=PIPELINE_TRACKING)
        wall = time.perf_counter() - t
        tracks = len({p.track_id for f in result.frames for p in f.points})
        print(
            f"{minutes:g} min, {args.people} people, {len(obs)} frames: {wall:.1f} s "
            f"({wall / minutes:.2f} s per minute of recording), {tracks} tracks",
            flush=True,
        )


if __name__ == "__main__":
    main()
