"""Take from a track the few observations it held on someone else's way.

Where two people come close, a track may hold, for a frame or a few, a detection of the other person or
one that merged both (it lies between them): the track makes a short *excursion* towards the other person
and comes back. The encounter re-decision (:mod:`studio.track.encounters`) keeps every observation with one
of the two tracks it re-decides, so it only moves such a detection between them; the evaluator and the
labels then see the track on the wrong person for those frames, often as an identity switch and a switch
back, and the smoother bends the track's path towards the other person.

Offline, the track's hits on both sides of the excursion are known. A run of at most ``max_hits``
consecutive hits of a track is taken from it when every hit of the run lies farther than ``deviation``
from the straight line between the track's hits just before and just after the run (over at most
``max_s``), and closer to another track's position in its frame (that track's hit there, or its straight
path through a gap) than to that line. The track then goes straight through, with interpolated positions;
the observations belong to nobody and the gap fill (:mod:`studio.track.fill`) may give them to a track
whose way they lie on. A hit off the line with nobody else near it (a person turning, or the detector's
error) stays.

Measured with ``bench/replay_tracking.py`` on simulator version 4 (docs/results.md, session 29):
``moving`` seeds 1–12 identity switches 23 → 20 unperturbed and 147 → 131 under five seeds of 5 mm noise,
F1 unchanged (0.9611); ``static`` seeds 1–6 under three noise seeds 40 → 28, F1 0.963 → 0.966; ``rooms``
seed 1 F1 0.9526 → 0.9555, switches 62 → 67 over five noise seeds (one more on each: a person found again
after a long gap who was not labelled there before); laser only 93 → 96 unperturbed, 94 → 94 on
average under two noise seeds.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from studio.track.base import Observations
from studio.track.fill import track_paths
from studio.track.swaps import Hits

__all__ = ["ExcursionConfig", "detach_excursions"]


@dataclass(frozen=True)
class ExcursionConfig:
    """Options of :func:`detach_excursions`.

    Attributes:
        deviation: every hit of an excursion lies farther than this from the straight line between the
            track's hits around it, metres (about four times a detection's error).
        max_hits: longest excursion, in hits.
        max_s: longest time between the hits around an excursion, seconds (over longer spans a walker's
            path is no straight line).
    """

    deviation: float = 0.25
    max_hits: int = 8
    max_s: float = 2.0

    def __post_init__(self) -> None:
        if self.deviation <= 0 or self.max_hits < 1 or self.max_s <= 0:
            raise ValueError("deviation and max_s must be positive, max_hits at least 1")


def detach_excursions(
    obs: Sequence[Observations], tracks: dict[int, Hits], config: ExcursionConfig | None = None
) -> tuple[dict[int, Hits], int]:
    """Take every excursion (see the module docstring) from the tracks.

    Args:
        obs: the per-frame observations the hits index.
        tracks: track id → its hits ``(frame index, row)`` in frame order; not modified.
        config: options.

    Returns:
        The tracks without their excursions, and how many hits were taken.
    """
    cfg = config or ExcursionConfig()
    paths = track_paths(obs, tracks)
    out: dict[int, Hits] = {}
    taken = 0
    for tid, h in tracks.items():
        drop = np.zeros(len(h), dtype=bool)
        if len(h) >= 3:
            xy = np.array([obs[i].xy[r] for i, r in h], dtype=np.float64)
            t = np.array([obs[i].stamp_ns for i, _ in h], dtype=np.int64)
            # each hit's distance to the nearest other track in its frame (inf: nobody else there)
            near = np.array([_nearest_other(xy[m], h[m][0], tid, paths) for m in range(len(h))])
            k = 1
            while k < len(h) - 1:
                end = _excursion_end(xy, t, near, k, cfg) if np.isfinite(near[k]) else None
                if end is None:
                    k += 1
                else:
                    drop[k:end] = True
                    k = end + 1
        taken += int(drop.sum())
        out[tid] = [hit for hit, d in zip(h, drop, strict=True) if not d]
    return out, taken


def _excursion_end(
    xy: np.ndarray, t: np.ndarray, near: np.ndarray, k: int, cfg: ExcursionConfig
) -> int | None:
    """The index of the hit after the shortest excursion that starts at hit ``k`` (hits ``k`` to that index
    minus one), or None; ``near``: each hit's distance to the nearest other track."""
    js = np.arange(k + 1, min(k + cfg.max_hits, len(xy) - 1) + 1)
    # a run may not span more than max_s, nor hold a hit with nobody else near (longer runs would too)
    ok = (t[js] - t[k - 1] <= cfg.max_s * 1e9) & np.isfinite(near[js - 1])
    js = js[: int(np.argmin(ok)) if not ok.all() else len(js)]
    if not len(js):
        return None
    ms = np.arange(k, js[-1])  # every hit a run may hold
    span = np.maximum((t[js] - t[k - 1]).astype(np.float64), 1.0)
    w = (t[ms] - t[k - 1])[None, :] / span[:, None]  # (runs, hits)
    line = (1.0 - w)[..., None] * xy[k - 1] + w[..., None] * xy[js][:, None, :]
    off = np.hypot(*np.moveaxis(xy[ms][None] - line, -1, 0))
    inside = ms[None, :] < js[:, None]  # hit m is in the run that ends before hit j
    good = (off > cfg.deviation) & (near[ms][None, :] < off)
    runs = np.all(good | ~inside, axis=1)
    return int(js[np.argmax(runs)]) if runs.any() else None


def _nearest_other(p: np.ndarray, frame: int, tid: int, paths: dict[int, dict[int, np.ndarray]]) -> float:
    """Distance from ``p`` to the nearest other track's position in ``frame`` (inf when there is none)."""
    d = [float(np.hypot(*(p - q))) for o, q in paths.get(frame, {}).items() if o != tid]
    return min(d, default=float("inf"))
