"""``studio label``: recording + rig → people's positions with identities in every frame.

Two passes. The first (:mod:`studio.pipeline.perceive`) streams the recording once and keeps per frame
the image and laser detections and the scan points, and builds the static-world map in the odom frame.
The second fuses, tracks in the odom frame (UKF + GNN, RTS smoothing, tracklet stitching) and returns
labels.
"""

from __future__ import annotations

import bisect
import time
from collections import Counter
from collections.abc import Callable
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from studio.detect.laser.base import KIND_BLOB, KIND_PAIR, LaserDetections
from studio.detect.laser.classical import ClassicalLaserDetector
from studio.errors import StudioError
from studio.fuse.base import PersonObservations, ScanRays
from studio.fuse.fusion import colours_hidden, fuse_frame
from studio.geometry import EquirectCamera
from studio.labels.base import LabelFrame, LabelPerson, as_box
from studio.pipeline.base import FrameResult, LabelOptions
from studio.pipeline.perceive import (
    PerceptionFrame,
    base_scans,
    detect_again,
    odom_scans,
    perceive,
    point_times,
    rig_camera,
)
from studio.track.appearance import APPEARANCE_DIM
from studio.track.sight import ScanView

__all__ = ["LabelRun", "PerceptionFrame", "label_recording", "perceive"]

FloatArray = NDArray[np.float64]
_STATIC_OCCUPIED = 0.7  # a cell is structure when it was hit in this share of the scans that saw it
_BODY_HIT_SHARE = 0.8  # a base-frame cell hit by this share of one scanner's scans is the robot's body ...
_BODY_MIN_SCANS = 20  # ... judged once that scanner has this many scans in its map
_SEGMENT_SHARE = 0.7  # a detection is on structure / the body when this share of its points is
_VOUCH_S, _VOUCH_M = 0.5, 0.3  # a box-confirmed laser person vouches for static detections this near
_CAMERA_SEEN_M = 0.3  # a camera observation no track took vouches for a track this near (camera gate)
# without the camera, the walk of a track counts only its observations on places that the static map saw
# occupied in less than this share of the scans that looked at them, or saw change while the scanner stood
# still (StaticMap.changed_at): furniture that a moving robot's beams graze from some places and hit from
# others looks half occupied (0.3–0.6 on leg_tracker's negative_2.bag), a walker's path through a room it
# crossed 0.0–0.2; a track hopping between chair legs then walked nowhere
_WALK_OCCUPIED = 0.3
_WALK_GAP_S, _WALK_MEDIAN = 0.5, 5  # a stretch of a track (min_walk_m) ends at a gap this long, s; smoothing
_CAMERA_TAIL_BACK_S = 1.0  # with a camera, stitching's take-over looks back this far (see tracking_config)
# leg pairs on spots seen empty (_pairs_on_empty): the classical detector's leg threshold there, and the
# distance (m) from the detections it already made that they must keep
_EMPTY_LEG_SCORE, _EMPTY_APART_M = 0.1, 0.8
_PAIR_ON_STRUCTURE, _PAIR_SPREAD = 0.2, 0.35  # a leg pair with this share of its points on structure, ...
# ... that far (m) from its other points, paired a leg with a chair leg or a corner


@dataclass
class LabelRun:
    """Everything ``studio label`` produces, in memory."""

    labels: list[LabelFrame]
    detections: list[FrameResult]
    image_size: tuple[int, int] | None
    camera: EquirectCamera | None
    timings_s: dict[str, float] = field(default_factory=dict)
    counts: dict[str, Any] = field(default_factory=dict)
    notes: list[str] = field(default_factory=list)
    image_detections: list[tuple[int, int, Any]] = field(default_factory=list)
    """``(frame, stamp_ns, ImageDetections)`` for every frame the image detector ran on."""


def _static_masks(
    frames: list[PerceptionFrame], static_map: Any | None = None, body_maps: list[Any] | None = None
) -> tuple[list[NDArray[np.bool_]], list[NDArray[np.bool_]]]:
    """Per frame: which laser detections and which scan points lie on never-moving structure or on the
    robot's own body.

    ``static_map``, ``body_maps``: the map of the frames' scans in the world frame and one map per scanner
    of its scans in the base frame, when they were built already (by :func:`perceive`)."""
    from studio.detect.laser.static_map import StaticMap

    smap = static_map
    if smap is None:
        smap = StaticMap.build(s for f in frames for s in odom_scans(f))
    bodies = body_maps
    if bodies is None:
        n = max((len(f.origins) for f in frames), default=0)
        bodies = [
            StaticMap.build(
                (list(base_scans(f))[k] for f in frames if len(f.origins) > k),
                max_free_range=0.0,
                steady_scans=0,
            )
            for k in range(n)
        ]
    det_static, pt_static = [], []
    for f in frames:
        base = f.points[:, :2].astype(np.float64)
        pts_world = f.world_pose.apply(base)  # NaN rows stay NaN
        # the robot's body: what a scanner hits in most of its own scans, in the base frame
        body = np.zeros(len(base), bool)
        for k, m in enumerate(bodies):
            if m.n_scans >= _BODY_MIN_SCANS:
                sel = f.origin_of_point == k
                body[sel] = m.hit_fraction(base[sel]) >= _BODY_HIT_SHARE
        pt_static.append(smap.structure(pts_world, occupied=_STATIC_OCCUPIED) | body)
        if f.laser is not None and len(f.laser.xy):
            ds = smap.is_static(f.laser, pts_world, occupied=_STATIC_OCCUPIED, min_share=_SEGMENT_SHARE)
            if body.any() and f.laser.segments is not None:
                on_body = [len(g) > 0 and float(np.mean(body[g])) >= _SEGMENT_SHARE for g in f.laser.segments]
                ds |= np.array(on_body)
            det_static.append(ds)
        else:
            det_static.append(np.zeros(0 if f.laser is None else len(f.laser.xy), dtype=bool))
    return det_static, pt_static


def fuse_all(
    frames: list[PerceptionFrame],
    camera: EquirectCamera | None,
    options: LabelOptions,
    *,
    static_map: Any | None = None,
    body_maps: list[Any] | None = None,
) -> list[FrameResult]:
    """Static filter + fusion of every frame (base frame); the maps as :func:`_static_masks`."""
    laser_only = camera is None or options.sources == "laser"
    # how occupied the places of the observations are: for the walk gate (laser only) and, with the
    # camera, for the walking stretches that count as the camera's support (see track_all)
    walks = options.min_walk_m > 0
    # camera-only runs use neither laser detections nor scan points: no map to build
    smap = None
    if options.static_filter and options.sources != "camera" and any(len(f.points) for f in frames):
        from studio.detect.laser.static_map import StaticMap

        # (where it changed while a scanner stood still only matters to the walk gate: see perceive)
        scans = (s for f in frames for s in odom_scans(f))
        smap = static_map or StaticMap.build(scans, steady_scans=3 if laser_only else 0)
        det_static, pt_static = _static_masks(frames, smap, body_maps)
    else:
        det_static = [np.zeros(0 if f.laser is None else len(f.laser.xy), bool) for f in frames]
        pt_static = [np.zeros(len(f.points), bool) for f in frames]
    # Image frames first: a static laser detection on a frame without an image is dropped unless a box
    # took a static laser detection at that place on an image frame within ``_VOUCH_S`` (someone standing
    # still on a spot the laser never saw free looks static). Only a static one: a box on someone walking
    # past a chair leg says nothing of the chair leg (session 36: simulated ``moving`` seed 18, such a
    # chair leg kept on the frames between images made a second track beside the walker, two switches).
    out: list[FrameResult | None] = [None] * len(frames)
    vouch_ns: list[int] = []
    vouch_xy: list[FloatArray] = []
    detector = None
    # without the camera, the classical detector with the lower leg threshold of spots seen empty
    on_empty = None
    if laser_only and smap is not None and (options.laser_detector or "classical") == "classical":
        from studio.detect.laser import get_laser_detector

        on_empty = get_laser_detector("classical", leg_min_score=_EMPTY_LEG_SCORE)
    for i in sorted(range(len(frames)), key=lambda k: frames[k].image is None):
        f, ds, ps = frames[i], det_static[i], pt_static[i]
        laser = f.laser
        laser_z: FloatArray = f.laser_z
        # A leg paired with a chair leg or a wall corner sits between the two: the laser detector runs
        # again on that frame without those structure points (only theirs: a still person stays).
        if laser is not None and laser.segments is not None and ps.any():
            mixed = [
                k
                for k, g in enumerate(laser.segments)
                if laser.kind[k] == KIND_PAIR and not ds[k] and _leg_on_structure(f.points[g, :2], ps[g])
            ]
            if mixed:
                if detector is None:
                    from studio.detect.laser import get_laser_detector

                    detector = get_laser_detector(options.laser_detector or "classical")
                drop = np.zeros(len(ps), bool)
                for k in mixed:
                    g = laser.segments[k]
                    drop[g] = ps[g]
                laser, laser_z = detect_again(f, detector, drop)
                segs = laser.segments
                ds = (
                    np.array([len(g) > 0 and float(ps[g].mean()) >= _SEGMENT_SHARE for g in segs], bool)
                    if segs is not None
                    else np.zeros(len(laser.xy), bool)
                )
        if on_empty is not None and smap is not None and laser is not None and laser.segments is not None:
            laser, laser_z, ds = _pairs_on_empty(f, laser, laser_z, ds, smap, on_empty)
        if laser is not None and ds.any() and f.image is None:
            keep = ~ds | _vouched(f, laser.xy, vouch_ns, vouch_xy)
            laser = laser.select(np.flatnonzero(keep))
            laser_z = laser_z[keep]
            ds = np.zeros(len(laser_z), bool)
        pts, rays, pts_occ = None, None, None
        # each scan point's share of occupied looks in the static map (walk gate, walking stretches)
        share = (
            smap.walk_share(f.world_pose.apply(f.points[:, :2].astype(np.float64)))
            if walks and smap is not None
            else None
        )
        if options.sources != "camera" and len(f.points):
            hit = np.isfinite(f.points[:, 0])
            kept = np.flatnonzero(hit & ~ps)
            pts = np.c_[f.points[kept], f.points_z(kept)]
            rays = ScanRays(f.origins[f.origin_of_point[hit]], f.points[hit, :2].astype(np.float64))
            if share is not None:
                pts_occ = share[kept]
        obs = fuse_frame(
            f.image,
            laser,
            camera=camera,
            laser_z=laser_z,
            scan_points=pts,
            laser_static=ds if laser is not None else None,
            rays=rays,
            config=options.fusion,
        )
        if f.image is not None:
            vouch_ns.append(f.stamp_ns)
            took = np.asarray(obs.laser_index)[np.asarray(obs.source) == "fused"]
            took = took[took >= 0]
            places = laser.xy[took[ds[took]]] if laser is not None else np.zeros((0, 2))
            vouch_xy.append(f.world_pose.apply(places))
        out[i] = FrameResult(
            f.index,
            f.stamp_ns,
            f.robot_pose,
            obs,
            None if pts is None else pts.astype(np.float32),
            f.track_pose,
            _pair_legs(obs, laser),
            None if camera is None else colours_hidden(obs, camera),
            _measured_at(obs, f),
            None if share is None else _occupied(obs, laser, share),
            None if pts_occ is None else pts_occ.astype(np.float16),
        )
    return [r for r in out if r is not None]


def _occupied(obs: PersonObservations, laser: LaserDetections | None, share: FloatArray) -> FloatArray:
    """Per observation, how occupied the static map saw the place of its laser detection: the median over
    its beams of ``share``, each scan point's (``StaticMap.walk_share``); NaN without a laser detection."""
    out = np.full(len(obs), np.nan)
    if laser is None or laser.segments is None:
        return out
    for k, li in enumerate(np.asarray(obs.laser_index)):
        if 0 <= li < len(laser.segments) and len(laser.segments[li]):
            out[k] = float(np.median(share[laser.segments[li]]))
    return out


_PERSON_BEAMS_M = 0.35  # a person's beams lie within this of their position (legs apart, a wide coat)


def _measured_at(obs: PersonObservations, f: PerceptionFrame) -> FloatArray | None:
    """When each observation was measured, seconds after the frame stamp: the mean time of the beams
    within :data:`_PERSON_BEAMS_M` of a laser position (their scan, and where in its sweep), 0 for an
    image-only one or where no beam lies near; None when the frame's beams carry no times."""
    times = point_times(f)
    if times is None or not len(obs):
        return None
    out = np.zeros(len(obs))
    hit = np.isfinite(f.points[:, 0])
    pts, dt = f.points[hit, :2].astype(np.float64), times[hit]
    if not len(pts):
        return out
    for k in np.flatnonzero(np.asarray(obs.source) != "image"):
        near = np.hypot(pts[:, 0] - obs.xy[k, 0], pts[:, 1] - obs.xy[k, 1]) <= _PERSON_BEAMS_M
        if near.any():
            out[k] = float(dt[near].mean())
    return out


def _pairs_on_empty(
    f: PerceptionFrame,
    laser: LaserDetections,
    laser_z: FloatArray,
    static: NDArray[np.bool_],
    smap: Any,
    detector: Any,
) -> tuple[LaserDetections, FloatArray, NDArray[np.bool_]]:
    """The frame's detections, plus the people ``detector`` finds among the returns that no detection holds
    and that lie on spots the robot saw empty at other times (:meth:`StaticMap.seen_empty`).

    The leg model scores a leg low when something stands less than a metre behind it (its ``occlusion``
    features: chair and table legs stand by walls), so someone standing by a wall or a cupboard goes
    unseen, though the same spot was empty before they came or after they left. Structure is never seen
    empty: those returns go to ``detector`` alone, without the structure behind them, and its leg pairs
    and blobs (two legs side by side merge into one) are taken; single legs are not, as a lone return on a
    spot seen empty is as often something moving with the robot or a stray beam. Only those more than
    ``_EMPTY_APART_M`` from every detection already made: beside someone, a weak pair is as often a second
    reading of a group, and the people in it are then exchanged (laser-only `moving` seeds 1–20: 97
    switches at 0.8 m, 94–97 from 0.6 to 1.2 m, 111 at 0.3 m, 104 without the rule). A robot that never
    moves never sees a spot empty: nothing changes there.
    """
    free = smap.seen_empty(f.world_pose.apply(f.points[:, :2].astype(np.float64)))
    if laser.segments is not None:
        for g in laser.segments:
            free[g] = False
    if np.count_nonzero(free) < 2 * detector.segment.min_points:
        return laser, laser_z, static
    extra, z = detect_again(f, detector, ~free)
    new = (extra.kind == KIND_PAIR) | (extra.kind == KIND_BLOB)
    if len(laser) and len(extra):
        gap = np.hypot(*(extra.xy[:, None, :] - laser.xy[None, :, :]).transpose(2, 0, 1))
        new &= gap.min(axis=1) > _EMPTY_APART_M
    if not new.any():
        return laser, laser_z, static
    added = np.zeros(int(new.sum()), bool)
    return laser.then(extra.select(new)), np.r_[laser_z, z[new]], np.r_[static, added]


def _pair_legs(obs: PersonObservations, laser: LaserDetections | None) -> FloatArray | None:
    """Per observation the two legs of the laser leg pair it was made from (NaN rows for the others)."""
    if laser is None or laser.legs is None:
        return None
    out = np.full((len(obs), 2, 2), np.nan)
    li = obs.laser_index  # -1 for image-only and scan-cluster positions
    out[li >= 0] = laser.legs[li[li >= 0]]
    return out


def _leg_on_structure(points: NDArray[np.float32], static: NDArray[np.bool_]) -> bool:
    """Whether a leg pair's points (``(K, 2)``, which of them lie on structure) are a leg and a piece of
    structure: a share of them on structure, away from the rest by more than a stance."""
    if not len(static) or static.mean() < _PAIR_ON_STRUCTURE or static.all():
        return False
    sep = np.hypot(*(points[static].mean(axis=0) - points[~static].mean(axis=0)))
    return bool(sep >= _PAIR_SPREAD)


def _vouched(
    f: PerceptionFrame, xy: FloatArray, stamps: list[int], places: list[FloatArray]
) -> NDArray[np.bool_]:
    """Which of ``xy`` (base frame) lie within ``_VOUCH_M`` of a box-confirmed static laser person of an image
    frame within ``_VOUCH_S`` of ``f`` (``stamps`` sorted, ``places`` their positions in the world frame)."""
    out = np.zeros(len(xy), bool)
    if not stamps or not len(xy):
        return out
    lo = bisect.bisect_left(stamps, f.stamp_ns - int(_VOUCH_S * 1e9))
    hi = bisect.bisect_right(stamps, f.stamp_ns + int(_VOUCH_S * 1e9))
    near = [places[k] for k in range(lo, hi) if len(places[k])]
    if near:
        p = np.concatenate(near)
        w = f.world_pose.apply(xy)
        out = (
            np.min(np.hypot(w[:, None, 0] - p[None, :, 0], w[:, None, 1] - p[None, :, 1]), axis=1) <= _VOUCH_M
        )
    return out


def recover_missed(fused: list[FrameResult], result: Any, options: LabelOptions) -> list[FrameResult]:
    """Add scan-cluster observations where a track coasted but the laser saw something at its position."""
    cfg = options.fusion
    r = options.recover_radius
    out = []
    for fr, tf in zip(fused, result.frames, strict=True):
        pts = fr.scan_points
        extra, extra_occ = [], []
        if pts is not None and len(pts):
            inv = fr.world_pose.inverse()
            taken = fr.observations.xy
            for p in tf.points:
                if p.det_index >= 0:
                    continue
                c = inv.apply(p.xy)
                near = np.hypot(pts[:, 0] - c[0], pts[:, 1] - c[1]) <= r
                if near.sum() < cfg.cluster_min_points:
                    continue
                xy = np.median(pts[near, :2].astype(np.float64), axis=0)
                xy = xy + cfg.leg_radius * xy / max(float(np.hypot(*xy)), 1e-6)
                if len(taken) and np.min(np.hypot(*(taken - xy).T)) < r:
                    continue
                taken = np.vstack([taken, xy[None]])
                extra.append(xy)
                if fr.scan_occupied is not None:
                    extra_occ.append(float(np.median(fr.scan_occupied[near].astype(np.float64))))
        if extra:
            n = len(extra)
            add = PersonObservations(
                np.array(extra),
                np.repeat((cfg.cluster_sigma**2 * np.eye(2))[None], n, 0),
                np.full(n, 0.3),
                ("laser",) * n,
                ("scan-cluster",) * n,
                np.full((n, 4), np.nan),
                np.full(n, -1),
                np.full(n, -1),
            )
            dt = None if fr.obs_dt is None else np.r_[fr.obs_dt, np.zeros(n)]
            occ = fr.occupied
            if occ is not None:  # the walk gate judges a recovered cluster as it does a detection
                occ = np.r_[occ, extra_occ if len(extra_occ) == n else np.full(n, np.nan)]
            fr = replace(
                fr, observations=PersonObservations.concat([fr.observations, add]), obs_dt=dt, occupied=occ
            )
        out.append(fr)
    return out


_REGROUP_LEG_MAX_M = ClassicalLaserDetector.pair_max  # two legs farther apart are no pair (0.6 m)


def _regroupings(legs: FloatArray, pairs: NDArray[np.intp]) -> list[tuple[int, int, int, int]]:
    """For every two leg pairs (``pairs``, rows of ``legs``) whose legs can also pair the other ways, each
    such way as ``(pair a, its leg, pair b, its leg)`` of one midpoint; the other midpoint joins the other
    two legs."""
    out = []
    for n, a in enumerate(pairs.tolist()):
        for b in pairs[n + 1 :].tolist():
            for lb in (0, 1):  # leg 0 of a with leg lb of b, leg 1 of a with the other
                d0 = np.hypot(*(legs[a, 0] - legs[b, lb]))
                d1 = np.hypot(*(legs[a, 1] - legs[b, 1 - lb]))
                if max(d0, d1) <= _REGROUP_LEG_MAX_M:
                    out += [(a, 0, b, lb), (a, 1, b, 1 - lb)]
    return out


def _to_odom(
    fr: FrameResult, appearance: NDArray[np.float32] | None, leg_sigma: float, view: ScanView | None = None
) -> Any:
    """The frame's observations in the tracking frame, with what the scanners saw (``view``); each leg
    pair's two legs follow as alternative rows (``Observations.alt_of``, 1-σ ``leg_sigma``), their
    ``det_index`` after the observations'; then, for every two leg pairs whose legs can pair the other ways
    (each two legs within 0.6 m), the midpoints of those other pairings (``Observations.joins``: source
    ``laser``, the pairs' mean covariance, the lower score, no colours)."""
    from studio.track.base import Observations

    obs = fr.observations
    n = len(obs)
    legs = np.full((n, 2, 2), np.nan)
    if fr.legs is not None:
        legs[: len(fr.legs)] = fr.legs[:n]
    pairs = np.flatnonzero(np.isfinite(legs).all(axis=(1, 2)))
    regroup = _regroupings(legs, pairs)
    leg_row = {(int(p), side): n + 2 * k + side for k, p in enumerate(pairs) for side in (0, 1)}
    pose = fr.world_pose
    R = pose.matrix()[:2, :2]
    mid = np.array([(legs[a, la] + legs[b, lb]) / 2 for a, la, b, lb in regroup]).reshape(-1, 2)
    xy = np.concatenate([obs.xy.reshape(-1, 2), legs[pairs].reshape(-1, 2), mid])
    xy = pose.apply(xy) if len(xy) else np.zeros((0, 2))
    cov_obs = R @ obs.cov @ R.T
    cov = np.concatenate(
        [
            cov_obs,
            np.repeat((leg_sigma**2 * np.eye(2))[None], 2 * len(pairs), 0),
            np.array([(cov_obs[a] + cov_obs[b]) / 2 for a, _, b, _ in regroup]).reshape(-1, 2, 2),
        ]
    )
    m = len(regroup)
    alt = np.r_[np.full(n, -1), np.repeat(pairs, 2), np.full(m, -1)].astype(np.int64)
    joins = np.full((len(xy), 2), -1, np.int64)
    for k, (a, la, b, lb) in enumerate(regroup):
        joins[len(xy) - m + k] = leg_row[a, la], leg_row[b, lb]
    app = None
    if appearance is not None:
        app = np.full((len(xy), APPEARANCE_DIM), np.nan, np.float32)
        hidden = np.zeros(n, bool)
        if fr.colours_hidden is not None:
            hidden[: len(fr.colours_hidden)] = fr.colours_hidden[:n]
        for k, bi in enumerate(obs.box_index):
            if 0 <= bi < len(appearance) and not hidden[k]:
                app[k] = appearance[bi]
    source = obs.source + tuple(obs.source[k] for k in pairs for _ in range(2)) + ("laser",) * m
    score = np.r_[
        obs.score, np.repeat(obs.score[pairs], 2), [min(obs.score[a], obs.score[b]) for a, _, b, _ in regroup]
    ]
    dt = None
    if fr.obs_dt is not None and len(fr.obs_dt) == n:
        dt = np.r_[
            fr.obs_dt,
            np.repeat(fr.obs_dt[pairs], 2),
            [(fr.obs_dt[a] + fr.obs_dt[b]) / 2 for a, _, b, _ in regroup],
        ]
    return Observations(
        fr.stamp_ns,
        xy,
        cov,
        source,
        score,
        app,
        np.arange(len(xy)),
        alt if len(pairs) else None,
        dt,
        view,
        joins if m else None,
    )


def tracking_config(options: LabelOptions, *, has_camera: bool) -> Any:
    """``options.tracking`` for a rig with or without a camera.

    With a camera (and ``sources`` not ``laser``):

    * The encounter re-decision does not split laser leg pairs between two tracks
      (``EncounterConfig.split_legs``): people who pass each other get a box each on the image frames, and
      the split mostly kept a duplicate track alive on one person's two legs. Session 21, simulated
      ``moving`` recordings with a camera: identity switches 83 → 67 on seeds 1–12 of version 4, F1 up
      0.001; laser only, the split is needed (93 → 104 switches without it on seeds 1–8).
    * A continuation may take a tracklet over from up to 1 s before its end (``StitchConfig.tail_back_s``,
      0.5 s without a camera): the colours at both ends check such a link. Session 22, simulated
      ``moving`` seeds 1–12 with the camera: 59 → 46 switches against 0.5 s; laser only, 1 s gave 97 → 107.
    * No hidden walks (``StitchConfig.hidden_max_error`` 0): a tracklet the camera did not describe is joined
      across a long gap only near where the other was lost. Session 62, simulated ``moving`` seeds 1–70 with
      the camera: 54 → 57 switches with them (seeds 6 and 59: pieces of someone else the camera had not
      described); laser only they are kept.
    * The time windows are stretched to the image detector's period. People only the camera sees (beside
      the robot, where its body hides them from the lasers, or beyond the lasers' reach) are observed on
      image frames only, every ``image_period_s`` (every 6th frame of a 30 Hz camera at the default 0.2 s):
      a tentative track must be able to collect ``confirm_hits`` of them in its confirmation window, and
      neither a tentative track nor a tracklet may be cut in the gaps between them.
    """
    cfg = options.tracking
    if not has_camera or options.sources == "laser":
        return cfg
    if cfg.encounters is not None:
        cfg = replace(cfg, encounters=replace(cfg.encounters, split_legs=False))
    if cfg.stitch is not None:
        cfg = replace(
            cfg,
            stitch=replace(
                cfg.stitch, tail_back_s=max(cfg.stitch.tail_back_s, _CAMERA_TAIL_BACK_S), hidden_max_error=0.0
            ),
        )
    period = options.image_period_s
    if period <= 0:
        return cfg
    t = cfg.tracker
    tracker = replace(
        t,
        confirm_window_s=max(t.confirm_window_s, (t.confirm_hits - 1) * period + 0.05),
        tentative_max_coast_s=max(t.tentative_max_coast_s, 1.5 * period),
    )
    return replace(cfg, tracker=tracker, split_gap_s=max(cfg.split_gap_s, 1.5 * period))


def longest_walk(observed: list[tuple[int, float, float]]) -> float:
    """How far a track walked in one stretch, m: the largest diameter of :func:`walk_stretches`."""
    return max((d for _, _, d in walk_stretches(observed)), default=0.0)


def walk_stretches(observed: list[tuple[int, float, float]]) -> list[tuple[int, int, float]]:
    """``(first stamp_ns, last stamp_ns, diameter m)`` of each stretch of a track's observed positions
    ``(stamp_ns, x, y)`` (in time order) between gaps longer than ``_WALK_GAP_S``, each stretch's positions
    median-filtered over ``_WALK_MEDIAN`` observations first (a track that jitters or hops between two
    chair legs in one stretch does not walk); stretches of fewer observations than that are left out."""
    from scipy.ndimage import median_filter

    if len(observed) < _WALK_MEDIAN:
        return []
    stamps = np.array([o[0] for o in observed], dtype=np.int64)  # exact: float64 rounds epoch ns
    xy_all = np.array([o[1:] for o in observed], dtype=np.float64)
    cuts = np.flatnonzero(np.diff(stamps) > _WALK_GAP_S * 1e9) + 1
    out = []
    for t, run in zip(np.split(stamps, cuts), np.split(xy_all, cuts), strict=True):
        if len(run) < _WALK_MEDIAN:
            continue
        xy = median_filter(run, size=(_WALK_MEDIAN, 1), mode="nearest")
        out.append((int(t[0]), int(t[-1]), _diameter(xy)))
    return out


def _diameter(xy: FloatArray) -> float:
    """The largest distance between two of the points ``(N, 2)``, N ≥ 2 (on the convex hull's vertices: a
    track of a whole recording has thousands of points)."""
    from scipy.spatial import ConvexHull, QhullError
    from scipy.spatial.distance import pdist

    if len(xy) > 64:
        try:
            xy = xy[ConvexHull(xy).vertices]
        except QhullError:  # all on one line (or one point): the farthest from the farthest is an end
            far = xy[np.argmax(np.hypot(*(xy - xy[0]).T))]
            return float(np.hypot(*(xy - far).T).max())
    return float(pdist(xy).max())


def track_all(
    frames: list[PerceptionFrame],
    fused: list[FrameResult],
    options: LabelOptions,
    *,
    has_camera: bool,
    tracker: Callable[..., Any] | None = None,
) -> tuple[list[LabelFrame], list[FrameResult]]:
    """Track in the odom frame and turn tracks into per-frame labels in the base frame.

    Args:
        tracker: called as ``tracker(observations, config=OfflineConfig)`` in place of
            :func:`~studio.track.offline.track_offline`, with the per-frame
            :class:`~studio.track.base.Observations` in the odom frame in the order of ``fused``; a tool
            that compares association methods passes its own.

    Returns:
        The labels, and the per-frame observations the final tracking pass used (``fused`` plus the
        scan clusters recovered where tracks coasted).
    """
    from studio.track.offline import track_offline

    run_tracker = tracker or track_offline
    config = tracking_config(options, has_camera=has_camera)
    sigma = options.fusion.leg_sigma
    views = [pf.scan_view() for pf in frames]  # once: a frame that still has its beams makes it anew
    observations = [
        _to_odom(fr, pf.appearance, sigma, v) for fr, pf, v in zip(fused, frames, views, strict=True)
    ]
    result = run_tracker(observations, config=config)
    if options.recover_radius > 0 and options.sources != "camera":
        fused = recover_missed(fused, result, options)
        observations = [
            _to_odom(fr, pf.appearance, sigma, v) for fr, pf, v in zip(fused, frames, views, strict=True)
        ]
        result = run_tracker(observations, config=config)
    # camera confirmation and minimum duration, per track
    camera_hits: dict[int, list[int]] = {}
    span: dict[int, list[int]] = {}
    sources: dict[int, Counter[str]] = {}
    camera_gate = has_camera and options.sources == "both"
    walk_gate = options.min_walk_m > 0 and (not has_camera or options.sources == "laser")
    # with the camera, a stretch in which a track walked min_walk_m counts as the camera's support there
    walk_support = camera_gate and options.min_walk_m > 0
    # walk gate and walking stretches: each track's observed positions (not on places seen occupied)
    observed: dict[int, list[tuple[int, float, float]]] = {}
    by_camera = ("fused", "image")
    for fr_i, (fr, tf) in enumerate(zip(fused, result.frames, strict=True)):
        how = fr.observations.how
        ob = observations[fr_i]
        occ = fr.occupied
        # camera observations no track took: the camera saw someone there, whoever the tracks say it is
        taken = {p.det_index for p in tf.points}
        free = [k for k, src in enumerate(ob.source) if camera_gate and src in by_camera and k not in taken]
        seen = ob.xy[free].reshape(-1, 2)
        for p in tf.points:
            span.setdefault(p.track_id, []).append(fr.stamp_ns)
            camera = False
            if p.det_index >= 0:
                src = ob.source[p.det_index]
                sources.setdefault(p.track_id, Counter())[src] += 1
                if walk_gate or walk_support:
                    # a leg of a split pair or a midpoint of two pairs' legs (a row past the
                    # observations) is where its pair was
                    row = ob.origin(p.det_index)
                    # left out, not marked: a walk that crosses such places for over _WALK_GAP_S is cut
                    # there (else a few observations on the way from one chair leg to the next span a hop)
                    if occ is None or not 0 <= row < len(occ) or not occ[row] >= _WALK_OCCUPIED:
                        observed.setdefault(p.track_id, []).append(
                            (fr.stamp_ns, float(p.xy[0]), float(p.xy[1]))
                        )
                # a laser person beside someone a box took, in that box: the camera saw someone there too
                beside = p.det_index < len(how) and how[p.det_index] == "beside-box"
                camera = src in by_camera or beside
            if not camera and len(seen):
                camera = bool(np.min(np.hypot(*(seen - p.xy).T)) <= _CAMERA_SEEN_M)
            if camera:
                camera_hits.setdefault(p.track_id, []).append(fr.stamp_ns)
    keep = set()
    walking: dict[int, list[tuple[int, int]]] = {}  # with the camera: each kept track's walking stretches
    for tid, stamps in span.items():
        if (max(stamps) - min(stamps)) / 1e9 < options.min_track_s:
            continue
        if camera_gate and len(camera_hits.get(tid, ())) < options.min_camera_hits:
            continue
        if walk_gate and longest_walk(observed.get(tid, [])) < options.min_walk_m:
            continue
        keep.add(tid)
        if walk_support:
            walking[tid] = [
                (a, b) for a, b, d in walk_stretches(observed.get(tid, [])) if d >= options.min_walk_m
            ]
    support = {tid: np.array(v, dtype=np.int64) for tid, v in camera_hits.items()}
    window_ns = int(options.camera_support_s * 1e9)

    def supported(tid: int, stamp: int) -> bool:
        if not camera_gate:
            return True
        if any(a <= stamp <= b for a, b in walking.get(tid, ())):
            return True  # the laser saw someone walk here: a person, whom the camera may not box (far away)
        t = support.get(tid)
        if t is None:
            return False
        k = int(np.searchsorted(t, stamp))
        near = [t[i] for i in (k - 1, k) if 0 <= i < len(t)]
        return any(abs(int(x) - stamp) <= window_ns for x in near)

    labels = []
    for fr_i, (fr, tf) in enumerate(zip(fused, result.frames, strict=True)):
        inv = fr.world_pose.inverse()
        R = inv.matrix()[:2, :2]
        people = []
        for p in tf.points:
            if p.track_id not in keep or not supported(p.track_id, fr.stamp_ns):
                continue
            xb = inv.apply(p.xy)
            xo = fr.robot_pose.apply(xb)  # the outputs stay in the odometry frame
            cov = R @ p.cov @ R.T
            o, ob, k = fr.observations, observations[fr_i], p.det_index
            # rows past the observations are legs of a pair split between two people, or midpoints of two
            # pairs' legs paired the other way: placed by the laser alone, the pair's score, no box (the
            # pair's box, if any, vouched for both: see camera_hits)
            leg = k >= len(o)
            j = ob.origin(k) if k >= 0 else k
            if k < 0:
                source = sources[p.track_id].most_common(1)[0][0]
            else:
                source = "laser" if leg else ob.source[k]
            people.append(
                LabelPerson(
                    id=p.track_id,
                    x=float(xb[0]),
                    y=float(xb[1]),
                    x_odom=float(xo[0]),
                    y_odom=float(xo[1]),
                    cov=((cov[0, 0], cov[0, 1]), (cov[1, 0], cov[1, 1])),
                    source=source,
                    box=as_box(o.box[k]) if 0 <= k < len(o) else None,
                    score=float(o.score[j]) if j >= 0 else None,
                    extra={"interpolated": True} if j < 0 else {},
                )
            )
        labels.append(LabelFrame(fr.index, tuple(people), fr.stamp_ns, fr.robot_pose))
    return labels, fused


def label_recording(
    recording: str | Path,
    rig: Any,
    *,
    options: LabelOptions | None = None,
    progress: Callable[[int, int], None] | None = None,
    on_frame: Callable[[Any, PerceptionFrame], None] | None = None,
) -> LabelRun:
    """Label a recording (both passes). See the module docstring."""
    opts = options or LabelOptions()
    if rig.camera is None and opts.sources == "both":
        opts = LabelOptions(**{**opts.__dict__, "sources": "laser"})
    if opts.method == "thesis":
        from studio.pipeline.thesis import label_thesis

        return label_thesis(Path(recording), rig, opts, progress=progress, on_frame=on_frame)
    t0 = time.perf_counter()
    sizes: dict[str, tuple[int, int]] = {}

    def hook(frame: Any, pf: PerceptionFrame) -> None:
        if frame.panorama is not None and "size" not in sizes:
            sizes["size"] = (frame.panorama.image.shape[1], frame.panorama.image.shape[0])
        if on_frame is not None:
            on_frame(frame, pf)

    frames, info = perceive(Path(recording), rig, opts, progress=progress, on_frame=hook)
    notes: list[str] = list(info["notes"])
    if not frames:
        raise StudioError(f"{recording}: no frame could be built: {info['sync_report'].why_empty()}")
    dropped = info["sync_report"].dropped_note()
    if dropped:
        notes.append(dropped)
    unsynced = info["sync_report"].unsynced() if info["use_laser"] else []
    if unsynced and len(unsynced) == len(info["rig"].lasers):
        raise StudioError(f"{recording}: {unsynced[0]}; --sources camera labels without the lasers")
    notes += unsynced
    if info["use_laser"] and not unsynced and not any(np.isfinite(f.points[:, 0]).any() for f in frames):
        notes.append(
            "no scan has a valid range (all NaN, inf or outside range_min–range_max): the lasers found nobody"
        )
    camera = None
    rig = info["rig"]
    if "size" in sizes and rig.camera is not None:
        camera = rig_camera(rig, *sizes["size"])
    looked = [f.image for f in frames if f.image is not None]
    if camera is not None and opts.sources == "both" and looked and not any(len(d.boxes) for d in looked):
        with_people = sum(f.laser is not None and len(f.laser) > 0 for f in frames)
        if with_people:
            notes.append(
                f"the image detector found nobody in any of the {len(looked)} images it looked at, the "
                f"lasers someone in {with_people} frames: with a camera a track is kept only where a box "
                "confirmed it (a covered or dark lens? images too small?); --sources laser labels from the "
                "lasers alone"
            )
    t1 = time.perf_counter()
    fused = fuse_all(frames, camera, opts, static_map=info["static_map"], body_maps=info["body_maps"])
    frames = [f.without_beams() for f in frames]  # tracking needs none: its peak memory is the run's
    t2 = time.perf_counter()
    labels, fused = track_all(frames, fused, opts, has_camera=camera is not None)
    t3 = time.perf_counter()
    timings = dict(info["timings_s"])
    timings.update({"pass1_total": t1 - t0, "static_filter_and_fusion": t2 - t1, "tracking": t3 - t2})
    counts = {
        "frames": len(frames),
        "observations": int(sum(len(f.observations) for f in fused)),
        "by_source": _count_sources(fused),
        "tracks": len({p.id for lf in labels for p in lf.people}),
        "sync": info["sync"],
        "scan_matching": info["scan_matching"],
        "image_looks": info["image_looks"],
        "views_run": info["views_run"],
        "view_columns_run": info["view_columns_run"],
        "laser_beam_deg": info["laser_beam_deg"],
        "laser_sweep_ms": info["laser_sweep_ms"],
    }
    image_dets = [(f.index, f.stamp_ns, f.image) for f in frames if f.image is not None]
    return LabelRun(labels, fused, sizes.get("size"), camera, timings, counts, notes, image_dets)


def _count_sources(fused: list[FrameResult]) -> dict[str, int]:
    out: dict[str, int] = {}
    for f in fused:
        for s, h in zip(f.observations.source, f.observations.how, strict=True):
            out[f"{s}/{h}"] = out.get(f"{s}/{h}", 0) + 1
    return out


def observations_to_frames(fused: list[FrameResult]) -> list[LabelFrame]:
    """``detections.yaml`` content: fused people per frame, ids are indices."""
    out = []
    for fr in fused:
        o: PersonObservations = fr.observations
        people = tuple(
            LabelPerson(
                id=k,
                x=float(o.xy[k, 0]),
                y=float(o.xy[k, 1]),
                source=o.source[k],
                score=float(o.score[k]),
                box=as_box(o.box[k]),
                cov=((o.cov[k, 0, 0], o.cov[k, 0, 1]), (o.cov[k, 1, 0], o.cov[k, 1, 1])),
                extra={"how": o.how[k]},
            )
            for k in range(len(o))
        )
        out.append(LabelFrame(fr.index, people, fr.stamp_ns, fr.robot_pose))
    return out
