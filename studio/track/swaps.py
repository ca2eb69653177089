"""Identity swaps between two people who came close: undo them with clothing colours, offline.

Two people who walk or stand within half a metre of each other are the online tracker's hardest case:
their legs merge in the scan, their boxes overlap, and a merged detection between them pulls one track
over to the other person. Motion cannot tell afterwards which track is whom; clothing colours can, and
offline both sides of the encounter are known.

For two tracklets that overlap in time, every *encounter* (a run of frames in which both are observed
less than ``close_m`` apart) is judged by the colours of each before and after it (the ``views`` nearest
described observations on each side, medians as in stitching). With ``d(X, Y)`` the colour difference
(:func:`studio.track.appearance.appearance_distance`), the tails are exchanged when

    d(A_before, B_after) + d(B_before, A_after) + margin  <  d(A_before, A_after) + d(B_before, B_after)

and both crossed pairs match (each at most ``max_appearance``): the colours say the tracks came out of
the encounter the other way round. The cut goes where the colours seen inside the encounter change from
matching one person to matching the other (at the closest approach when none is described there).
Encounters without enough described observations on all four sides are left as they are.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from studio.track.appearance import appearance_distance, median_appearance
from studio.track.base import Observations

__all__ = ["SwapConfig", "repair_swaps", "side_colours"]

# A track's hits: (frame index, row in that frame's Observations), in frame order.
Hits = list[tuple[int, int]]


@dataclass(frozen=True)
class SwapConfig:
    """Options of :func:`repair_swaps`.

    Attributes:
        close_m: two tracklets observed closer than this in a frame are in an encounter, metres.
        views: described observations on each side of an encounter whose median colours are compared.
        margin: how much better (ΔE, summed over both pairs) the exchanged tails must match.
        max_appearance: largest colour difference of each exchanged pair (ΔE).
    """

    close_m: float = 0.9
    views: int = 5
    margin: float = 6.0
    max_appearance: float = 15.0

    def __post_init__(self) -> None:
        if self.close_m <= 0 or self.views < 1 or self.margin < 0 or self.max_appearance <= 0:
            raise ValueError("close_m, views and max_appearance must be positive, margin non-negative")


def repair_swaps(
    obs: Sequence[Observations], tracklets: dict[int, Hits], config: SwapConfig | None = None
) -> tuple[dict[int, Hits], int]:
    """Exchange the tails of tracklets whose colours say they swapped people in an encounter.

    Args:
        obs: the per-frame observations the hits index.
        tracklets: id → hits (sorted by frame); not modified.
        config: options.

    Returns:
        The tracklets after the repairs (same ids) and the number of tails exchanged.
    """
    cfg = config or SwapConfig()
    tracks = {tid: list(h) for tid, h in tracklets.items() if h}
    done: set[tuple[int, int, int]] = set()
    swaps = 0
    changed = True
    while changed:
        changed = False
        for a, b, first, cut, last in _encounters(obs, tracks, cfg):
            key = (min(a, b), max(a, b), cut)
            if key in done:
                continue
            done.add(key)
            sides = _swapped(obs, tracks[a], tracks[b], first, last, cfg)
            if sides is not None:
                ha, hb = tracks[a], tracks[b]
                cut = _cut(obs, ha, hb, first, cut, last, *sides)
                tracks[a] = [h for h in ha if h[0] <= cut] + [h for h in hb if h[0] > cut]
                tracks[b] = [h for h in hb if h[0] <= cut] + [h for h in ha if h[0] > cut]
                swaps += 1
                changed = True
                break  # the encounters of these two changed: list them again
    return tracks, swaps


def _encounters(
    obs: Sequence[Observations], tracks: dict[int, Hits], cfg: SwapConfig
) -> list[tuple[int, int, int, int, int]]:
    """``(id_a, id_b, first frame, frame of closest approach, last frame)`` of every encounter, in time
    order."""
    span = {tid: (h[0][0], h[-1][0]) for tid, h in tracks.items()}
    ids = sorted(tracks, key=lambda t: span[t])
    out = []
    for n, a in enumerate(ids):
        pos_a = None
        for b in ids[n + 1 :]:
            if span[b][0] > span[a][1]:
                break
            if span[b][1] < span[a][0]:
                continue
            if pos_a is None:
                pos_a = {i: obs[i].xy[r] for i, r in tracks[a]}
            common = [(i, r) for i, r in tracks[b] if i in pos_a]
            if not common:
                continue
            frames = np.array([i for i, _ in common])
            dist = np.array([float(np.hypot(*(pos_a[i] - obs[i].xy[r]))) for i, r in common])
            close = dist < cfg.close_m
            # runs of consecutive common frames that are close
            k = 0
            while k < len(close):
                if not close[k]:
                    k += 1
                    continue
                j = k
                while j + 1 < len(close) and close[j + 1]:
                    j += 1
                m = k + int(np.argmin(dist[k : j + 1]))
                out.append((frames[m], a, b, frames[k], frames[j]))
                k = j + 1
    out.sort()
    return [(a, b, int(first), int(cut), int(last)) for cut, a, b, first, last in out]


def side_colours(
    obs: Sequence[Observations], hits: Hits, first: int, last: int, after: bool, views: int
) -> NDArray[np.float32] | None:
    """Median colours of the ``views`` described observations nearest the encounter, before or after it."""
    rows = []
    seq = [h for h in hits if h[0] > last] if after else [h for h in reversed(hits) if h[0] < first]
    for i, r in seq:
        app = obs[i].appearance
        if app is not None and np.all(np.isfinite(app[r])):
            rows.append(app[r])
            if len(rows) >= views:
                break
    return median_appearance(np.array(rows)) if len(rows) >= views else None


def _swapped(
    obs: Sequence[Observations], ha: Hits, hb: Hits, first: int, last: int, cfg: SwapConfig
) -> tuple[NDArray[np.float32], NDArray[np.float32]] | None:
    """The colours of A and B before the encounter when the tracks came out of it swapped, else None."""
    found = [side_colours(obs, h, first, last, after, cfg.views) for h in (ha, hb) for after in (False, True)]
    sides = [s for s in found if s is not None]
    if len(sides) < 4:
        return None
    a0, a1, b0, b1 = sides
    same = appearance_distance(a0, a1) + appearance_distance(b0, b1)
    cross_a, cross_b = appearance_distance(a0, b1), appearance_distance(b0, a1)
    if max(cross_a, cross_b) <= cfg.max_appearance and cross_a + cross_b + cfg.margin < same:
        return a0, b0
    return None


def _cut(
    obs: Sequence[Observations],
    ha: Hits,
    hb: Hits,
    first: int,
    closest: int,
    last: int,
    a0: NDArray[np.float32],
    b0: NDArray[np.float32],
) -> int:
    """The last frame before the swap: inside the encounter, where the described observations change
    from matching the colours before it to matching the other person's (the closest approach when no
    observation inside it is described)."""
    frames = list(range(first, last + 1))
    # per frame: how much worse keeping the track is than exchanging it, from the colours seen there
    gain = np.zeros(len(frames))
    for hits, own, other in ((ha, a0, b0), (hb, b0, a0)):
        for i, r in hits:
            app = obs[i].appearance
            if first <= i <= last and app is not None and np.all(np.isfinite(app[r])):
                gain[i - first] += appearance_distance(app[r], own) - appearance_distance(app[r], other)
    if not np.any(gain):
        return closest
    # exchange after frame c: cost(c) = -(sum of gains after c); choose the c that maximises the gain after
    after = np.concatenate([np.cumsum(gain[::-1])[::-1][1:], [0.0]])
    return frames[int(np.argmax(after))]
