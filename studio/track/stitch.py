"""Tracklet stitching across gaps: re-join a person's track that the online tracker split.

A tracklet A that ends at ``t1`` may continue as a tracklet B that starts at ``t2`` with
``0 < t2 - t1 <= max_gap_s``. The pair is allowed when

* motion agrees: the constant-velocity bridge is consistent. With ``e`` the mean of the distances between
  A's end predicted forward to ``t2`` and B's start, and B's start predicted backward to ``t1`` and A's end,
  ``e <= n_sigma·σ + max_accel_speed·gap`` (σ from both estimates' covariances; ``max_accel_speed`` is the
  largest velocity change a person makes unseen, m/s) and the straight distance is walkable:
  ``|B.start - A.end| <= n_sigma·σ + max_speed·gap``;
* appearance agrees (when both carry a descriptor): colour difference
  (:func:`studio.track.appearance.appearance_distance`) ``<= max_appearance``.

Its cost is ``e / gate + appearance_weight · d_app / max_appearance``. Where the frames carry what the
scanners saw (:mod:`studio.track.sight`), a motion link is refused when the walk it assumes — leaving A's end
at A's velocity, reaching B's start at B's — crossed places the scanners saw empty for ``seen_empty_s`` or
longer: whoever A was did not walk that way, so B is someone else.

Longer gaps, up to ``reid_max_gap_s`` (someone who left the sensors' view and came back), cannot be
bridged by motion; such a pair is allowed by **appearance alone**: both tracklets are described by at
least ``min_views`` observations, their whole-tracklet colours differ by at most
``reid_max_appearance`` and the distance is walkable (``max_speed · gap``). Its cost is
``1 + d_app / reid_max_appearance``: a re-identification never beats a good motion bridge. Of the
returns one lost person could make, the sooner is the likelier: each re-identification of A costs
``reid_cost_per_min`` more for every minute it comes after A's soonest one.

Without colours on both sides (a laser-only rig, someone the camera did not describe), a long gap, up to
``lost_max_gap_s``, is still bridged when both tracklets are long (``lost_min_duration_s``: a person, not
clutter) and the later one starts near where the earlier one was lost (within ``lost_distance + lost_speed ·
gap``): most people who vanish from a robot's sensors for a few seconds are hidden, not gone. With colours on
both sides that differ too much for a re-identification, the same position rule still joins them (whatever
their durations) when the colours next to the joint (``app_end``, ``app_start``) differ by at most
``max_appearance``: a tracklet's colours as a whole are spoiled by a stretch on a neighbour, and a few views
of someone far away are noisy. Where the frames carry what the scanners saw, a tracklet may also continue one
lost longer ago than a motion bridge reaches when the walk between them (the one that leaves A's end at A's
velocity and reaches B's start at B's) runs within ``hidden_max_error`` of what both velocities predict and
the scanners never saw any of its way empty: someone who walked on, hidden. The cost of such links,
``lost_cost`` plus up to 0.5 for the distance (or the walk's error), is above any colour or motion link, so
they only take what nothing better wants. A wrong guess costs little: without it the person comes back under a
new id, which the evaluator counts as a switch as well.

Ends are matched to starts one-to-one by the Hungarian algorithm with a cost for leaving an end or a start
unlinked, and chains (A → B → C) follow. Tracklets without usable colours (``min_views``) attach by motion
only, after the described ones are linked; a chain of them that nothing continues goes into the gap of a
re-identification when it lies in that gap near both ends (someone far away, standing still) or goes on
by motion from where one end is and lies a walk from the other (someone who walked on), and so does
a chain with described pieces whose colours agree with both ends (a piece described by only a few crops,
``fill_max_views``, as a motion link asks; one described by more, as a re-identification asks). A piece
seen in two crops that both say someone else (``few_views``) goes in only where both ends are near it.
"""

from __future__ import annotations

import itertools
from collections.abc import Callable, Collection
from dataclasses import dataclass, replace

import numpy as np
from numpy.typing import NDArray

from studio.track.appearance import appearance_distance
from studio.track.gnn import gnn_assign
from studio.track.sight import Sight

__all__ = ["StitchConfig", "Tracklet", "chain_links", "link_cuts", "stitch_links"]

FloatArray = NDArray[np.float64]


@dataclass(frozen=True)
class Tracklet:
    """What stitching needs to know about one tracklet.

    Attributes:
        track_id: its id.
        start_ns, end_ns: stamps of its first and last observation, ns.
        x_start, x_end: (4,) (smoothed) states ``[px, py, vx, vy]`` there (m, m/s).
        P_start, P_end: (4, 4) their covariances.
        app_start, app_end: (6,) appearance descriptors near its start / end, or None.
        app: (6,) descriptor of the whole tracklet, or None.
        n_app: how many observations ``app`` comes from.
        hit_ns, x_hit, P_hit: (K,) stamps of its observations and (K, 4) / (K, 4, 4) its forward-filtered
            states there (each from the observations up to it), or None; with them a tracklet may be
            continued by one that starts before it ends (its tail is then given up).
    """

    track_id: int
    start_ns: int
    end_ns: int
    x_start: FloatArray
    P_start: FloatArray
    x_end: FloatArray
    P_end: FloatArray
    app_start: NDArray[np.float32] | None = None
    app_end: NDArray[np.float32] | None = None
    app: NDArray[np.float32] | None = None
    n_app: int = 0
    hit_ns: NDArray[np.int64] | None = None
    x_hit: FloatArray | None = None
    P_hit: FloatArray | None = None

    def cut_before(self, stamp_ns: int) -> Tracklet | None:
        """This tracklet as it stood at its last observation before ``stamp_ns`` (forward-filtered end
        state), or None when it has fewer than two observations before then."""
        if self.hit_ns is None or self.x_hit is None or self.P_hit is None:
            return None
        k = int(np.searchsorted(self.hit_ns, stamp_ns)) - 1
        if k < 1:
            return None
        return replace(self, end_ns=int(self.hit_ns[k]), x_end=self.x_hit[k], P_end=self.P_hit[k])


@dataclass(frozen=True)
class StitchConfig:
    """Options of :func:`stitch_links`.

    Attributes:
        max_gap_s: longest gap bridged, seconds.
        n_sigma: how many standard deviations of the estimates the gates allow.
        max_accel_speed: largest unseen change of velocity, m/s (2 = a walker turning back).
        max_speed: fastest walking speed, m/s.
        max_appearance: largest colour difference (ΔE) of a motion link (when both sides have descriptors).
        appearance_weight: weight of the appearance term in the cost. At 2 (1 until session 33) a motion
            link's colours count as much as its motion error at half the colour gate: ``moving`` seeds 1–20 of
            simulator version 6, 53 → 48 identity switches, IDF1 0.942 → 0.950 (1.5 and 3: 50 and 49;
            version 5's recordings 63 → 62; ``rooms`` seed 1, six people queueing 0.4 m apart in a door for
            30 s, 35 → 46 switches but IDF1 0.736 → 0.816). Two tracklets whose joint colours differ by
            12–20 ΔE are two people more often than one (one person: 95 % under 6.5 ΔE,
            :mod:`studio.track.appearance`).
        reid_max_gap_s: longest gap bridged by appearance alone, seconds (0: no re-identification). Session
            37: 60 → 90 s (with ``reid_cost_per_min``; see there).
        reid_cost_per_min: how much more a re-identification of A costs per minute it comes after the
            soonest re-identification A could make (0.2: a return a minute later must match A's colours
            2 ΔE better to win). Session 37 (``docs/results.md``): with a 90 s window alone, ``rooms`` seed 1
            joined a walker lost for 4.7 s to a piece of themselves 65 s later whose colours matched 0.6 ΔE
            better, and the 4.7 s return began a second track of them (IDF1 0.889 → 0.817); with this
            term ``rooms`` is as with 60 s and ``moving`` seeds 1–20 gain what the longer window gives.
            It orders the returns of one person only: it does not raise a re-identification against a
            motion link.
        reid_max_appearance: largest colour difference of a re-identification.
        min_views: a tracklet's colours count only when at least this many of its observations have a
            descriptor (one crop may show a neighbour or be half occluded).
        few_views: a tracklet described by at least this many observations, but fewer than ``min_views``,
            has no colours a link may rest on, yet two crops that both say someone else refuse a motion link
            to (from) a described tracklet, as ``max_appearance`` does between described ones (0: never).
            Session 58 (``docs/results.md``): held-out ``moving`` seed 37, person 0 described twice, 48 ΔE
            from the track of person 5 whom their tracklet was linked to by motion; seeds 21–40 21 → 19
            identity switches, seeds 1–20 and 41–50 18 → 19; 1 (one crop, perhaps of a neighbour) was no
            gain. Such a piece also goes into no re-identification's gap away from both its ends
            (:func:`stitch_links`, session 77).
        few_max_appearance: the colour difference (ΔE) over which those two crops refuse the link. Until
            session 60 it was ``max_appearance`` (25); held-out seed 22 linked person 1's track by motion to
            a piece of person 5 that walked on where person 1 left view, seen twice, 24 ΔE from person 1's
            colours and 4–6 ΔE from person 5's (two switches). Medians of ten views differ by 6.5 ΔE or less
            for one person in 95 % of cases and by 12.9 or more for two people (:mod:`.appearance`); two
            views are noisier, hence the margin over both.
        unknown_appearance: the appearance term of a motion link when a side has no usable colours, as a
            fraction of ``appearance_weight`` (unknown is not a perfect match; 0.25 × 2 = 0.5, the same term
            as before session 33, so laser-only rigs link as they did).
        miss_cost: cost of leaving a tracklet end or start unlinked; links are chosen to minimise the total,
            so one good link beats two poor ones that conflict with it.
        max_overlap_s, overlap_cost: B may continue A although it starts up to ``max_overlap_s`` before A
            ends (A's tail left its person — pulled onto clutter or a neighbour — and B took the person
            over): the link is judged from A's state at its last observation before B starts, costs
            ``overlap_cost`` more, and A's observations from B's start on are given up.
        tail_back_s: B may also continue A from one of A's observations up to this long before B starts
            (A's last few observations were already a neighbour's when B picked the person up), at
            ``overlap_cost`` more; A's later observations are then given up (:func:`link_cuts`). 0: never.
            Session 22 (``docs/results.md``): simulated ``moving`` seeds 1–12 with the camera 65 → 59
            identity switches, laser only 112 → 97.
        fill_distance, fill_speed: a chain of pieces (undescribed, or see ``fill_max_views``) goes into the
            gap of a re-identification when each joint is at most ``fill_distance + fill_speed · gap`` long
            (m, m/s), or when one joint is a motion link at most ``fill_distance`` long and the other at most
            ``fill_distance + max_speed · gap``: the piece goes on from where one end is, and the person
            walked on to the other (session 54, ``docs/results.md``: held-out ``moving`` seed 35, a walker
            lost 10 m away and seen again 2 s later on the spot for 2 s by the laser alone, then
            re-identified 20 s and 13.6 m further on; two switches).
        fill_max_views: a described tracklet that nothing links, described by at most this many
            observations, may go into such a gap like an undescribed one when its colours differ from both
            ends' by at most ``max_appearance`` (the median of a few crops of someone far away is too
            noisy for the ``reid_max_appearance`` of a re-identification of its own). Session 44
            (``docs/results.md``): ``moving`` seed 8 two switches fewer, a four-view piece of someone 8 m
            away 15 ΔE off their colours; a walker in other clothes seen in ten views (16 ΔE off) stays
            out. A piece described by more observations goes into a gap, alone or in a chain, when its
            colours are within ``reid_max_appearance`` of both ends' and the chain holds no
            re-identification of its own (session 53). 0: only undescribed pieces.
        walk_max_appearance: a chain that goes into a gap because it continues both ends by motion links,
            colours set aside (its colours spoiled where it was seen), holds no piece described by more
            than ``fill_max_views`` observations whose colours differ from either end's by more than this
            (ΔE): that is someone else who stepped in where the person vanished (session 78,
            ``docs/results.md``: held-out ``moving`` seed 97, a 29 s piece of another person, 125 views
            41 ΔE off, went into a 34 s gap: 1 → 8 switches; the spoiled pieces of seeds 66 and 17 were
            20–29 ΔE off).
        beside_m: a chain of pieces whose tracklet lies within this of another tracklet (not an end of the
            gap) at half or more of its observations goes into no gap: it is a second track on that person
            (a duplicate born on one leg), not a piece of whoever was lost, m (0: no such check). Two people
            walking together keep their centres 0.4 m or more apart (held-out ``moving`` seed 43, 0.41–0.54 m:
            at 0.4 and 0.5 m that companion's piece stayed out of their gap, 1 → 3 switches). Session 67
            (``docs/results.md``): with a 30 Hz camera, simulated ``moving`` seed 3 (60 s) had a duplicate's
            0.6 s piece put into another person's 20 s gap and the encounter re-decision then spread the
            person over both tracks (two switches); at 10 Hz seeds 1–70 are unchanged.
        lost_max_gap_s: longest gap bridged without colours (not both sides described) and without a motion
            bridge, seconds (0: never).
        lost_min_duration_s: both tracklets of such a link span at least this long, seconds.
        lost_distance, lost_speed: the later tracklet starts within ``lost_distance + lost_speed · gap`` of
            where the earlier one ended (m, m/s).
        lost_cost: cost of such a link at distance 0 (it rises by 0.5 at the limit; ``2 · miss_cost`` is
            the most any link may cost).
        seen_empty_s: a motion link is refused when the walk it assumes crossed places the scanners saw
            empty (:mod:`studio.track.sight`) for at least this long, seconds (0: never; no effect without a
            ``sight``). Session 62 (``docs/results.md``): of the motion-link candidates (gaps of 0.5–3 s) on
            laser-only replays of simulated ``moving`` seeds 1–12 and 51–62, 0.5 s refuses none of 441 that
            join one person and 37 of 121 that join two; laser-only 107 → 104 identity switches, with the
            camera (seeds 1–70) 55 → 54, F1 up on both.
        hidden_min_duration_s, hidden_max_error: without colours on both sides, B continues A across a
            gap of ``max_gap_s`` to ``lost_max_gap_s`` when both span at least ``hidden_min_duration_s``,
            the mean of the distances from B's start to the way A's end walks in the gap (at A's velocity
            or slower, stopping anywhere on it) and from A's end to the way B's start came (the same,
            backwards) is at most ``hidden_max_error`` (m), and the scanners never saw the walk between them
            (as for ``seen_empty_s``) empty: someone who walked on unseen, behind someone or something,
            though further than "found again where lost" reaches. 0: never; no effect without a ``sight``.
            Session 62 (``docs/results.md``): laser-only replays of simulated ``moving`` seeds 51–62 49 → 44
            identity switches, seeds 1–12 55 → 55, F1 up on both; with the camera, seeds 1–70 54 → 57, so
            the labelling pipeline sets it to 0 on rigs with a camera
            (:func:`studio.pipeline.label.tracking_config`). Session 76: the ways instead of the points
            at their ends (people slow down and stop; walking on at one speed for seconds overshoots),
            laser-only seeds 11–20 and 39–70 174 → 169 switches, IDF1 0.811 → 0.820.

    The ``lost_*`` defaults (session 22, ``docs/results.md``): laser-only replays of the simulated
    ``moving`` seeds 1–8 from 93 to 72 identity switches, seeds 9–12 from 52 to 40, F1 unchanged; with the
    camera, seeds 1–8 the same switches.
    """

    max_gap_s: float = 3.0
    n_sigma: float = 3.0
    max_accel_speed: float = 2.0
    max_speed: float = 2.5
    max_appearance: float = 25.0
    appearance_weight: float = 2.0
    reid_max_gap_s: float = 90.0
    reid_max_appearance: float = 10.0
    reid_cost_per_min: float = 0.2
    min_views: int = 3
    few_views: int = 2
    few_max_appearance: float = 20.0
    unknown_appearance: float = 0.25
    miss_cost: float = 1.5
    max_overlap_s: float = 3.0
    overlap_cost: float = 0.25
    fill_distance: float = 1.0
    fill_speed: float = 0.5
    fill_max_views: int = 5
    walk_max_appearance: float = 35.0
    beside_m: float = 0.3
    lost_max_gap_s: float = 20.0
    lost_min_duration_s: float = 2.0
    lost_distance: float = 1.0
    lost_speed: float = 0.25
    lost_cost: float = 2.0
    tail_back_s: float = 0.5
    seen_empty_s: float = 0.5
    hidden_min_duration_s: float = 0.5
    hidden_max_error: float = 1.5

    def __post_init__(self) -> None:
        if (
            min(
                self.max_gap_s,
                self.max_appearance,
                self.reid_max_appearance,
                self.few_max_appearance,
                self.walk_max_appearance,
            )
            <= 0
        ):
            raise ValueError(
                "max_gap_s, max_appearance, reid_max_appearance, few_max_appearance and walk_max_appearance"
                " must be positive"
            )
        if (
            min(
                self.reid_max_gap_s,
                self.reid_cost_per_min,
                self.lost_max_gap_s,
                self.lost_distance,
                self.lost_speed,
                self.few_views,
                self.seen_empty_s,
                self.hidden_min_duration_s,
                self.hidden_max_error,
                self.beside_m,
            )
            < 0
        ):
            raise ValueError(
                "reid_max_gap_s, reid_cost_per_min, few_views, seen_empty_s, beside_m, the hidden_* options, "
                "and the lost_* gap, distance and speed must not be negative"
            )


def _pair_cost(a: Tracklet, b: Tracklet, cfg: StitchConfig, sight: Sight | None = None) -> float | None:
    link = _link(a, b, cfg, sight)
    return None if link is None else link[0]


def _link(
    a: Tracklet, b: Tracklet, cfg: StitchConfig, sight: Sight | None = None
) -> tuple[float, int | None] | None:
    """The cost of B continuing A, and the stamp of A's last observation kept when B continues it from an
    earlier one than its last before B starts (else None); None when B may not continue A."""
    c = _plain_cost(a, b, cfg, sight)
    best: tuple[float, int | None] | None = None if c is None else (c, None)
    gap = (b.start_ns - a.end_ns) * 1e-9
    if cfg.tail_back_s <= 0 or b.start_ns <= a.start_ns or not -cfg.max_overlap_s <= gap <= cfg.max_gap_s:
        return best
    # A's last observations before B starts may have left the person for a neighbour (B took the person
    # over from there): B may continue A from one of A's observations up to tail_back_s before B starts
    head = a.cut_before(b.start_ns)  # A at its last observation before B starts: the plain (overlap) case
    while head is not None:
        head = head.cut_before(head.end_ns)
        if head is None or (b.start_ns - head.end_ns) * 1e-9 > cfg.tail_back_s:
            break
        ch = _plain_cost(head, b, cfg, sight)
        if ch is not None and (best is None or ch + cfg.overlap_cost < best[0]):
            best = (ch + cfg.overlap_cost, head.end_ns)
    return best


def _plain_cost(a: Tracklet, b: Tracklet, cfg: StitchConfig, sight: Sight | None = None) -> float | None:
    gap = (b.start_ns - a.end_ns) * 1e-9
    if gap <= 0.0:
        if -gap > cfg.max_overlap_s or b.start_ns <= a.start_ns:
            return None
        head = a.cut_before(b.start_ns)
        if head is None:
            return None
        c = _plain_cost(head, b, cfg, sight)
        return None if c is None else c + cfg.overlap_cost
    if gap > cfg.max_gap_s:
        return _reid_cost(a, b, gap, cfg, sight)
    pa, va, pb, vb = a.x_end[:2], a.x_end[2:], b.x_start[:2], b.x_start[2:]
    e = _motion_error(a, b, gap)
    lam = lambda M: float(np.linalg.eigvalsh(M)[-1])  # noqa: E731 - largest eigenvalue
    var_pos = lam(a.P_end[:2, :2]) + lam(b.P_start[:2, :2])
    var = var_pos + 0.5 * gap**2 * (lam(a.P_end[2:, 2:]) + lam(b.P_start[2:, 2:]))
    gate = cfg.n_sigma * np.sqrt(var) + cfg.max_accel_speed * gap
    if e > gate or np.hypot(*(pb - pa)) > cfg.n_sigma * np.sqrt(var_pos) + cfg.max_speed * gap:
        return None
    if (
        sight
        and 0 < cfg.seen_empty_s <= gap
        and sight.clear_seconds(pa, a.end_ns, pb, b.start_ns, va, vb) >= cfg.seen_empty_s
    ):
        return None  # the scanners saw the way between them empty: nobody walked it
    cost = e / gate
    if _described(a, cfg) and _described(b, cfg):
        d = appearance_distance(a.app_end, b.app_start)  # type: ignore[arg-type]
        if d > cfg.max_appearance:
            return None
        return cost + cfg.appearance_weight * d / cfg.max_appearance
    if _few_against(a, b, cfg):
        return None
    # Unknown appearance is not a perfect match: a tracklet the camera never saw (laser clutter, or
    # someone out of view) must not win over a continuation whose colours agree.
    return cost + cfg.appearance_weight * cfg.unknown_appearance


def _motion_error(a: Tracklet, b: Tracklet, gap: float) -> float:
    """The mean of the distances between A's end predicted ``gap`` seconds forward and B's start, and B's
    start predicted back and A's end (constant velocity), m."""
    pa, va, pb, vb = a.x_end[:2], a.x_end[2:], b.x_start[:2], b.x_start[2:]
    return float(0.5 * (np.hypot(*(pb - (pa + va * gap))) + np.hypot(*(pa - (pb - vb * gap)))))


def _stop_error(a: Tracklet, b: Tracklet, gap: float) -> float:
    """As :func:`_motion_error`, but each side may have slowed down or stopped on the way: the distances to
    the way A's end walks in ``gap`` seconds at most at its velocity (and B's start back), m."""

    def to_way(p: FloatArray, start: FloatArray, step: FloatArray) -> float:
        n2 = float(step @ step)
        k = 0.0 if n2 <= 0.0 else min(1.0, max(0.0, float((p - start) @ step) / n2))
        return float(np.hypot(*(p - (start + k * step))))

    pa, va, pb, vb = a.x_end[:2], a.x_end[2:], b.x_start[:2], b.x_start[2:]
    return 0.5 * (to_way(pb, pa, va * gap) + to_way(pa, pb, -vb * gap))


def _few_against(a: Tracklet, b: Tracklet, cfg: StitchConfig) -> bool:
    """Whether one of A and B is described by ``few_views`` to ``min_views - 1`` observations, the other is
    described, and their colours where B continues A differ by more than ``few_max_appearance``."""
    if cfg.few_views <= 0 or a.app_end is None or b.app_start is None:
        return False
    if not ((_few(a, cfg) and _described(b, cfg)) or (_few(b, cfg) and _described(a, cfg))):
        return False
    return appearance_distance(a.app_end, b.app_start) > cfg.few_max_appearance


def _few(t: Tracklet, cfg: StitchConfig) -> bool:
    """Whether ``t`` is described by ``few_views`` to ``min_views - 1`` observations: too few for its colours
    to carry a link, enough for two crops that say someone else to refuse one."""
    return cfg.few_views <= t.n_app < cfg.min_views


def _described(t: Tracklet, cfg: StitchConfig) -> bool:
    has = t.app is not None and t.app_start is not None and t.app_end is not None
    return has and t.n_app >= cfg.min_views


def _reid_cost(a: Tracklet, b: Tracklet, gap: float, cfg: StitchConfig, sight: Sight | None) -> float | None:
    if not (_described(a, cfg) and _described(b, cfg)):
        return _lost_cost(a, b, gap, cfg, sight)
    if gap > cfg.reid_max_gap_s:
        return None
    if np.hypot(*(b.x_start[:2] - a.x_end[:2])) > cfg.max_speed * gap + 1.0:
        return None
    d = appearance_distance(a.app, b.app)  # type: ignore[arg-type]
    if d <= cfg.reid_max_appearance:
        return 1.0 + d / cfg.reid_max_appearance
    # A tracklet's colours as a whole are spoiled when a stretch of it was on a neighbour, and a few
    # views of someone far away are noisy: one who comes back where they were lost, with the colours
    # seen at the joint agreeing as a motion link asks, is still found again (the camera saw a person on
    # both sides, so no clutter guard on the durations)
    if appearance_distance(a.app_end, b.app_start) <= cfg.max_appearance:  # type: ignore[arg-type]
        return _lost_cost(a, b, gap, cfg, sight, min_duration_s=0.0)
    return None


def _lost_cost(
    a: Tracklet,
    b: Tracklet,
    gap: float,
    cfg: StitchConfig,
    sight: Sight | None,
    *,
    min_duration_s: float | None = None,
) -> float | None:
    """Cost of B continuing A across a long gap by where A was lost (both tracklets span ``min_duration_s``,
    default ``lost_min_duration_s``), else by a hidden walk (``hidden_*``), or None."""
    if gap > cfg.lost_max_gap_s:
        return None
    shortest_s = min(a.end_ns - a.start_ns, b.end_ns - b.start_ns) * 1e-9
    shortest_allowed = cfg.lost_min_duration_s if min_duration_s is None else min_duration_s
    limit = cfg.lost_distance + cfg.lost_speed * gap
    d = float(np.hypot(*(b.x_start[:2] - a.x_end[:2])))
    if shortest_s >= shortest_allowed and d <= limit:
        return cfg.lost_cost + 0.5 * d / limit
    # someone who walked on unseen: B starts on the way A's walk leads (and A ends on the way B's came),
    # and the scanners never saw that walk's way empty
    if not sight or cfg.hidden_max_error <= 0 or shortest_s < cfg.hidden_min_duration_s:
        return None
    e = _stop_error(a, b, gap)
    if e > cfg.hidden_max_error:
        return None
    if sight.clear_seconds(a.x_end[:2], a.end_ns, b.x_start[:2], b.start_ns, a.x_end[2:], b.x_start[2:]) > 0:
        return None
    return cfg.lost_cost + 0.5 * e / cfg.hidden_max_error


def stitch_links(
    tracklets: list[Tracklet],
    *,
    config: StitchConfig | None = None,
    cut: Collection[tuple[int, int]] = (),
    sight: Sight | None = None,
) -> list[tuple[int, int]]:
    """Decide which tracklet continues which.

    Args:
        tracklets: the tracklets.
        config: options.
        cut: ``(id_a, id_b)`` pairs that were one tracklet, cut where its colours changed for good
            (:mod:`studio.track.colour_cuts`). B continues A again only when both are described and their
            colours next to the cut differ by at most ``reid_max_appearance``: a motion link's looser
            ``max_appearance`` would join two people again whom the cut separated (one walked out of view as
            the other walked in at that spot: the joint is as smooth as a path gets; simulated ``moving``
            seeds 1–20 of version 6, four such links, joint colours 17–25 ΔE apart, all wrong).
        sight: what the scanners saw in each frame; with it a motion link is refused where the walk it
            assumes (leaving A's end at A's velocity, reaching B's start at B's) crossed places they saw
            empty for ``seen_empty_s`` or longer, and a hidden walk may join tracklets (``hidden_*``).

    Returns:
        ``(id_a, id_b)`` links: B continues A. Every id is at most once an ``id_a`` and once an ``id_b``.
    """
    cfg = config or StitchConfig()
    apart = set(cut)

    def may_rejoin(a: Tracklet, b: Tracklet) -> bool:
        if (a.track_id, b.track_id) not in apart:
            return True
        if not (_described(a, cfg) and _described(b, cfg)):
            return False
        return appearance_distance(a.app_end, b.app_start) <= cfg.reid_max_appearance  # type: ignore[arg-type]

    described = [t for t in tracklets if _described(t, cfg)]
    # Pass 1: the tracklets the camera described, with motion and colours (and re-identification).
    first = _assign(described, described, cfg, may_rejoin, sight)
    # Pass 2: the others (laser clutter, someone out of view) attach by motion to what pass 1 built; two
    # described chains that pass 1 left apart are not joined.
    nxt = {a: b for a, b, _ in first}
    prv = {b: a for a, b, _ in first}
    desc_ids = {t.track_id for t in described}
    tails = [t for t in tracklets if t.track_id not in nxt]
    heads = [t for t in tracklets if t.track_id not in prv]
    second = _assign(
        tails,
        heads,
        cfg,
        lambda a, b: not (a.track_id in desc_ids and b.track_id in desc_ids) and may_rejoin(a, b),
        sight,
    )
    return _fill_gaps(tracklets, _unjoin(first, second, desc_ids), desc_ids, cfg, sight)


def _assign(
    ends: list[Tracklet],
    starts: list[Tracklet],
    cfg: StitchConfig,
    ok: Callable[[Tracklet, Tracklet], bool],
    sight: Sight | None,
) -> list[tuple[int, int, float]]:
    """One-to-one links from ``ends`` to ``starts`` minimising the total cost: ``(id_a, id_b, cost)``."""
    cost = np.zeros((len(ends), len(starts)))
    allowed = np.zeros(cost.shape, dtype=bool)
    for i, a in enumerate(ends):
        for j, b in enumerate(starts):
            if a.track_id != b.track_id and ok(a, b):
                c = _pair_cost(a, b, cfg, sight)
                if c is not None:
                    cost[i, j], allowed[i, j] = c, True
    if cfg.reid_cost_per_min > 0:
        # Of the returns A could make after a long absence, the sooner is the likelier (the longer someone is
        # away, the likelier a colour match is someone else): each re-identification of A costs more by the
        # minutes it comes after A's soonest one.
        for i, a in enumerate(ends):
            gaps = {
                j: g
                for j, b in enumerate(starts)
                if allowed[i, j] and (g := _reid_gap(a, b, cfg)) is not None
            }
            if gaps:
                soonest = min(gaps.values())
                for j, g in gaps.items():
                    cost[i, j] += cfg.reid_cost_per_min * (g - soonest) / 60.0
    return [
        (ends[i].track_id, starts[j].track_id, float(cost[i, j]))
        for i, j in gnn_assign(cost, allowed, miss_cost=cfg.miss_cost)
    ]


def _reid_gap(a: Tracklet, b: Tracklet, cfg: StitchConfig) -> float | None:
    """The gap of B continuing A by colours alone (a re-identification), seconds, or None when an allowed
    link of B to A would be another kind."""
    gap = (b.start_ns - a.end_ns) * 1e-9
    if gap <= cfg.max_gap_s or not (_described(a, cfg) and _described(b, cfg)):
        return None
    return gap if appearance_distance(a.app, b.app) <= cfg.reid_max_appearance else None  # type: ignore[arg-type]


def _unjoin(
    first: list[tuple[int, int, float]], second: list[tuple[int, int, float]], described: set[int]
) -> list[tuple[int, int]]:
    """All links, less the dearest pass-2 link on every path that joins two described chains."""
    links = {a: (b, c, False) for a, b, c in second} | {a: (b, c, True) for a, b, c in first}
    heads = set(links) - {b for b, _, _ in links.values()}
    drop = set()
    for h in heads:
        seen_described, bridge = h in described, []  # pass-2 links since the last described tracklet
        cur = h
        while cur in links:
            nxt, c, in_first = links[cur]
            if not in_first:
                bridge.append((c, cur))
            if nxt in described:
                if seen_described and bridge:
                    drop.add(max(bridge)[1])
                seen_described, bridge = True, []
            cur = nxt
    return sorted((a, b) for a, (b, _, _) in links.items() if a not in drop)


def _fill_gaps(
    tracklets: list[Tracklet],
    links: list[tuple[int, int]],
    described: set[int],
    cfg: StitchConfig,
    sight: Sight | None,
) -> list[tuple[int, int]]:
    """Put chains of pieces that nothing continues into the gap of a re-identification.

    Pass 1 joins A → C across a long gap by colours; the pieces the camera could not describe in between
    (someone far away, standing where A ended) are then neither before nor after anything. So is a piece the
    camera described in a few crops only (``fill_max_views``) whose noisy colours were too far from A's for a
    re-identification; it counts as one of them where its colours are within ``max_appearance`` of both A's
    and C's. So does a chain of pieces linked to each other but to nothing else whose described pieces all
    agree with A's and C's colours: those with a few crops within ``max_appearance``, the others within
    ``reid_max_appearance``, unless the chain holds a re-identification of its own (session 53: held-out
    ``moving`` seed 28, a walker lost for 4.6 s and found again as a piece whose first crops showed a
    neighbour, 12 ΔE off as a whole, linked on to a 13-view piece 5 ΔE off; A and C were joined across both
    and the pieces, 9 s of the person, came out as a track of their own: two switches). A chain whose
    colours agree with neither end counts too when it continues the gap's start and the gap's end continues
    it by motion links, colours set aside (within ``max_gap_s`` and the gates of :func:`_plain_cost`): the
    person seen there with spoiled colours — a desk top over their trousers while the robot drove past
    (session 76, ``docs/results.md``: simulated ``moving`` seeds 66 and 17, 9 s and 18 s pieces 20–29 ΔE
    off, two switches each). Someone else would have to step in where the person vanished and vanish where
    they come back, both within seconds — which happens in a crowd: a piece described in more than
    ``fill_max_views`` crops more than ``walk_max_appearance`` off either end is someone else's (session 78).
    A free chain goes between A and C when it lies inside the gap in time and each joint is at most
    ``fill_distance + fill_speed · gap`` long, or one joint is a motion link at most ``fill_distance`` long
    and the other a walk (``fill_distance + max_speed · gap``); several go in one after another in time.
    A piece of it seen in ``few_views`` to ``min_views - 1`` crops whose colours differ from an end's by more
    than ``few_max_appearance`` keeps the chain out (those crops say someone else, as they refuse a motion
    link) unless both joints are at most ``fill_distance`` long, or the chain walked through as above: on the
    spot where the person was lost and found again, it is the person whatever two crops say (session 77,
    ``docs/results.md``: simulated ``moving`` seed 11, a second track on a neighbour 4 m from a 53 s gap's
    ends, seen twice 46 ΔE off, went into it: two switches; seed 50, the person standing where they were
    lost for 4 s, seen twice 39 ΔE off, belongs in theirs).
    Where it fits several gaps, it goes where more of its joints are motion links (a short gap a walker
    bridges, within the gates of :func:`_plain_cost`: two people waiting at one spot leave gaps that overlap
    for long, but only the one who left just before the piece starts continues into it), then where the
    joints are shortest.

    A chain may also overlap one end of the gap by up to ``max_overlap_s`` (the online pass had two tracks on
    the person for a moment, or the track after the gap began on someone else and took the person over
    later): at the gap's start when it may continue that end by motion from before its own start (or the
    end's last observation lies within ``fill_distance`` of the chain there), at the gap's end when the
    track after it, at the chain's last observation, lies within ``fill_distance`` of it (or continues it
    by motion). :func:`~studio.track.offline.join_chains` settles the overlap as for any link that
    overlaps. Such a joint counts as neither a motion link nor a clean one: a chain goes where its joints
    do not overlap when it fits such a gap too. Session 65 (``docs/results.md``): held-out ``moving`` seeds
    43 (a 2.5 s piece 0.1 s into the gap's start) and 56 (a 20 s piece 2.6 s past the gap's end, where
    the re-identified track began on a passer-by).
    """
    by_id = {t.track_id: t for t in tracklets}
    nxt = dict(links)
    prv = {b: a for a, b in links}

    def chain_reidentifies(chain: list[int]) -> bool:
        """Whether a chain holds a link across more than ``max_gap_s`` (someone found again: a track of its
        own, not a piece)."""
        return any(
            (by_id[b].start_ns - by_id[a].end_ns) * 1e-9 > cfg.max_gap_s for a, b in itertools.pairwise(chain)
        )

    free = []  # (head, tail, described members, tracklet ids) of chains linked to nothing else
    for t in tracklets:
        if t.track_id in prv:
            continue
        chain = [t.track_id]
        while chain[-1] in nxt:
            chain.append(nxt[chain[-1]])
        members = [by_id[c] for c in chain if c in described]
        if members and (cfg.fill_max_views <= 0 or chain_reidentifies(chain)):
            continue  # only undescribed pieces; or a chain that is a re-identification of its own
        free.append((by_id[chain[0]], by_id[chain[-1]], members, chain))
    free.sort(key=lambda ht: ht[0].start_ns)

    def colours_fit(members: list[Tracklet], a: Tracklet, c: Tracklet) -> bool:
        """Whether the described members of a chain look like both ends of a gap: a few noisy views within
        ``max_appearance``, more within ``reid_max_appearance``."""
        for m in members:
            limit = cfg.max_appearance if m.n_app <= cfg.fill_max_views else cfg.reid_max_appearance
            if any(appearance_distance(m.app, h.app) > limit for h in (a, c)):  # type: ignore[arg-type]
                return False
        return True

    def few_against(chain: list[int], a: Tracklet, c: Tracklet) -> bool:
        """Whether a piece of the chain seen in ``few_views`` to ``min_views - 1`` crops differs from an
        end's colours by more than ``few_max_appearance``: those crops say someone else, as for a motion
        link (:func:`_few_against`)."""
        if cfg.few_views <= 0:
            return False
        few = [m for m in map(by_id.__getitem__, chain) if _few(m, cfg) and m.app is not None]
        return any(
            appearance_distance(m.app, h.app) > cfg.few_max_appearance  # type: ignore[arg-type]
            for m in few
            for h in (a, c)
        )

    blind = replace(cfg, max_appearance=np.inf, few_views=0)

    def walked_through(chain: list[int], a: Tracklet, c: Tracklet, first: Tracklet) -> bool:
        """Whether the chain continues ``a`` and ``c`` continues the chain by motion links, colours set
        aside: the colours against it are the chain's own (A and C agree), spoiled where it was seen —
        unless a piece described in more than ``fill_max_views`` crops differs from the colours of the gap's
        ends (``first`` and ``c``) by more than ``walk_max_appearance``: someone else."""
        if any(
            m.n_app > cfg.fill_max_views and appearance_distance(m.app, h.app) > cfg.walk_max_appearance  # type: ignore[arg-type]
            for m in map(by_id.__getitem__, chain)
            if m.app is not None
            for h in (first, c)
        ):
            return False
        head, tail = by_id[chain[0]], by_id[chain[-1]]
        for x, y in ((a, head), (tail, c)):
            if not 0.0 < (y.start_ns - x.end_ns) * 1e-9 <= cfg.max_gap_s:
                return False
            if _plain_cost(x, y, blind, sight) is None:
                return False
        return True

    def joint(a: Tracklet, b: Tracklet) -> tuple[int, float, bool] | None:
        """(-1 for a motion link, 1 for an overlap, else 0; length; whether it is short) of the joint a → b,
        or None when it is not walkable. Where b starts before a ends (by up to ``max_overlap_s``), the
        joint is b's position at a's last observation to a's there, or, where b continues a by motion from
        a's last observation before b starts, a's position there to b's start; the shorter, at most
        ``fill_distance``."""
        gap = (b.start_ns - a.end_ns) * 1e-9
        if gap <= 0.0:
            if b.start_ns <= a.start_ns or -gap > cfg.max_overlap_s:
                return None
            lengths = []
            if (
                b.hit_ns is not None
                and b.x_hit is not None
                and (k := np.searchsorted(b.hit_ns, a.end_ns)) < len(b.hit_ns)
            ):
                lengths.append(float(np.hypot(*(b.x_hit[k, :2] - a.x_end[:2]))))
            if (head := a.cut_before(b.start_ns)) is not None and _link(a, b, cfg, sight) is not None:
                lengths.append(float(np.hypot(*(b.x_start[:2] - head.x_end[:2]))))
            if not lengths or min(lengths) > cfg.fill_distance:
                return None
            return 1, min(lengths), True
        d = float(np.hypot(*(b.x_start[:2] - a.x_end[:2])))
        if d > cfg.fill_distance + cfg.max_speed * gap:
            return None
        motion = gap <= cfg.max_gap_s and _plain_cost(a, b, cfg, sight) is not None
        return -int(motion), d, d <= cfg.fill_distance + cfg.fill_speed * gap

    # the gaps of re-identifications: host (a, c) -> the tracklet its chain reaches so far
    hosts = {
        (a, c): by_id[a]
        for a, c in links
        if a in described and c in described and (by_id[c].start_ns - by_id[a].end_ns) * 1e-9 > cfg.max_gap_s
    }
    out = set(links)
    for head, tail, members, chain in free:  # in time order; each goes into the gap it continues best
        best, best_key = None, (1, np.inf)
        beside: set[int] | None = None  # the tracklets the chain keeps beside (measured once it fits a gap)
        for (a, c), cur in hosts.items():
            end = by_id[c]
            if head.start_ns <= cur.start_ns or tail.end_ns >= end.end_ns:
                continue
            fits = colours_fit(members, by_id[a], end)
            # needed only where colours do not fit
            walked = not fits and walked_through(chain, cur, end, by_id[a])
            if not (fits or walked):
                continue
            j1, j2 = joint(cur, head), joint(tail, end)
            if j1 is None or j2 is None or (j1[0] > 0 and j2[0] > 0):
                continue  # not walkable, or overlapping both ends (someone else alongside the person)
            far = max(j1[1], j2[1]) > cfg.fill_distance
            if (
                far
                and few_against(chain, by_id[a], end)
                and not (walked or walked_through(chain, cur, end, by_id[a]))
            ):
                continue  # seen elsewhere in someone else's colours
            # both joints short; or one a motion link within fill_distance and the other walkable (a walker's
            # piece that goes on from where one end is, then walks on to the other)
            close = any(j[0] < 0 and j[1] <= cfg.fill_distance for j in (j1, j2))
            if not ((j1[2] and j2[2]) or close):
                continue
            if beside is None:
                ids = set(chain)
                beside = set().union(*(_beside(by_id[m], tracklets, ids, cfg.beside_m) for m in chain))
            if beside - {a, c, cur.track_id}:
                continue  # a second track on someone else
            if (key := (j1[0] + j2[0], j1[1] + j2[1])) < best_key:
                best, best_key = (a, c), key
        if best is not None:
            cur = hosts[best]
            out.discard((cur.track_id, best[1]))
            out |= {(cur.track_id, head.track_id), (tail.track_id, best[1])}
            hosts[best] = tail
    return sorted(out)


def _beside(t: Tracklet, tracklets: list[Tracklet], chain: set[int], within_m: float) -> set[int]:
    """Ids of the tracklets (other than ``chain``'s) that ``t`` lies within ``within_m`` of, by their
    forward-filtered positions at ``t``'s observation times, at half or more of ``t``'s observations."""
    out: set[int] = set()
    if within_m <= 0 or t.hit_ns is None or t.x_hit is None or len(t.hit_ns) < 2:
        return out
    need = 0.5 * len(t.hit_ns)
    for o in tracklets:
        if o.track_id in chain or o.hit_ns is None or o.x_hit is None or len(o.hit_ns) < 2:
            continue
        inside = (t.hit_ns >= o.hit_ns[0]) & (t.hit_ns <= o.hit_ns[-1])
        if np.count_nonzero(inside) < need:
            continue
        at = t.hit_ns[inside].astype(np.float64)
        when = o.hit_ns.astype(np.float64)
        there = np.column_stack([np.interp(at, when, o.x_hit[:, 0]), np.interp(at, when, o.x_hit[:, 1])])
        if np.count_nonzero(np.hypot(*(t.x_hit[inside, :2] - there).T) <= within_m) >= need:
            out.add(o.track_id)
    return out


def link_cuts(
    tracklets: list[Tracklet],
    links: list[tuple[int, int]],
    *,
    config: StitchConfig | None = None,
    sight: Sight | None = None,
) -> dict[int, int]:
    """For the links of :func:`stitch_links` in which B continues A from an observation before A's last one
    before B starts (``tail_back_s``): B's id → the stamp of A's last observation to keep, ns."""
    cfg = config or StitchConfig()
    by_id = {t.track_id: t for t in tracklets}
    out = {}
    for a, b in links:
        link = _link(by_id[a], by_id[b], cfg, sight)
        if link is not None and link[1] is not None:
            out[b] = link[1]
    return out


def chain_links(ids: list[int], links: list[tuple[int, int]]) -> dict[int, int]:
    """Map every tracklet id to the id of the first tracklet of its chain."""
    prev = {b: a for a, b in links}
    root: dict[int, int] = {}
    for i in ids:
        r = i
        while r in prev:
            r = prev[r]
        root[i] = r
    return root
