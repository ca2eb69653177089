"""Offline tracking for labeling: what a whole recording allows and an online tracker cannot.

1. An online pass of :class:`~studio.track.ukf.UkfTracker` gives *tracklets* (which observation belongs to
   which track in which frame), including the hits a track had while still tentative.
2. Tracks that were never confirmed are dropped; the others are cut where they went unobserved for longer
   than ``split_gap_s`` (a coasting track's wide gate may have caught clutter), pieces with too few hits are
   dropped; each tracklet *claims* the observations nobody took right on its way through the frames it
   coasted, whatever their colours (``claim``: the online association turns down a person's
   camera-described detections when the track's colours are someone else's, so without them the tracklet
   shows only its first person's colours, and the stages below cannot see that it went on with another),
   and it is cut where its clothing colours change for good (:mod:`studio.track.colour_cuts`: the
   track went on with someone else); where two tracklets came close and their clothing colours say they
   came out of the encounter the other way round, their tails are exchanged (:mod:`studio.track.swaps`);
   the tracklets are filtered and RTS-smoothed on their own and then **stitched** across gaps
   (:mod:`studio.track.stitch`: motion + appearance, solved globally); a continuation takes the id of the
   tracklet it continues, and one that started before the tracklet it continues ended (its tail had left
   the person), or that continues it from an observation shortly before its last one, replaces that tail
   — unless the tail is the one that lies on the joint way, the straight line from the kept observation
   before the overlap to the continuation's first observation after it (``overlap_margin``): then the
   continuation's own first observations were someone else's, and they are given up instead.
   Where two stitched tracks come close, the detections they held there are distributed between them
   again by their motion through and after the encounter (:mod:`studio.track.encounters`); the tracks it
   changed are stitched again (a piece that held the neighbour when stitching ran may now hold the person
   whose track ended just before the encounter), and the colour repair runs once more on the stitched
   tracks: a tracklet cut by a gap just before an encounter had too few described observations on one side
   for it to judge, its stitched track has enough.
   Then a track's short excursions onto someone else's way (a few observations off its line that lie
   closer to another track) are taken from it, and so are its last (first) few observations where they
   went onto someone whose own track goes on from there (:mod:`studio.track.excursions`), and last, each
   track's gaps take the observations no track holds that lie on its way through them
   (:mod:`studio.track.fill`): a lone detection the online pass could not confirm splits a long gap into
   pieces short enough to interpolate.
3. Each final track is filtered forward over every frame of its span and **RTS-smoothed**
   (:mod:`studio.track.smooth`); frames inside short gaps get smoothed, *interpolated* positions. An
   observation that another track, unobserved in that frame, passes close by was probably one detection of
   both people (two people passing merge in the scan and in the image): it counts with its covariance
   widened by ``shared_sigma``, so the track's motion carries it past instead of the midpoint pulling it
   towards the other person.
4. Tracks shorter than ``min_track_duration_s`` or with fewer than ``min_track_hits`` observations are dropped
   (likely false positives); the rest are numbered 0, 1, 2, … in order of appearance.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field, replace

import numpy as np
from numpy.typing import NDArray

from studio.track.appearance import APPEARANCE_DIM, appearance_distance, median_appearance
from studio.track.base import Observations, TrackFrame, TrackPoint, TrackResult
from studio.track.colour_cuts import ColourCutConfig, cut_colour_changes
from studio.track.duplicates import DuplicateConfig, merge_duplicates
from studio.track.encounters import EncounterConfig, reassign_encounters
from studio.track.excursions import ExcursionConfig, detach_excursions
from studio.track.fill import GapFillConfig, fill_gaps
from studio.track.sight import Sight
from studio.track.smooth import FilterRun, filter_track, rts_smooth
from studio.track.stitch import StitchConfig, Tracklet, chain_links, link_cuts, stitch_links
from studio.track.swaps import SwapConfig, repair_swaps
from studio.track.ukf import UkfTracker, UkfTrackerConfig

__all__ = ["OfflineConfig", "join_chains", "track_offline", "tracks_from_hits"]

FloatArray = NDArray[np.float64]


@dataclass(frozen=True)
class OfflineConfig:
    """Options of :func:`track_offline`.

    Attributes:
        tracker: options of the online pass (``report_tentative`` is forced on). Its ``max_coast_s`` can be
            short: stitching bridges longer gaps with more information than the online tracker has.
        colour_cuts: options of the cuts where a tracklet's clothing colours change for good (it went on
            with someone else, :mod:`studio.track.colour_cuts`), made before the swap repair and stitching,
            or None to skip them.
        stitch: stitching options, or None to skip stitching.
        swaps: options of the identity-swap repair between tracklets that came close
            (:mod:`studio.track.swaps`), run on the tracklets and again on the stitched tracks, or None to
            skip it.
        encounters: options of the re-decision of encounters between stitched tracks by their motion
            (:mod:`studio.track.encounters`), or None to skip it.
        excursions: options of taking from the final tracks the short runs of observations that lie on
            another track's way (:mod:`studio.track.excursions`), or None to skip it.
        claim: options of giving the tracklets of the online pass, before the colour stages, the
            observations nobody took on their way through the frames they coasted (:func:`fill_gaps` with
            a tight radius, no colour test, and gaps up to 0.5 s: the default ``split_gap_s``, a
            tracklet has no longer ones, and none searched along the way), or None to skip it. Session 35
            (``docs/results.md``): simulated ``moving`` seeds 1–20, 43 → 40 identity switches, IDF1 0.946 →
            0.953; under three seeds of 5 mm noise 42.3 → 40.0 on average.
        gap_fill: options of giving the tracks' gaps the observations no track holds that lie on their way
            (:mod:`studio.track.fill`), or None to skip it.
        duplicates: options of merging the tracklets of the online pass that follow one person twice, one
            on each leg (:mod:`studio.track.duplicates`), or None to skip it.
        smooth: RTS-smooth the tracks (else the forward filter's estimates are output).
        interpolate_max_gap_s: gaps in a track up to this long (between the observations around them) get
            interpolated positions; longer gaps stay empty, seconds. The default is stitching's motion
            bridge (``StitchConfig.max_gap_s``): a gap that motion can bridge is given positions.
        interpolate_max_speed, interpolate_any_speed_s: a gap longer than ``interpolate_any_speed_s`` is
            interpolated only if the track crosses it at no more than ``interpolate_max_speed`` (m/s, a
            brisk walk): a straight path is a poor guess for a fast one, which is often a wrong link.
        split_gap_s: a track of the online pass is cut into tracklets where it went unobserved for longer
            than this, seconds (a coasting track's wide gate may have caught clutter or someone else).
        min_tracklet_hits: tracklets with fewer observations are dropped before stitching.
        min_track_duration_s: final tracks spanning less time are dropped, seconds.
        min_track_hits: final tracks with fewer observations are dropped.
        appearance_frames: how many observations at a tracklet's start / end make its appearance.
        renumber: number the final tracks 0, 1, 2, … in order of their first frame (else they keep the ids
            of the online pass, with gaps).
        shared_radius: an observation of one final track within this distance of another track's smoothed
            position, in a frame where that track has no observation, is taken for one detection of both
            people, metres (0: never).
        shared_sigma: such an observation's covariance is widened by this standard deviation, metres.
        overlap_margin: where stitching links B to A although B began before A ended, A's observations in
            the overlap are kept and B's given up when A's lie nearer, on average by more than this, to the
            straight line from A's last kept observation before the overlap to B's first one after it
            (over at most ``interpolate_max_gap_s``), metres (0: B's always win, as before session 60).
            Held-out simulated ``moving`` seed 29 (session 60, ``docs/results.md``): a tracklet that began on
            person 3's second leg beside their own track and went on with person 2 took person 2's track
            over where the two overlapped, and 1.1 s of person 2 came out on person 3; two switches.
        correlation_s: observations' errors stay correlated for about this long, seconds (a leg pair's
            centre moves with the gait, a person's blob keeps the same part hidden): where the frames come
            faster than one per ``correlation_s``, every observation's covariance is widened by
            ``correlation_s`` over the median time between frames, so that a second of observations
            weighs about as much at any frame rate (0: observations are independent at any rate), and an
            excursion (``ExcursionConfig.max_hits``) may hold as many times more hits. See
            :data:`studio.pipeline.base.PIPELINE_TRACKING`.
    """

    tracker: UkfTrackerConfig = field(default_factory=lambda: UkfTrackerConfig(max_coast_s=1.0))
    colour_cuts: ColourCutConfig | None = field(default_factory=ColourCutConfig)
    stitch: StitchConfig | None = field(default_factory=StitchConfig)
    swaps: SwapConfig | None = field(default_factory=SwapConfig)
    encounters: EncounterConfig | None = field(default_factory=EncounterConfig)
    excursions: ExcursionConfig | None = field(default_factory=ExcursionConfig)
    claim: GapFillConfig | None = field(
        default_factory=lambda: GapFillConfig(
            radius=0.25, max_gap_s=0.5, max_appearance=math.inf, path_max_gap_s=0.0
        )
    )
    gap_fill: GapFillConfig | None = field(default_factory=GapFillConfig)
    duplicates: DuplicateConfig | None = field(default_factory=DuplicateConfig)
    smooth: bool = True
    interpolate_max_gap_s: float = 3.0
    interpolate_max_speed: float = 1.5
    interpolate_any_speed_s: float = 1.0
    split_gap_s: float = 0.5
    min_tracklet_hits: int = 3
    min_track_duration_s: float = 0.5
    min_track_hits: int = 5
    appearance_frames: int = 10
    renumber: bool = True
    shared_radius: float = 0.6
    shared_sigma: float = 0.3
    overlap_margin: float = 0.15
    correlation_s: float = 0.0

    def __post_init__(self) -> None:
        if (
            self.interpolate_max_gap_s < 0
            or self.interpolate_any_speed_s < 0
            or self.interpolate_max_speed <= 0
        ):
            raise ValueError(
                "interpolate_max_gap_s and interpolate_any_speed_s must be non-negative, "
                "interpolate_max_speed positive"
            )
        if min(self.shared_radius, self.shared_sigma, self.overlap_margin, self.correlation_s) < 0:
            raise ValueError(
                "shared_radius, shared_sigma, overlap_margin and correlation_s must be non-negative"
            )


# A track's hits: (frame index, row in that frame's Observations), in frame order.
_Hits = list[tuple[int, int]]


def _online_pass(obs: Sequence[Observations], cfg: OfflineConfig) -> dict[int, _Hits]:
    tracker = UkfTracker(config=replace(cfg.tracker, report_tentative=True))
    hits: dict[int, _Hits] = {}
    confirmed: set[int] = set()
    for i, o in enumerate(obs):
        row_of = {int(d): r for r, d in enumerate(o.det_index)}
        for e in tracker.step(o):
            if e.det_index >= 0:
                hits.setdefault(e.track_id, []).append((i, row_of[e.det_index]))
            if e.state == "confirmed":
                confirmed.add(e.track_id)
    # Split where a track went unobserved for long (a coasting track's wide gate may have caught clutter or
    # another person there); stitching re-joins the pieces that belong together.
    out: dict[int, _Hits] = {}
    next_id = max(hits, default=-1) + 1
    for tid in sorted(hits):
        if tid not in confirmed:
            continue
        h = hits[tid]
        pieces: list[_Hits] = [[h[0]]]
        for prev, cur in itertools.pairwise(h):
            if (obs[cur[0]].stamp_ns - obs[prev[0]].stamp_ns) * 1e-9 > cfg.split_gap_s:
                pieces.append([])
            pieces[-1].append(cur)
        for n, piece in enumerate(pieces):
            if len(piece) >= max(1, cfg.min_tracklet_hits):
                out[tid if n == 0 else next_id] = piece
                next_id += n > 0
    return out


def _run(
    obs: Sequence[Observations],
    hits: _Hits,
    cfg: OfflineConfig,
    shared: frozenset[tuple[int, int]] = frozenset(),
) -> FilterRun:
    first, last = hits[0][0], hits[-1][0]
    K = last - first + 1
    stamps = np.array([obs[i].stamp_ns for i in range(first, last + 1)], dtype=np.int64)
    z = np.full((K, 2), np.nan)
    R = np.tile(np.eye(2), (K, 1, 1))
    dt = np.zeros(K)
    for i, r in hits:
        z[i - first] = obs[i].xy[r]
        R[i - first] = obs[i].cov[r]
        if obs[i].dt_s is not None:
            dt[i - first] = obs[i].dt_s[r]  # type: ignore[index]
        if (i, r) in shared:
            R[i - first] = R[i - first] + cfg.shared_sigma**2 * np.eye(2)
    t = cfg.tracker
    return filter_track(
        stamps, z, R, accel_sigma=t.accel_sigma, init_speed_sigma=t.init_speed_sigma, measured_dt=dt
    )


# an image-only observation's colours count for its track when within this of its fused ones' median, ΔE
_IMAGE_ONLY_AGREE = 10.0


def _descriptors(obs: Sequence[Observations], hits: _Hits) -> NDArray[np.float32]:
    """(M, D) appearance descriptors of a track's observations that have one.

    Where the track has fused observations with colours, those of its image-only observations count only
    when they lie within ``_IMAGE_ONLY_AGREE`` of the fused ones' median. An image-only position comes from
    the box's foot row, whose range is loose far away, so the tracker may give it to someone else on the
    box's bearing: on simulated ``moving`` seeds 1-10 and 23, 16 % of the image-only observations' colours
    were more than 15 ΔE from their person's own (9 % nearer someone else's), against 1.9 % (0.8 %) of the
    fused ones. Dropping them all cost the low-cost-lidar rig (1° beams, more image-only positions) three
    switches on seeds 1-8 (session 56, ``docs/results.md``)."""
    rows = [
        (obs[i].appearance[r], obs[i].source[r] == "image")  # type: ignore[index]
        for i, r in hits
        if obs[i].appearance is not None
    ]
    rows = [(a, img) for a, img in rows if np.all(np.isfinite(a))]
    own = [a for a, img in rows if not img]
    ref = median_appearance(np.array(own, np.float32)) if own and len(own) < len(rows) else None
    if ref is not None:
        rows = [(a, img) for a, img in rows if not img or appearance_distance(a, ref) <= _IMAGE_ONLY_AGREE]
    return np.array([a for a, _ in rows], np.float32).reshape(len(rows), APPEARANCE_DIM)


_Cache = dict[tuple[tuple[int, int], ...], tuple[FilterRun, FloatArray, FloatArray]]


def _estimate(
    obs: Sequence[Observations], hits: _Hits, cfg: OfflineConfig, cache: _Cache
) -> tuple[FilterRun, FloatArray, FloatArray]:
    """Forward run and smoothed states of a track, computed once per set of hits."""
    key = tuple(hits)
    if key not in cache:
        run = _run(obs, hits, cfg)
        cache[key] = (run, *rts_smooth(run))
    return cache[key]


def _tracklet(
    tid: int, obs: Sequence[Observations], hits: _Hits, cfg: OfflineConfig, cache: _Cache
) -> Tracklet:
    run, x, P = _estimate(obs, hits, cfg, cache)
    n = max(1, cfg.appearance_frames)
    desc = _descriptors(obs, hits)
    at = np.array([i for i, _ in hits]) - hits[0][0]
    return Tracklet(
        tid,
        int(run.stamps_ns[0]),
        int(run.stamps_ns[-1]),
        x[0],
        P[0],
        x[-1],
        P[-1],
        median_appearance(desc[:n]) if len(desc) else None,
        median_appearance(desc[-n:]) if len(desc) else None,
        median_appearance(desc) if len(desc) else None,
        len(desc),
        run.stamps_ns[at],
        run.x[at],
        run.P[at],
    )


def _points(
    tid: int,
    obs: Sequence[Observations],
    hits: _Hits,
    cfg: OfflineConfig,
    cache: _Cache,
    shared: frozenset[tuple[int, int]] = frozenset(),
) -> list[tuple[int, TrackPoint]]:
    if shared:
        run = _run(obs, hits, cfg, shared)
        xs, Ps = rts_smooth(run)
    else:
        run, xs, Ps = _estimate(obs, hits, cfg, cache)
    x, P = (xs, Ps) if cfg.smooth else (run.x, run.P)
    first = hits[0][0]
    det_of = {i: int(obs[i].det_index[r]) for i, r in hits}
    hit_frames = [i for i, _ in hits]
    out = []
    for a, b in itertools.pairwise(hit_frames):
        out.append((a, det_of[a]))
        gap = (obs[b].stamp_ns - obs[a].stamp_ns) * 1e-9
        if b > a + 1 and gap <= cfg.interpolate_max_gap_s:
            step = float(np.hypot(*(x[b - first, :2] - x[a - first, :2])))
            if gap <= cfg.interpolate_any_speed_s or step <= cfg.interpolate_max_speed * gap:
                out.extend((i, -1) for i in range(a + 1, b))
    out.append((hit_frames[-1], det_of[hit_frames[-1]]))
    return [
        (
            i,
            TrackPoint(
                tid,
                x[i - first, :2],
                P[i - first, :2, :2],
                det,
                smoothed=cfg.smooth,
                interpolated=det < 0,
                vxy=x[i - first, 2:],
            ),
        )
        for i, det in out
    ]


def _shared_hits(
    obs: Sequence[Observations], tracks: list[_Hits], cfg: OfflineConfig, cache: _Cache
) -> list[frozenset[tuple[int, int]]]:
    """Per track, its hits that were probably one detection of two people: in a frame where another
    track has no observation but its smoothed position lies within ``shared_radius`` of the hit."""
    if cfg.shared_radius <= 0 or len(tracks) < 2:
        return [frozenset() for _ in tracks]
    pos = []
    for h in tracks:
        _, x, _ = _estimate(obs, h, cfg, cache)
        pos.append((h[0][0], x[:, :2], {i for i, _ in h}))
    out = []
    for a, h in enumerate(tracks):
        marked = set()
        for i, r in h:
            z = obs[i].xy[r]
            for b, (first, xb, held) in enumerate(pos):
                if b == a or i in held or not first <= i < first + len(xb):
                    continue
                if float(np.hypot(*(xb[i - first] - z))) < cfg.shared_radius:
                    marked.add((i, r))
                    break
        out.append(frozenset(marked))
    return out


def _for_rate(obs: list[Observations], cfg: OfflineConfig) -> tuple[list[Observations], OfflineConfig]:
    """The observations and options for the frames' rate (``OfflineConfig.correlation_s``): with ``n``
    frames within ``correlation_s`` (``correlation_s`` over the median time between frames), where ``n``
    is more than 1 % over 1, every covariance widened by ``n`` and an excursion's longest run ``n`` times as
    many hits; else as they are."""
    steps = np.diff(np.array([o.stamp_ns for o in obs], dtype=np.float64))
    steps = steps[steps > 0]
    if cfg.correlation_s <= 0 or not len(steps):
        return obs, cfg
    n = cfg.correlation_s / (float(np.median(steps)) * 1e-9)
    if n <= 1.01:
        return obs, cfg
    if cfg.excursions is not None:
        cfg = replace(cfg, excursions=replace(cfg.excursions, max_hits=round(cfg.excursions.max_hits * n)))
    return [replace(o, cov=o.cov * n) for o in obs], cfg


def track_offline(
    observations: Sequence[Observations],
    *,
    config: OfflineConfig | None = None,
    on_stage: Callable[[str, dict[int, _Hits]], None] | None = None,
) -> TrackResult:
    """Track people over a whole recording, using past and future observations.

    Args:
        observations: one :class:`Observations` per frame (in the odom frame for our method), stamps
            non-decreasing. Frames without people are empty observations, not left out.
        config: options.
        on_stage: called after each stage with its name and the tracks' hits (id → ``(frame index, row)``
            in frame order; ids are the stage's own, not the output's): what each stage did, for tracing
            a wrong identity to the stage that made it (``bench/trace_tracking.py``). It must not modify
            the hits.

    Returns:
        One :class:`~studio.track.base.TrackFrame` per input frame; points are smoothed (unless disabled)
        and points in bridged gaps are flagged ``interpolated`` with ``det_index = -1``.

    Raises:
        TrackingError: stamps decrease.
    """
    obs, cfg = _for_rate(list(observations), config or OfflineConfig())
    trace = on_stage or (lambda _name, _tracks: None)
    tracklets = _online_pass(obs, cfg)
    trace("online", tracklets)
    if cfg.duplicates is not None:
        tracklets, _ = merge_duplicates(obs, tracklets, cfg.duplicates)
        trace("duplicates", tracklets)
    if cfg.claim is not None:
        tracklets, _ = fill_gaps(obs, tracklets, cfg.claim)
        trace("claim", tracklets)
    colour_cut_pairs: list[tuple[int, int]] = []
    if cfg.colour_cuts is not None:
        tracklets, colour_cut_pairs = cut_colour_changes(obs, tracklets, cfg.colour_cuts)
        trace("colour_cuts", tracklets)
    if cfg.swaps is not None:
        tracklets, _ = repair_swaps(obs, tracklets, cfg.swaps)
        trace("swaps", tracklets)
    cache: _Cache = {}
    sight = Sight([o.stamp_ns for o in obs], [o.view for o in obs])
    if cfg.stitch is not None and len(tracklets) > 1:
        merged = _stitch(obs, tracklets, colour_cut_pairs, sight, cfg, cache)
    else:
        merged = join_chains(obs, tracklets, {tid: tid for tid in tracklets}, {}, cfg)
    trace("stitch", merged)
    if cfg.encounters is not None and len(merged) > 1:

        def estimate(h: _Hits) -> tuple[FloatArray, FloatArray, FloatArray]:
            run, x, _ = _estimate(obs, h, cfg, cache)
            return run.x, run.P, x

        before = merged
        merged, _ = reassign_encounters(
            obs, merged, estimate, accel_sigma=cfg.tracker.accel_sigma, config=cfg.encounters
        )
        trace("encounters", merged)
        if cfg.stitch is not None:
            # the tracks the re-decision changed are stitched again (a piece that held the neighbour when
            # stitching ran may now hold the person whose track ended just before the encounter)
            changed = {tid for tid, h in merged.items() if h != before.get(tid)}
            merged = _stitch(obs, merged, colour_cut_pairs, sight, cfg, cache, among=changed)
            trace("stitch again", merged)
    if cfg.duplicates is not None and len(merged) > 1:
        merged, _ = merge_duplicates(obs, merged, cfg.duplicates)
        trace("duplicates again", merged)
    if cfg.swaps is not None and len(merged) > 1:
        merged, _ = repair_swaps(obs, merged, cfg.swaps)
        trace("swaps again", merged)
    if cfg.excursions is not None:
        merged, _ = detach_excursions(obs, merged, cfg.excursions)
        trace("excursions", merged)
    if cfg.gap_fill is not None:
        merged, _ = fill_gaps(obs, merged, cfg.gap_fill)
        trace("gap_fill", merged)
    return _output(obs, merged, cfg, cache)


def _stitch(
    obs: Sequence[Observations],
    tracks: dict[int, _Hits],
    cut: list[tuple[int, int]],
    sight: Sight,
    cfg: OfflineConfig,
    cache: _Cache,
    among: set[int] | None = None,
) -> dict[int, _Hits]:
    """The tracks joined by the links of :func:`stitch_links`; with ``among``, only by those with an end in
    it, and the tracks as they were when there is none. Stitching again the tracks the encounter
    re-decision changed: simulated ``moving`` seed 61 (session 77, ``docs/results.md``), where the online
    pass swapped person 5 and a neighbour in an encounter and a colour cut ended person 5's track 0.4 s
    before it; the re-decision gave person 5's detections after the encounter to the piece the cut had left
    on the neighbour, and that piece came out as a track of its own."""
    assert cfg.stitch is not None
    if among is not None and not among:
        return tracks
    summaries = [_tracklet(tid, obs, h, cfg, cache) for tid, h in tracks.items()]
    links = stitch_links(summaries, config=cfg.stitch, cut=cut, sight=sight)
    if among is not None:
        links = [(a, b) for a, b in links if a in among or b in among]
        if not links:
            return tracks
    root = chain_links(list(tracks), links)
    cuts = link_cuts(summaries, links, config=cfg.stitch, sight=sight)
    return join_chains(obs, tracks, root, cuts, cfg)


def join_chains(
    obs: Sequence[Observations],
    tracklets: dict[int, _Hits],
    root: dict[int, int],
    cuts: dict[int, int],
    cfg: OfflineConfig,
) -> dict[int, _Hits]:
    """The hits of each stitched chain (keyed by its first tracklet's id, ``root``), its tracklets joined in
    order of their start. One that starts before the previous one ended takes over from there, or from
    where stitching cut the previous one (``cuts``: tracklet id → stamp of the previous one's last hit to
    keep, :func:`~studio.track.stitch.link_cuts`), and the previous one's tail is given up — unless that tail
    is the one on the joint way (``overlap_margin``): then the new one's hits up to the tail's end are."""
    merged: dict[int, _Hits] = {}
    for tid, h in sorted(tracklets.items(), key=lambda kv: kv[1][0][0]):
        chain = merged.setdefault(root[tid], [])
        cut = cuts.get(tid)
        kept = [x for x in chain if x[0] < h[0][0] and (cut is None or obs[x[0]].stamp_ns <= cut)]
        after = [x for x in h if chain and x[0] > chain[-1][0]]
        if _tail_on_the_way(obs, kept, chain[len(kept) :], h[: len(h) - len(after)], after, cfg):
            chain[:] = chain + after
        else:
            chain[:] = kept + h
    return merged


def _tail_on_the_way(
    obs: Sequence[Observations], kept: _Hits, tail: _Hits, head: _Hits, after: _Hits, cfg: OfflineConfig
) -> bool:
    """Whether, where B (``head`` + ``after``) continues A (``kept`` + ``tail``) from within A, A's ``tail``
    rather than B's ``head`` (the hits of the overlap) lies on the joint way: the straight line from A's
    last kept hit to B's first hit ``after`` A's end, nearer on average by more than ``overlap_margin``."""
    if cfg.overlap_margin <= 0 or not (kept and tail and head and after):
        return False
    (i0, r0), (i1, r1) = kept[-1], after[0]
    t0, t1 = obs[i0].stamp_ns, obs[i1].stamp_ns
    if (t1 - t0) * 1e-9 > cfg.interpolate_max_gap_s:
        return False
    p0, p1 = obs[i0].xy[r0], obs[i1].xy[r1]

    def off_the_way(hits: _Hits) -> float:
        w = np.array([(obs[i].stamp_ns - t0) / (t1 - t0) for i, _ in hits])[:, None]
        xy = np.array([obs[i].xy[r] for i, r in hits], dtype=np.float64)
        return float(np.mean(np.hypot(*(xy - ((1.0 - w) * p0 + w * p1)).T)))

    return off_the_way(tail) + cfg.overlap_margin < off_the_way(head)


def tracks_from_hits(
    observations: Sequence[Observations],
    tracks: dict[int, list[tuple[int, int]]],
    *,
    config: OfflineConfig | None = None,
) -> TrackResult:
    """Stage 3 and 4 of :func:`track_offline` alone: smooth, interpolate, filter and number tracks whose
    observations were assigned by someone else.

    It serves tools that compare association methods on the same observations (``bench/replay_tracking.py
    --oracle`` assigns them by ground truth).

    Args:
        observations: one :class:`Observations` per frame, as for :func:`track_offline`.
        tracks: track id → its hits ``(frame index, row in that frame's observations)``, one per frame at
            most; the lists are not modified.
        config: options (only the smoothing, interpolation, shared-observation, minimum-track and
            ``correlation_s`` ones are used).

    Raises:
        ValueError: a hit names a frame or row that does not exist, or two hits of one track share a frame.
    """
    obs, cfg = _for_rate(list(observations), config or OfflineConfig())
    out: dict[int, _Hits] = {}
    for tid, h in tracks.items():
        hits = sorted((int(i), int(r)) for i, r in h)
        frames = [i for i, _ in hits]
        if any(not (0 <= i < len(obs) and 0 <= r < len(obs[i].xy)) for i, r in hits):
            raise ValueError(f"track {tid} has a hit outside the observations")
        if len(set(frames)) != len(frames):
            raise ValueError(f"track {tid} has two hits in one frame")
        if hits:
            out[tid] = hits
    return _output(obs, out, cfg, {})


def _output(
    obs: list[Observations], tracks: dict[int, _Hits], cfg: OfflineConfig, cache: _Cache
) -> TrackResult:
    """Per-frame smoothed (and interpolated) points of the tracks long enough to keep, numbered."""
    kept = []
    for tid, h in tracks.items():
        h.sort()
        duration_s = (obs[h[-1][0]].stamp_ns - obs[h[0][0]].stamp_ns) * 1e-9
        if len(h) >= cfg.min_track_hits and duration_s >= cfg.min_track_duration_s:
            kept.append((h[0][0], tid, h))
    kept.sort()
    shared = _shared_hits(obs, [h for _, _, h in kept], cfg, cache)
    per_frame: list[list[TrackPoint]] = [[] for _ in obs]
    for n, (_, tid, h) in enumerate(kept):
        for i, p in _points(n if cfg.renumber else tid, obs, h, cfg, cache, shared[n]):
            per_frame[i].append(p)
    return TrackResult(tuple(TrackFrame(o.stamp_ns, tuple(p)) for o, p in zip(obs, per_frame, strict=True)))
