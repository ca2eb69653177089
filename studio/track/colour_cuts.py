"""Cut a tracklet where its clothing colours change for good: it went on with someone else.

An online track can go on from one person to another without a gap: at a door, one person walks out of
sight just as another walks in where they were; in a crowd, a coasting track takes whoever comes next
to its prediction. Motion sees one smooth path; the colours of the observations it holds say two people.
Offline, the whole tracklet is known, so the change can be found and cut before stitching, which then
links each piece with the motion and colours of its own person. Stitching joins the two pieces of a cut
again only when their colours next to the cut agree as a re-identification asks
(``StitchConfig.reid_max_appearance``), not merely within a motion link's looser ``max_appearance``: a cut
through one person is undone, but not one between two people who left and entered view at one spot.

A tracklet is cut at the *change point* of its described observations: the split into an earlier and a
later part whose median colours differ most, provided they differ by at least ``min_change`` (ΔE,
:func:`studio.track.appearance.appearance_distance`), each part has at least ``views`` described
observations, each part is consistent (its observations' median difference from its own median at most
``max_spread``) and the ``views`` observations on each side of the split are nearer their own part's
median than the other's (a short run of a neighbour's colours, from a box paired with the wrong laser
detection, is no change). Observations like neither part (``min_change`` or more from both medians: a
crop of the two people at once, as the one walks in where the other walks out) take no side; until
session 44 one such crop next to the change blocked every split near it (simulated ``moving`` seed 18
frame 680: 41 ΔE, 25 and 34 views either side, two such crops, no cut). The cut goes where the track went
unobserved for longest between the last described observation before the change and the first one after
(it lost the one person there and took the other, as at a door; the middle one of equally long gaps,
counted in frames, so neither the stamps' jitter nor a frame the sensor dropped counts), or halfway
between the two when the track missed no frame in between; each piece is searched again. The track's
positions overrule that miss where they tell the two people apart: a track that jumped from one person to
another standing beside them (hidden behind the one, or just not boxed) has two ways that do not meet. For
each place a cut may go, the straight constant-velocity paths through the track's hits over
``jump_context_s`` before it and over as long after it are taken halfway between the two hits either side;
where they lie farther apart than at the longest miss by at least ``jump_gain``, the cut goes where they lie
farthest apart (session 78: simulated ``moving`` seed 50 frame 558, a track went on from a walker to the
person standing 0.4 m behind them, seen by the laser alone for 1.3 s until a 3-frame miss as they walked
off; cut at that miss, two identity switches). A tracklet that
held three people in turn has no one best split: the largest change of the medians may fall inside the
middle person's views, which are like neither part. The split then moves to the end of those views that
gives them to the part whose median they are nearer on average, and the piece holding two people is cut
again (session 57: held-out ``moving`` seed 22, cut 29 frames late).

At either end of a tracklet fewer views suffice when the change is large: the first (or last)
``end_views`` to ``views - 1`` described observations are cut off when their median and the rest's differ by
at least twice ``min_change`` and both parts pass the same consistency and siding tests. This is the door
of the paragraph above when the camera saw the one who walked out only once or twice before the track took
the one who walked in (simulated ``moving`` seed 18 frame 150: two views, 36.7 ΔE; a person 9 m away is
boxed on few image frames).

Measured with ``bench/replay_tracking.py`` on simulator version 4 (docs/results.md, session 27):
``moving`` seeds 1–12 35 → 28 identity switches (under five seeds of 5 mm noise 216 → 175 in all), IDF1
0.90 → 0.94, F1 unchanged; ``rooms`` seed 1 about the same (61 → 58 under five noise seeds); ``static``
seeds 1–6 (the robot still) 31 → 40 under three noise seeds, worse where three people stand 0.4 m apart.
The cut at the longest miss instead of always halfway (session 35, simulator version 6, ``moving`` seeds
1–20): 42 → 43 switches unperturbed, 43.0 → 42.3 under three seeds of 5 mm noise, both within the noise;
kept for the switch it was made for (seed 11 frame 270, gone) and because a miss is evidence where halfway
is none.
"""

from __future__ import annotations

import bisect
import itertools
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from studio.track.appearance import appearance_matrix, appearance_rows
from studio.track.base import Observations
from studio.track.excursions import straight_velocity
from studio.track.swaps import Hits

__all__ = ["ColourCutConfig", "colour_change", "cut_colour_changes"]


@dataclass(frozen=True)
class ColourCutConfig:
    """Options of :func:`cut_colour_changes`.

    Attributes:
        min_change: the medians of the two parts must differ by at least this much (ΔE). The same person
            seen at different times differs by 2.9 (median) / 6.5 (95 %), two people by 12.9 (5 %) / 33
            (median) on the simulated walkers (:mod:`studio.track.appearance`).
        views: described observations each part needs, and how many next to the cut must side with
            their own part.
        max_spread: largest median difference of a part's observations from its own median (ΔE).
        end_views: described observations a part at either end of the tracklet needs when the change is at
            least ``2 · min_change`` (0: ``views`` everywhere). Session 37 (``docs/results.md``): 2 on
            simulated ``moving`` seeds 1–20, 30 → 27 identity switches; 3 for every part (not only at the
            ends) gave 41.
        jump_gain: the cut goes where the track's ways before and after it lie farthest apart, not at
            the longest miss, when they lie farther apart there by at least this, metres (about four
            times a detection's error; 0 turns this off; see the module docstring).
        jump_context_s: each of those ways is fitted to the hits over this long on its side, seconds.
    """

    min_change: float = 15.0
    views: int = 5
    max_spread: float = 8.0
    end_views: int = 2
    jump_gain: float = 0.25
    jump_context_s: float = 1.0

    def __post_init__(self) -> None:
        if self.min_change <= 0 or self.views < 1 or self.max_spread <= 0 or self.end_views < 0:
            raise ValueError("min_change, views and max_spread must be positive, end_views not negative")
        if self.jump_gain < 0 or self.jump_context_s <= 0:
            raise ValueError("jump_gain must be 0 or more, jump_context_s positive")


def _running_medians(x: NDArray[np.float64]) -> NDArray[np.float64]:
    """Row ``m`` of the result is the per-column median of ``x[: m + 1]`` (as :func:`numpy.median`)."""
    out = np.empty_like(x)
    for c in range(x.shape[1]):
        seen: list[float] = []
        for m, v in enumerate(x[:, c].tolist()):
            bisect.insort(seen, v)
            out[m, c] = (seen[m // 2] + seen[(m + 1) // 2]) / 2
    return out


def colour_change(colours: NDArray[np.float64], config: ColourCutConfig) -> int | None:
    """Where a sequence of descriptors ``(M, 6)`` changes for good: the index of the first one of the later
    part, or None when there is no such change (module docstring).

    The medians of every earlier and later part come from running medians (O(M log M) comparisons); the
    consistency tests (O(M) each) run on the splits in order of decreasing change until one passes, so a
    track followed for an hour costs seconds, not minutes.
    """
    n, m_min = len(colours), config.views
    if n < 2 * m_min:
        return _end_change(colours, config)
    first = _running_medians(colours)  # first[m - 1]: median of colours[:m]
    last = _running_medians(colours[::-1])[::-1]  # last[m]: median of colours[m:]
    splits = np.arange(m_min, n - m_min + 1)
    change = appearance_rows(first[splits - 1], last[splits])
    for k in np.argsort(-change, kind="stable"):  # ties: the earlier split, as a scan from the start would
        if change[k] < config.min_change:
            break
        m = int(splits[k])
        meds = np.stack([first[m - 1], last[m]])
        if _split_holds(colours, m, meds, config):
            return _settle(colours, m, meds, config)
    return _end_change(colours, config)


def _settle(colours: NDArray[np.float64], m: int, meds: NDArray[np.float64], config: ColourCutConfig) -> int:
    """The split ``m`` moved to an end of the run of descriptors around it that are like neither part
    (``min_change`` or more from both medians): to the end that gives the run to the part whose median
    it is nearer on average (the later one on a tie).

    A track that held three people in turn has no one best split: the medians' largest change can fall
    inside the middle person's stretch, whose views are like neither part and so take no side in
    :func:`_split_holds` (held-out ``moving`` seed 22 frame 629: 15 views of a second person after the
    first's, cut 29 frames after the change). Moved to an end of that stretch, the split separates two
    of the three, and the piece holding two is searched again.
    """
    d = appearance_matrix(colours, meds)  # (M, 2): to the earlier part's median, to the later part's
    neither = d.min(axis=1) >= config.min_change
    lo, hi = m, m  # the run is colours[lo:hi]
    while lo > 0 and neither[lo - 1]:
        lo -= 1
    while hi < len(colours) and neither[hi]:
        hi += 1
    if lo == hi:
        return m
    run = d[lo:hi].mean(axis=0)  # the run never reaches an end: most of each part lies near its median
    return hi if run[0] < run[1] else lo


def _split_holds(
    colours: NDArray[np.float64], m: int, meds: NDArray[np.float64], config: ColourCutConfig
) -> bool:
    """Whether the parts before and after ``m`` (medians ``meds``) are each consistent and the ``views``
    descriptors next to the split side with their own part."""
    before, after = colours[:m], colours[m:]
    d_b, d_a = appearance_matrix(before, meds), appearance_matrix(after, meds)  # (., 2): to before, after
    if max(np.median(d_b[:, 0]), np.median(d_a[:, 1])) > config.max_spread:
        return False
    # a crop like neither part (two people in one box, next to the change) takes no side
    d_b, d_a = d_b[d_b.min(axis=1) < config.min_change], d_a[d_a.min(axis=1) < config.min_change]
    end, start = d_b[-config.views :], d_a[: config.views]
    if not (len(end) and len(start)):
        return False
    return not (np.any(end[:, 0] > end[:, 1]) or np.any(start[:, 1] > start[:, 0]))


def _end_change(colours: NDArray[np.float64], config: ColourCutConfig) -> int | None:
    """A change that leaves ``end_views`` to ``views - 1`` descriptors at either end (module docstring):
    the index of the first one of the later part, or None."""
    n, m_min, k_min = len(colours), config.views, config.end_views
    if k_min <= 0:
        return None
    best, best_change = None, -np.inf
    for k in range(k_min, min(m_min, n - m_min + 1)):  # the short part has k, the long one at least m_min
        for m in (k, n - k):  # ties: the shorter part, at the start
            meds = np.stack([np.median(colours[:m], axis=0), np.median(colours[m:], axis=0)])
            change = float(appearance_rows(meds[:1], meds[1:])[0])
            if (
                change >= 2.0 * config.min_change
                and change > best_change
                and _split_holds(colours, m, meds, config)
            ):
                best, best_change = m, change
    return best


def _cut_at(obs: Sequence[Observations], hits: Hits, config: ColourCutConfig) -> int | None:
    """Where to cut ``hits`` (the index of the first hit of the later piece), or None."""
    at: list[int] = []
    rows: list[NDArray[np.float32]] = []
    for k, (i, r) in enumerate(hits):
        app = obs[i].appearance
        if app is not None and np.all(np.isfinite(app[r])):
            at.append(k)
            rows.append(app[r])
    shortest = config.end_views if 0 < config.end_views < config.views else config.views  # a part's fewest
    if len(rows) < config.views + shortest:
        return None
    m = colour_change(np.asarray(rows, dtype=np.float64), config)
    if m is None:
        return None
    lo, hi = at[m - 1] + 1, at[m]  # the cut goes before one of hits[lo..hi]
    # steps between hits in the recording's frames (a frame the sensor dropped is no miss); the longest
    # nearest the middle: without a miss, every step is one frame and that is halfway
    gaps = np.diff([i for i, _ in hits[lo - 1 : hi + 1]])
    longest = np.flatnonzero(gaps == gaps.max())
    k = lo + int(longest[np.argmin(np.abs(longest - (hi - lo) / 2))])
    if config.jump_gain <= 0 or hi == lo:
        return k
    jump = _jumps(obs, hits, lo, hi, config.jump_context_s)
    best = int(np.argmax(jump))
    return lo + best if jump[best] - jump[k - lo] >= config.jump_gain else k


def _jumps(
    obs: Sequence[Observations], hits: Hits, lo: int, hi: int, context_s: float
) -> NDArray[np.float64]:
    """For every cut ``k`` in ``lo..hi`` (before ``hits[k]``), how far apart the track's way before the cut
    and its way after it are at the cut (metres): each is the straight constant-velocity path through the
    hits over ``context_s`` on its side, taken halfway between ``hits[k - 1]`` and ``hits[k]``."""
    t = np.array([obs[i].stamp_ns for i, _ in hits], dtype=np.int64)
    xy = np.array([obs[i].xy[r] for i, r in hits], dtype=np.float64)
    span = int(context_s * 1e9)
    out = np.empty(hi - lo + 1)
    for k in range(lo, hi + 1):
        at = (t[k - 1] + t[k]) // 2
        a = int(np.searchsorted(t, t[k - 1] - span))
        b = int(np.searchsorted(t, t[k] + span, side="right"))
        before = _path_at(t[a:k], xy[a:k], at, xy[k - 1])
        after = _path_at(t[k:b], xy[k:b], at, xy[k])
        out[k - lo] = float(np.hypot(*(before - after)))
    return out


def _path_at(
    t: NDArray[np.int64], xy: NDArray[np.float64], at: int, nearest: NDArray[np.float64]
) -> NDArray[np.float64]:
    """The least-squares straight path through positions ``xy`` at stamps ``t`` (ns), at stamp ``at``;
    ``nearest`` (the hit next to the cut) with fewer than three."""
    if len(t) < 3:
        return nearest
    return xy.mean(axis=0) + straight_velocity(t, xy) * (at - t.mean()) * 1e-9


def cut_colour_changes(
    obs: Sequence[Observations], tracklets: dict[int, Hits], config: ColourCutConfig | None = None
) -> tuple[dict[int, Hits], list[tuple[int, int]]]:
    """Cut every tracklet where its colours change for good (module docstring).

    Args:
        obs: the per-frame observations the hits index.
        tracklets: id → hits (sorted by frame); not modified.
        config: options.

    Returns:
        The tracklets after the cuts (a cut tracklet keeps its id for its first piece; later pieces get new
        ids above all others) and, for every cut, the ids of the pieces either side of it (earlier, later).
    """
    cfg = config or ColourCutConfig()
    out: dict[int, Hits] = {}
    next_id = max(tracklets, default=-1) + 1
    cuts: list[tuple[int, int]] = []
    for tid in sorted(tracklets):
        pieces: list[int] = []  # in time order: the stack gives the earlier part first
        todo = [(tid, list(tracklets[tid]))]
        while todo:
            pid, h = todo.pop()
            k = _cut_at(obs, h, cfg)
            if k is None or k <= 0 or k >= len(h):
                out[pid] = h
                pieces.append(pid)
                continue
            todo.append((next_id, h[k:]))
            todo.append((pid, h[:k]))
            next_id += 1
        cuts += list(itertools.pairwise(pieces))
    return out, cuts
