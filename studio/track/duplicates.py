"""Merge two tracks that are one person followed twice, each on one of their legs.

A laser leg pair can go to two tracks, a leg each, where two people walk close enough for the laser to
pair a leg of each (:meth:`studio.track.ukf.UkfTracker._split_pairs`). The same rule keeps a *duplicate*
alive: when one person's legs were once detected as two people (a long stride, a leg hidden), a second
track is born on one leg, and from then on every pair of that person is split between the two tracks, one
leg each, 0.2–0.5 m apart: one person, two tracks, and identity switches between them (simulated
``moving`` seeds 1–3 without a camera: 7 of 25 switches).

Offline, the whole of both tracks is known. Two real people side by side are also detected apart: in
many frames each has an observation of their own. A duplicate hardly ever is: in the frames where both
tracks were observed, they took the two legs of one pair. Two tracks with at least ``min_shared`` such
frames, and observed apart (by two different observations) in at most ``max_apart_share`` of the frames
where both were observed, are merged: the track with more observations keeps the person, with the pair's
own observation where the two had split it and the other's observation where it had none; the other keeps
only its hits outside their common span.

A duplicate also holds one person *in turn*: the detector found one leg (or one detection) a frame, and
the two tracks took them by turns, so they were hardly ever observed in one frame (session 53, held-out
simulated ``moving`` seed 30: two tracks on one person for 3.3 s, 0.2–0.34 m apart, 25 frames with one
of them observed and none with both, and the evaluator went from one to the other and back: two
switches). Frames where only one of the two was observed and its observation lay within ``in_turn_m``
of the other's path (its observations before and after, interpolated) count as shared frames, when at
least ``1 - max_apart_share`` of such frames do and each track holds two or more observations in the
common span. Two people side by side are rarely observed by turns: each is seen on their own in most
frames, which counts against a merge as before.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from studio.track.base import Observations
from studio.track.swaps import Hits

__all__ = ["DuplicateConfig", "merge_duplicates"]


@dataclass(frozen=True)
class DuplicateConfig:
    """Options of :func:`merge_duplicates`.

    Attributes:
        min_shared: two tracks are one person only after holding the two legs of one pair in this many
            frames.
        max_apart_share: ... and when they were observed apart (by two different observations) in at most
            this share of those frames and the shared ones.
        in_turn_m: a frame where only one of the two tracks was observed, within this of the other's path,
            counts as shared (a person's legs are up to about 0.5 m apart in a stride); 0: only split pairs
            count. Session 53 (``bench/replay_tracking.py --laser-again``): simulated ``moving`` seeds
            21–40 36 → 34 identity switches, seeds 1–20 and 41–50 unchanged (31); 0.3 m changed nothing
            (seed 30's two tracks held legs up to 0.5 m from each other's path).
    """

    min_shared: int = 10
    max_apart_share: float = 0.1
    in_turn_m: float = 0.5

    def __post_init__(self) -> None:
        if self.min_shared < 1 or not 0.0 <= self.max_apart_share < 1.0 or self.in_turn_m < 0:
            raise ValueError("min_shared must be at least 1, max_apart_share in [0, 1) and in_turn_m >= 0")


def _parent(o: Observations, row: int) -> int:
    """The observation a row belongs to: the leg pair for one of its legs, else itself."""
    if o.alt_of is None or o.alt_of[row] < 0:
        return row
    return int(o.alt_of[row])


def _shared_and_apart(obs: Sequence[Observations], a: Hits, b: Hits) -> tuple[int, int]:
    """Frames where tracks ``a`` and ``b`` were both observed: how many on the two legs of one pair, how
    many by two different observations."""
    rows_b = dict(b)
    shared = apart = 0
    for i, ra in a:
        rb = rows_b.get(i)
        if rb is None:
            continue
        if _parent(obs[i], ra) == _parent(obs[i], rb):
            shared += 1
        else:
            apart += 1
    return shared, apart


def _in_turn(obs: Sequence[Observations], a: Hits, b: Hits, near_m: float) -> tuple[int, int]:
    """Frames of the common span where only one of tracks ``a`` and ``b`` was observed: how many, and in how
    many of them that observation lay within ``near_m`` of where the other track was (its observations
    before and after, interpolated by frame); 0, 0 unless each holds at least two observations there."""
    lo, hi = max(a[0][0], b[0][0]), min(a[-1][0], b[-1][0])
    spans = []
    for h in (a, b):
        inside = [(i, r) for i, r in h if lo <= i <= hi]
        if len(inside) < 2:
            return 0, 0
        spans.append(
            (np.array([i for i, _ in inside]), np.array([obs[i].xy[r] for i, r in inside], dtype=np.float64))
        )
    alone = near = 0
    for (fi, xi), (fo, xo) in (spans, spans[::-1]):
        only = ~np.isin(fi, fo)
        if not only.any():
            continue
        other = np.c_[np.interp(fi[only], fo, xo[:, 0]), np.interp(fi[only], fo, xo[:, 1])]
        alone += int(only.sum())
        near += int(np.count_nonzero(np.hypot(*(xi[only] - other).T) <= near_m))
    return alone, near


def merge_duplicates(
    obs: Sequence[Observations], tracks: dict[int, Hits], config: DuplicateConfig | None = None
) -> tuple[dict[int, Hits], list[tuple[int, int]]]:
    """Merge the tracks that follow one person twice (see the module docstring).

    Args:
        obs: the per-frame observations.
        tracks: track id → its hits ``(frame, row)`` in frame order.
        config: options.

    Returns:
        The tracks (a merged-away track keeps its hits outside the common span, or is gone), and the
        ``(kept, merged)`` id pairs.
    """
    cfg = config or DuplicateConfig()
    out = {tid: list(h) for tid, h in tracks.items() if h}
    merges: list[tuple[int, int]] = []
    # shared frames of each pair that qualifies, ``(ta, tb)`` with ta < tb; a merge re-measures only the
    # pairs of the two tracks it changed
    found: dict[tuple[int, int], int] = {}

    def measure(pairs: list[tuple[int, int]]) -> None:
        for ta, tb in pairs:
            found.pop((ta, tb), None)
            a, b = out[ta], out[tb]
            if a[-1][0] < b[0][0] or b[-1][0] < a[0][0]:
                continue
            shared, apart = _shared_and_apart(obs, a, b)
            alone, near = _in_turn(obs, a, b, cfg.in_turn_m) if cfg.in_turn_m > 0 else (0, 0)
            together = shared + (near if near >= (1.0 - cfg.max_apart_share) * alone else 0)
            if together >= cfg.min_shared and apart <= cfg.max_apart_share * (together + apart):
                found[ta, tb] = together

    ids = sorted(out, key=lambda t: out[t][0][0])
    pairs = []
    for n, ta in enumerate(ids):  # by start: only tracks that begin before ta ends can overlap it
        for tb in ids[n + 1 :]:
            if out[tb][0][0] > out[ta][-1][0]:
                break
            pairs.append((min(ta, tb), max(ta, tb)))
    measure(pairs)
    while found:
        (ta, tb), _ = max(found.items(), key=lambda kv: (kv[1], -kv[0][0], -kv[0][1]))
        keep, drop = (ta, tb) if len(out[ta]) >= len(out[tb]) else (tb, ta)
        out[keep], rest = _merged(obs, out[keep], out[drop])
        if rest:
            out[drop] = rest
        else:
            del out[drop]
            for key in [k for k in found if drop in k]:
                del found[key]
        merges.append((keep, drop))
        changed = [t for t in (keep, drop) if t in out]
        measure(sorted({(min(t, u), max(t, u)) for t in changed for u in out if u != t}))
    return out, merges


def _merged(obs: Sequence[Observations], keep: Hits, drop: Hits) -> tuple[Hits, Hits]:
    """``keep`` with ``drop``'s person in their common span: a split pair's own observation where both
    held its legs, ``drop``'s observation where ``keep`` had none (where they held different ones, keep's
    stays); and what is left of ``drop`` (its hits before and after the common span)."""
    lo, hi = max(keep[0][0], drop[0][0]), min(keep[-1][0], drop[-1][0])
    rows = dict(keep)
    for i, rb in drop:
        if not lo <= i <= hi:
            continue
        ra = rows.get(i)
        if ra is None:
            rows[i] = rb  # (a leg: its pair's other leg may be someone else's)
        elif _parent(obs[i], ra) == _parent(obs[i], rb):
            rows[i] = _parent(obs[i], ra)
    rest = [(i, r) for i, r in drop if not lo <= i <= hi]
    return sorted(rows.items()), rest
