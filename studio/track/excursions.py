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

**Ends** (``ends``). Where a track's person is lost (they walk away or are hidden) just as someone else
appears beside them, the track may take that person's first detections for its own last ones, and that
person's own track starts right after: an identity switch and a switch back, with no hits after the run
to draw a line to. At each end of a track, and at each side of a gap in it longer than ``max_s``, the run
of its last (first) at most ``max_hits`` hits over at most ``max_s`` is taken when every hit of the run
lies closer to another track, by more than the hit's standard error, than to the track's own
constant-velocity path from the hits before the run (velocity fitted over the ``velocity_s`` before it),
and is either farther than ``deviation`` from that path or within ``deviation`` of the other track (where
two tracks go on along one path, as a colour cut leaves them, neither is closer). The other tracks are
those observed within ``max_s`` after the run (before it, at a start); one's position is its hit in that
frame, its straight path through a gap of at most ``max_s``, or, before a later hit, that hit moved back
along the track's velocity there. The longest such run goes, and at least two hits stay before it.

A person who stood still and was lost there (hidden while someone walked past them) is found again on the
same spot, often by the passer-by's track as its last hits, while their own track goes on only after a
long gap or not at all. So the other tracks also count one that stood still (at most ``stood_speed`` over
its last ``velocity_s``) at its last hit before the run, if that hit is at most ``stood_s`` before the
run's end and its next one, if any, more than ``max_s`` after: its position after that hit is that hit.
Measured in session 56 (docs/results.md).

Where the lost person turned, their predicted way misses the run, and the positions cannot tell whose it
is; the camera can. A run whose hits all lie farther than ``deviation`` from the track's own path is also
taken when it holds a described hit and each of its described hits lies within ``colour_margin`` ΔE of
the median colours of one of those other tracks, and nearer them by ``colour_margin`` or more than the
track's own colours outside the run (both from ``colour_views`` described hits at least). Measured in
session 57 (docs/results.md).

Measured with ``bench/replay_tracking.py`` on simulator version 4 (docs/results.md, session 29):
``moving`` seeds 1–12 identity switches 23 → 20 unperturbed and 147 → 131 under five seeds of 5 mm noise,
F1 unchanged (0.9611); ``static`` seeds 1–6 under three noise seeds 40 → 28, F1 0.963 → 0.966; ``rooms``
seed 1 F1 0.9526 → 0.9555, switches 62 → 67 over five noise seeds (one more on each: a person found again
after a long gap who was not labelled there before); laser only 93 → 96 unperturbed, 94 → 94 on
average under two noise seeds.
"""

from __future__ import annotations

import itertools
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from studio.track.appearance import APPEARANCE_DIM, appearance_matrix
from studio.track.base import Observations
from studio.track.fill import track_paths
from studio.track.swaps import Hits

__all__ = ["ExcursionConfig", "detach_excursions", "straight_velocity"]


@dataclass(frozen=True)
class ExcursionConfig:
    """Options of :func:`detach_excursions`.

    Attributes:
        deviation: every hit of an excursion lies farther than this from the straight line between the
            track's hits around it, metres (about four times a detection's error).
        max_hits: longest excursion, in hits.
        max_s: longest time between the hits around an excursion, seconds (over longer spans a walker's
            path is no straight line).
        ends: also take a run at a track's end that went onto someone whose track goes on (see the
            module docstring).
        velocity_s: the track's velocity before an end's run is fitted over this long, seconds.
        stood_s: an end's run may also have gone onto someone who stood still where their track ended
            (began) at most this long before (after) the run, seconds; 0 turns this off.
        stood_speed: a track stood still at its end when its speed over its last ``velocity_s`` (at
            least three hits) was at most this, m/s.
        colour_margin: an end's run that left the track's own path but lies nowhere near another track's
            is still taken when each of its described hits lies within this (ΔE) of the colours of one of
            those other tracks and nearer them by at least this than the track's own (0 turns this off;
            see the module docstring).
        colour_views: described hits the track's own colours (outside the run) and the other track's
            need for that.
    """

    deviation: float = 0.25
    max_hits: int = 8
    max_s: float = 2.0
    ends: bool = True
    velocity_s: float = 1.0
    stood_s: float = 5.0
    stood_speed: float = 0.2
    colour_margin: float = 15.0
    colour_views: int = 3

    def __post_init__(self) -> None:
        if self.deviation <= 0 or self.max_hits < 1 or self.max_s <= 0 or self.velocity_s <= 0:
            raise ValueError("deviation, max_s and velocity_s must be positive, max_hits at least 1")
        if self.stood_s < 0 or self.stood_speed < 0 or self.colour_margin < 0 or self.colour_views < 1:
            raise ValueError(
                "stood_s, stood_speed and colour_margin must be 0 or more, colour_views at least 1"
            )


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
    # each track's hit stamps and positions, forward and in reversed time (for the ends)
    hits = {o: (_times_xy(obs, ho, False), _times_xy(obs, ho, True)) for o, ho in tracks.items() if ho}
    colours = {o: _median_colours(obs, ho, cfg) for o, ho in tracks.items()} if cfg.colour_margin > 0 else {}
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
        if cfg.ends and h:
            # each piece between gaps longer than max_s (the track's end there is an end of its own)
            t = hits[tid][0][0]
            cuts = [0, *(np.flatnonzero(np.diff(t) > cfg.max_s * 1e9) + 1).tolist(), len(h)]
            for a, b in itertools.pairwise(cuts):
                for head in (False, True):  # the head of what the tail leaves, two hits before each run
                    keep = a + np.flatnonzero(~drop[a:b])
                    if len(keep) >= 3:
                        piece = [h[m] for m in keep]
                        drop[keep] |= _end_run(piece, obs, tid, hits, colours, cfg, head=head)
        taken += int(drop.sum())
        out[tid] = [hit for hit, d in zip(h, drop, strict=True) if not d]
    return out, taken


def _end_run(
    h: Hits,
    obs: Sequence[Observations],
    tid: int,
    hits: dict[int, tuple[tuple[np.ndarray, np.ndarray], tuple[np.ndarray, np.ndarray]]],
    colours: dict[int, np.ndarray | None],
    cfg: ExcursionConfig,
    *,
    head: bool,
) -> np.ndarray:
    """Which of a track's hits form the run at its end (``head``: at its start) that went onto someone whose
    track goes on after it (came before it), or who stood still where their track was lost (begins); see
    the module docstring. All False when there is none. ``colours``: each track's median colours, or None
    (not described enough; empty: the colour test is off)."""
    t, xy = _times_xy(obs, h, head)
    app = _colours_of(obs, h[::-1] if head else h)
    # each hit's standard error: it must lie closer to the other track by more than that
    sigma = np.sqrt([np.trace(obs[i].cov[r]) / 2 for i, r in (h[::-1] if head else h)])
    drop = np.zeros(len(h), dtype=bool)
    n = len(h)
    # the others observed within max_s after this track's last hit, or that stood still at their last hit
    # before it (in reversed time for a head), with that hit's index (-1: none)
    others, other_colours = [], []
    for o, (fwd, back) in hits.items():
        if o == tid:
            continue
        to, xyo = back if head else fwd
        j = int(np.searchsorted(to, t[-1], side="right"))
        if j < len(to) and to[j] <= t[-1] + cfg.max_s * 1e9:
            others.append((to, xyo, -1))
        elif j > 0 and t[-1] - to[j - 1] <= cfg.stood_s * 1e9 and _stood(to[:j], xyo[:j], cfg):
            others.append((to, xyo, j - 1))  # lost (or ended) where it stood still
        else:
            continue
        if (c := colours.get(o)) is not None:
            other_colours.append(c)
    if not others:
        return drop
    for k in range(max(2, n - cfg.max_hits), n):  # the longest run first; two hits before it at least
        if t[-1] - t[k - 1] > cfg.max_s * 1e9:
            continue
        m = t[:k] >= t[k - 1] - cfg.velocity_s * 1e9
        v = straight_velocity(t[:k][m], xy[:k][m])
        ahead = xy[k - 1] + np.outer((t[k:] - t[k - 1]) * 1e-9, v)
        off = np.hypot(*(xy[k:] - ahead).T)
        dist = np.array([_nearest_at(others, tm, p, cfg) for tm, p in zip(t[k:], xy[k:], strict=True)])
        if np.all((dist + sigma[k:] < off) & ((off > cfg.deviation) | (dist < cfg.deviation))) or (
            np.all(off > cfg.deviation) and _colours_left(app, k, other_colours, cfg)
        ):
            drop[k:] = True
            break
    return drop[::-1] if head else drop


def _colours_of(obs: Sequence[Observations], h: Hits) -> np.ndarray:
    """(len(h), 6) descriptors of a track's hits, NaN rows where a hit has none."""
    out = np.full((len(h), APPEARANCE_DIM), np.nan)
    for m, (i, r) in enumerate(h):
        app = obs[i].appearance
        if app is not None:
            out[m] = app[r]
    return out


def _median_colours(obs: Sequence[Observations], h: Hits, cfg: ExcursionConfig) -> np.ndarray | None:
    """A track's median colours, or None with fewer than ``colour_views`` described hits."""
    app = _colours_of(obs, h)
    described = app[np.all(np.isfinite(app), axis=1)]
    return np.median(described, axis=0) if len(described) >= cfg.colour_views else None


def _colours_left(app: np.ndarray, k: int, others: list[np.ndarray], cfg: ExcursionConfig) -> bool:
    """Whether the run ``app[k:]`` holds described hits and each lies within ``colour_margin`` of one of the
    ``others``' colours and nearer them, by ``colour_margin`` or more, than the colours of ``app[:k]``
    (``colour_views`` described at least): a crop like nobody (half hidden, or two people in one box) is
    no evidence."""
    if not others:
        return False
    ok = np.all(np.isfinite(app), axis=1)
    run, rest = app[k:][ok[k:]], app[:k][ok[:k]]
    if not len(run) or len(rest) < cfg.colour_views:
        return False
    own = appearance_matrix(run, np.median(rest, axis=0))[:, 0]
    theirs = appearance_matrix(run, np.array(others)).min(axis=1)
    return bool(np.all((theirs <= cfg.colour_margin) & (theirs + cfg.colour_margin <= own)))


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


def _times_xy(obs: Sequence[Observations], h: Hits, reverse: bool) -> tuple[np.ndarray, np.ndarray]:
    """A track's hit stamps (ns) and positions; ``reverse``: in reversed time (stamps negated, last first)."""
    t = np.array([obs[i].stamp_ns for i, _ in h], dtype=np.int64)
    xy = np.array([obs[i].xy[r] for i, r in h], dtype=np.float64).reshape(-1, 2)
    return (-t[::-1], xy[::-1]) if reverse else (t, xy)


def straight_velocity(t: np.ndarray, xy: np.ndarray) -> np.ndarray:
    """Least-squares velocity (m/s) through hits at stamps ``t`` (ns); zero without a time span."""
    s = (t - t.mean()) * 1e-9
    ss = float(s @ s)
    return (s @ (xy - xy.mean(axis=0))) / ss if ss > 0 else np.zeros(2)


def _nearest_at(
    others: list[tuple[np.ndarray, np.ndarray, int]], tm: int, p: np.ndarray, cfg: ExcursionConfig
) -> float:
    """Distance from ``p`` to the nearest other track's position at stamp ``tm`` (inf: none known)."""
    best = float("inf")
    for to, xyo, stood in others:
        q = _position(to, xyo, tm, cfg, stood=stood)
        if q is not None:
            best = min(best, float(np.hypot(*(p - q))))
    return best


def _stood(to: np.ndarray, xyo: np.ndarray, cfg: ExcursionConfig) -> bool:
    """Whether a track stood still at its last hit: at least three hits over the ``velocity_s`` before,
    fitted speed at most ``stood_speed``."""
    m = to >= to[-1] - cfg.velocity_s * 1e9
    return int(m.sum()) >= 3 and float(np.hypot(*straight_velocity(to[m], xyo[m]))) <= cfg.stood_speed


def _position(
    to: np.ndarray, xyo: np.ndarray, tm: int, cfg: ExcursionConfig, *, stood: int = -1
) -> np.ndarray | None:
    """A track's position at stamp ``tm``: its hit, the straight line through a gap of at most ``max_s``,
    for ``stood_s`` after hit ``stood`` (where it stood still before a longer gap, or its end) that hit,
    or, up to ``max_s`` before its next hit, that hit moved back along the track's velocity there."""
    j = int(np.searchsorted(to, tm))  # the first hit at or after tm
    if stood >= 0 and j == stood + 1 and tm - to[stood] <= cfg.stood_s * 1e9:
        return xyo[stood]
    if j == len(to):
        return None
    if to[j] == tm:
        return xyo[j]
    if j > 0 and to[j] - to[j - 1] <= cfg.max_s * 1e9:
        w = (tm - to[j - 1]) / (to[j] - to[j - 1])
        return (1 - w) * xyo[j - 1] + w * xyo[j]
    if to[j] - tm > cfg.max_s * 1e9:
        return None
    m = to[j:] <= to[j] + cfg.velocity_s * 1e9
    return xyo[j] + straight_velocity(to[j:][m], xyo[j:][m]) * (tm - to[j]) * 1e-9
