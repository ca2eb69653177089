"""Give a track's gaps the observations nobody took that lie on its way.

The online pass confirms a track only after a few hits in a short window and deletes one that coasted
too long, so a single detection in the middle of a long gap (a person far away or half hidden, seen by
the laser once in two seconds) starts a tentative track that dies and belongs to nobody. Offline, the
final tracks are known on both sides of each gap: an observation nobody took, in a frame inside the gap,
close to the straight path between the observations at the gap's two ends, is the person's. It splits the
gap, so the pieces are short enough to interpolate (``OfflineConfig.interpolate_max_gap_s``), and the
labeling pipeline then looks for the person's scan points along them (``LabelOptions.recover_radius``).

An observation is given to a track only when it lies within ``radius`` of the track's path in that frame,
no other track's position lies within ``clearance`` of it there (another track's hit, or its straight
path through a gap of its own: two people in contact are 0.4 m apart, and a detection between them is
either's), and, where both the observation and the track's described observations next to the gap have
clothing colours, they agree within ``max_appearance`` ΔE. Over gaps longer than ``max_gap_s`` a walker's
path is no straight line in time, and the straight one may pass through someone else.

**Along the way** (``path_max_gap_s``, ``path_radius``). Someone far away who stands still is often seen
only now and then: the laser finds too few points on them to call them a person, and only the frames whose
image box picks up their scan points observe them, a detection every second or three. The online pass
keeps no track alive that long, and their track, stitched across the gap, waits at one spot for most of it
and then walks on: the straight path in time moves away from where they are. In a gap longer than
``max_gap_s`` but at most ``path_max_gap_s``, an observation nobody took is the track's when it lies within
``path_radius`` of the straight *way* between the gap's ends, whenever along it, and the person could have
walked (``max_speed``) there from the gap's start by then and on to the gap's end in the time left; the
clearance and colour tests hold as before. That covers someone who waited where they were lost or where they
were found again, and someone who walked straight at any pace. Measured in session 59 (``docs/results.md``):
held-out ``moving`` seed 26, F1 0.922 → 0.940, a person 7.3 m away who stood for 15 s.

The fill runs last, on the final tracks, so it changes no association of the pass it runs in; in the
labeling pipeline the longer interpolated stretches let the second pass recover scan points there, and
that pass associates again. Measured with ``bench/replay_tracking.py`` on simulator version 4
(docs/results.md, session 28): ``moving`` seeds 1–12 F1 0.9576 → 0.9611, MOTA 0.918 → 0.924, identity
switches 28 → 23 unperturbed and 104 → 87 under three seeds of 5 mm noise; laser only 99 → 93, F1
0.943 → 0.946; ``static`` seeds 1–6 F1 0.960 → 0.966, switches unchanged; ``rooms`` seed 1 F1 +0.003,
switches 11.6 → 12.4 on average under five noise seeds.
"""

from __future__ import annotations

import bisect
import itertools
import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from studio.track.appearance import appearance_distance, median_appearance
from studio.track.base import Observations
from studio.track.swaps import Hits

__all__ = ["GapFillConfig", "fill_gaps", "track_paths"]

FloatArray = NDArray[np.float64]


@dataclass(frozen=True)
class GapFillConfig:
    """Options of :func:`fill_gaps`.

    Attributes:
        radius: an observation must lie within this distance of the track's straight path through the
            gap, metres.
        clearance: no other track may lie within this distance of the observation, metres.
        max_gap_s: gaps up to this long are searched, seconds (longer ones are not one person's path).
        max_speed: a gap whose ends are farther apart than this speed times its duration is not searched
            (a straight path is a poor guess for a fast one), m/s.
        max_appearance: largest colour difference (ΔE) between a described observation and the median
            colours of the track's described observations next to the gap.
        appearance_views: how many described observations on each side of the gap make those colours.
        path_max_gap_s: gaps longer than ``max_gap_s`` and up to this long are searched along the way
            between their ends (see the module docstring), seconds; 0: never.
        path_radius: there, an observation must lie within this distance of that way, metres (tighter than
            ``radius``: anywhere along the way is a wider net than one place per frame).
    """

    radius: float = 0.35
    clearance: float = 0.8
    max_gap_s: float = 10.0
    max_speed: float = 1.5
    max_appearance: float = 25.0
    appearance_views: int = 5
    path_max_gap_s: float = 30.0
    path_radius: float = 0.2

    def __post_init__(self) -> None:
        if min(self.radius, self.clearance, self.max_gap_s, self.max_speed, self.max_appearance) <= 0:
            raise ValueError("radius, clearance, max_gap_s, max_speed and max_appearance must be positive")
        if self.path_max_gap_s < 0 or self.path_radius <= 0:
            raise ValueError("path_max_gap_s must not be negative, path_radius must be positive")
        if self.appearance_views < 1:
            raise ValueError("appearance_views must be at least 1")


def track_paths(obs: Sequence[Observations], tracks: dict[int, Hits]) -> dict[int, dict[int, FloatArray]]:
    """Per frame: each track's position there, from its hit or the straight line between the hits around."""
    out: dict[int, dict[int, FloatArray]] = {}
    for tid, h in tracks.items():
        for i, r in h:
            out.setdefault(i, {})[tid] = obs[i].xy[r]
        for (a, ra), (b, rb) in itertools.pairwise(h):
            ta, tb = obs[a].stamp_ns, obs[b].stamp_ns
            for i in range(a + 1, b):
                w = (obs[i].stamp_ns - ta) / max(tb - ta, 1)
                out.setdefault(i, {})[tid] = (1 - w) * obs[a].xy[ra] + w * obs[b].xy[rb]
    return out


def _colours(obs: Sequence[Observations], hits: Hits) -> list[NDArray[np.float32] | None]:
    """Per hit, the observation's clothing colours (None where it has none)."""
    out: list[NDArray[np.float32] | None] = []
    for i, r in hits:
        a = obs[i].appearance
        out.append(a[r] if a is not None and np.all(np.isfinite(a[r])) else None)
    return out


def _off_the_way(
    z: FloatArray, za: FloatArray, zb: FloatArray, t: float, dt: float, cfg: GapFillConfig
) -> float:
    """How far ``z``, seen ``t`` seconds into a gap of ``dt`` from ``za`` to ``zb``, lies from the straight
    way between them, metres; infinite where walking there from ``za`` by then, or from there to ``zb`` in
    the time left, would take more than ``max_speed``."""
    if float(np.hypot(*(z - za))) > cfg.radius + cfg.max_speed * t:
        return math.inf
    if float(np.hypot(*(zb - z))) > cfg.radius + cfg.max_speed * (dt - t):
        return math.inf
    ab = zb - za
    u = float(np.clip(np.dot(z - za, ab) / max(float(np.dot(ab, ab)), 1e-12), 0.0, 1.0))
    return float(np.hypot(*(z - (za + u * ab))))


def fill_gaps(
    obs: Sequence[Observations], tracks: dict[int, Hits], config: GapFillConfig | None = None
) -> tuple[dict[int, Hits], int]:
    """Add to each track's gaps the observations no track holds that lie on its way.

    Args:
        obs: the per-frame observations the hits index.
        tracks: track id → its hits ``(frame index, row)`` in frame order; not modified.
        config: options.

    Returns:
        The tracks with the added hits (in frame order), and how many were added.
    """
    cfg = config or GapFillConfig()
    taken = {(i, r) for h in tracks.values() for i, r in h}
    paths = track_paths(obs, tracks)
    out: dict[int, Hits] = {}
    added = 0
    for tid, h in tracks.items():
        colours = _colours(obs, h)
        described = [j for j, c in enumerate(colours) if c is not None]
        new: Hits = []
        for k, ((a, ra), (b, rb)) in enumerate(itertools.pairwise(h)):
            if b <= a + 1:
                continue
            dt = (obs[b].stamp_ns - obs[a].stamp_ns) * 1e-9
            za, zb = obs[a].xy[ra], obs[b].xy[rb]
            if float(np.hypot(*(zb - za))) > cfg.max_speed * max(dt, 1e-9):
                continue
            # a longer gap: along the way between its ends, not at one place per frame (module docstring)
            along = dt > cfg.max_gap_s
            if along and dt > cfg.path_max_gap_s:
                continue
            n = cfg.appearance_views
            m = bisect.bisect_right(described, k)  # described hits up to the gap's start
            near = [colours[j] for j in described[max(0, m - n) : m + n]]
            ref = median_appearance(np.array(near)) if near else None
            for i in range(a + 1, b):
                here = paths.get(i, {})
                path = here[tid]
                o = obs[i]
                alternative = o.alternative
                free = [r for r in range(len(o.xy)) if (i, r) not in taken and not alternative[r]]
                best, best_d = -1, cfg.path_radius if along else cfg.radius
                for r in free:
                    d = (
                        _off_the_way(o.xy[r], za, zb, (o.stamp_ns - obs[a].stamp_ns) * 1e-9, dt, cfg)
                        if along
                        else float(np.hypot(*(o.xy[r] - path)))
                    )
                    if d >= best_d:
                        continue
                    if any(
                        other != tid and float(np.hypot(*(o.xy[r] - p))) < cfg.clearance
                        for other, p in here.items()
                    ):
                        continue
                    a_r = o.appearance[r] if o.appearance is not None else None
                    if (
                        ref is not None
                        and a_r is not None
                        and np.all(np.isfinite(a_r))
                        and appearance_distance(a_r, ref) > cfg.max_appearance
                    ):
                        continue
                    best, best_d = r, d
                if best >= 0:
                    new.append((i, best))
                    taken.add((i, best))
        added += len(new)
        out[tid] = sorted(h + new)
    return out, added
