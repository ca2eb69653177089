"""Box ↔ laser fusion on the sphere (issue 3, item 3).

Laser detections are projected into the panorama with the rig's camera pose (spherical model, no per-face
homographies). Each person box gets a range estimate from the image alone — the foot row on the floor plane
(ankle keypoints, else the box bottom), or the apparent torso length when the feet are hidden — and boxes are
associated one-to-one with laser detections (Hungarian) on column and range consistency. A box the range gate
kept from every detection takes one inside its columns, nearer than its range, that no box took and that is
not on never-moving structure: its foot row was read too far (``FusionConfig.nearer_laser``). A box that still
finds no detection takes the scan cluster inside its azimuth span closest to the robot (the thesis's fallback,
here also range-gated); failing that, an image-only position from its range cue with a large covariance,
unless the laser saw through that spot (then the box is a loose one on someone farther away, or no person). A
laser detection on never-moving structure may be taken by a box (someone who stood still for the whole
recording looks static to the laser), but not from behind moving scan points in the box's columns: that is the
wall seen between the legs of a person the laser detector missed. There is never a fixed fallback position.
Laser detections no box confirms are kept with source ``laser``; whether they survive is decided at the track
level.

All positions are in the robot base frame, metres; ranges are horizontal distances from the camera centre.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray
from scipy.optimize import linear_sum_assignment

from studio.detect.image.base import ImageDetections
from studio.detect.laser.base import LaserDetections
from studio.fuse.base import FusionConfig, PersonObservations, ScanRays
from studio.geometry import EquirectCamera

__all__ = ["BoxRange", "box_ranges", "colours_hidden", "fuse_frame", "points_columns"]

FloatArray = NDArray[np.float64]

# COCO keypoint indices (MoveNet order)
_SHOULDERS = (5, 6)
_HIPS = (11, 12)
_KNEES = (13, 14)
_ANKLES = (15, 16)
_BIG = 1e9
_CLOTHES_Z = 1.0  # m above the base frame: between the thighs and the torso


@dataclass(frozen=True)
class BoxRange:
    """Image-only range cues of N boxes.

    Attributes:
        u_center: ``(N,)`` box centre column, px (may exceed W across the seam).
        az: ``(N,)`` bearing of the box centre in the base frame, seen from the camera, rad.
        range: ``(N,)`` horizontal distance camera → person, m (NaN when the image gives none).
        sigma: ``(N,)`` 1-σ of ``range``, m (inf when unknown).
        how: N strings: ``foot-row``, ``torso-size`` or ``none``.
        max_range: ``(N,)`` the farthest the person can be, from the box's top row (the top of a head, or
            of raised hands, at most ``FusionConfig.head_top_z`` above the floor), m (inf when the top row
            is not above the camera).
    """

    u_center: FloatArray
    az: FloatArray
    range: FloatArray
    sigma: FloatArray
    how: tuple[str, ...]
    max_range: FloatArray


def _cam_xy(camera: EquirectCamera) -> FloatArray:
    return np.asarray(camera.pose.t[:2], dtype=np.float64)


def _column_azimuth(camera: EquirectCamera, u: FloatArray) -> FloatArray:
    """Bearing in the base frame (seen from the camera) of panorama columns, at the horizon row."""
    v = np.full_like(u, camera.height / 2.0)
    rays = camera.bearing_base(np.stack([u % camera.width, v], axis=-1))
    return np.arctan2(rays[:, 1], rays[:, 0])


def _ground_range(camera: EquirectCamera, u: float, v: float, z: float) -> float:
    p = camera.backproject_to_ground(np.array([[u % camera.width, v]]), ground_z=z)[0]
    if not np.all(np.isfinite(p)):
        return float("nan")
    return float(np.hypot(*(p[:2] - _cam_xy(camera))))


def box_ranges(
    dets: ImageDetections, camera: EquirectCamera, *, config: FusionConfig | None = None
) -> BoxRange:
    """Range cues of every box from the image alone (see the module docstring)."""
    cfg = config or FusionConfig()
    n = len(dets.boxes)
    boxes = dets.boxes
    uc = (boxes[:, 0] + boxes[:, 2]) / 2.0 if n else np.zeros(0)
    az = _column_azimuth(camera, uc) if n else np.zeros(0)
    rng = np.full(n, np.nan)
    sig = np.full(n, np.inf)
    how = ["none"] * n
    sigma_v = cfg.foot_sigma_px * camera.width / 1920.0
    kp = dets.keypoints
    for i in range(n):
        foot_v, foot_z = None, cfg.floor_z
        torso = None
        if kp is not None:
            k = kp[i]
            ok = k[:, 2] >= cfg.foot_kpt_min_score
            ankles = [j for j in _ANKLES if ok[j]]
            if ankles:
                foot_v = float(max(k[j, 1] for j in ankles))
                foot_z = cfg.floor_z + cfg.ankle_height
            elif not any(ok[j] for j in _KNEES) and ok[list(_SHOULDERS)].any() and ok[list(_HIPS)].any():
                sh = [j for j in _SHOULDERS if ok[j]]
                hp = [j for j in _HIPS if ok[j]]
                torso = (float(np.mean(k[sh, 1])), float(np.mean(k[hp, 1])))
            elif any(ok[j] for j in _KNEES):
                foot_v = float(boxes[i, 3])  # legs seen down to the knees at least: the box bottom
        else:
            foot_v = float(boxes[i, 3])
        if foot_v is not None:
            r = _ground_range(camera, uc[i], foot_v, foot_z)
            if np.isfinite(r) and r <= cfg.max_range:
                r_hi = _ground_range(camera, uc[i], foot_v - sigma_v, foot_z)
                r_lo = _ground_range(camera, uc[i], foot_v + sigma_v, foot_z)
                s = abs(r_hi - r_lo) / 2.0 if np.isfinite(r_hi) and np.isfinite(r_lo) else np.inf
                rng[i], sig[i], how[i] = r, max(s, 0.05), "foot-row"
                continue
        if torso is not None:
            _, el_s = camera.pixel_to_angles(np.array([uc[i] % camera.width]), np.array([torso[0]]))
            _, el_h = camera.pixel_to_angles(np.array([uc[i] % camera.width]), np.array([torso[1]]))
            dt = float(np.tan(el_s[0]) - np.tan(el_h[0]))
            if dt > 1e-3:
                r = cfg.torso_length / dt
                if r <= cfg.max_range:
                    rng[i], sig[i], how[i] = r, max(cfg.torso_rel_sigma * r, 0.1), "torso-size"
    return BoxRange(uc, az, rng, sig, tuple(how), _top_bound(camera, uc, boxes[:, 1], cfg))


def _top_bound(camera: EquirectCamera, u: FloatArray, v_top: FloatArray, cfg: FusionConfig) -> FloatArray:
    """The farthest (horizontal range from the camera, m) a person can be whose box's top row is ``v_top``:
    nothing of them is higher than ``head_top_z``, so a top row well above the horizon means someone near
    (``head_top_margin`` for the top row's error). Inf where the top row is not above the camera."""
    out = np.full(len(u), np.inf)
    if not len(u):
        return out
    rays = camera.bearing_base(np.stack([np.asarray(u) % camera.width, np.asarray(v_top)], axis=-1))
    tan_el = rays[:, 2] / np.maximum(np.hypot(rays[:, 0], rays[:, 1]), 1e-9)
    rise = cfg.floor_z + cfg.head_top_z - float(camera.pose.t[2])
    up = tan_el > 1e-3
    if rise > 0:
        out[up] = (rise / tan_el[up]) * cfg.head_top_margin
    return out


def points_columns(camera: EquirectCamera, points_base: FloatArray) -> tuple[FloatArray, FloatArray]:
    """Panorama columns of base-frame points ``(M, 3)`` and their horizontal ranges from the camera."""
    pts = np.asarray(points_base, dtype=np.float64).reshape(-1, 3)
    if not len(pts):
        return np.zeros(0), np.zeros(0)
    uv, _ = camera.project(pts)
    rng = np.hypot(*(pts[:, :2] - _cam_xy(camera)).T)
    return uv[:, 0], rng


def colours_hidden(
    obs: PersonObservations,
    camera: EquirectCamera,
    *,
    margin: float = 0.5,
    body_radius: float = 0.2,
    core_frac: float = 0.2,
) -> NDArray[np.bool_]:
    """Which observations' boxes may show someone else's clothes: one box over two people on one bearing.

    A box's colours are read from its middle. When the laser sees someone nearer to the camera (by more
    than ``margin``) whose body (``body_radius`` either side of their position) covers the middle
    ``core_frac`` of the box's width, and the image detector gave that person no box of their own, the
    detector saw one person where there were two: the box is typically the front person's head and torso
    down to the feet of the one behind, its foot row says the range of the one behind, fusion gives it to
    that one's laser detection, and the colours are the front person's. On simulated ``moving`` recordings
    (seeds 1-10, each described observation compared with its own person's median colours) 44 of 56 such
    boxes were more than 15 ΔE off, against 309 of 16 086 boxes nobody covers (1.9 %); where the person in
    front has a box of their own (the detector told them apart), 11 of 50.

    Returns:
        ``(N,)`` True for rows with a box covered in that way (rows without a box are False).
    """
    n = len(obs)
    out = np.zeros(n, bool)
    has_box = obs.box_index >= 0
    if n < 2 or not has_box.any() or has_box.all():
        return out
    # columns at the height the colours are read from (a tilted camera sees the floor elsewhere)
    u, rng = points_columns(camera, np.c_[obs.xy, np.full(n, _CLOTHES_Z)])
    half = np.degrees(np.arctan2(body_radius, np.maximum(rng, 1e-6))) * camera.width / 360.0
    for k in np.flatnonzero(has_box):
        u1, _, u2, _ = obs.box[k]
        core = 0.5 * core_frac * (u2 - u1)
        front = ~has_box & (rng < rng[k] - margin)
        off = np.abs(_offset_in_box(u[front], u1, u2, camera.width))
        out[k] = bool(np.any(off < core + half[front]))
    return out


def _offset_in_box(u: FloatArray, u1: float, u2: float, width: int) -> FloatArray:
    """Signed column offset of ``u`` from the box centre, seam-aware, px."""
    c = (u1 + u2) / 2.0
    return (u - c + width / 2.0) % width - width / 2.0


def _polar_cov(az: float, r: float, sigma_r: float, sigma_t: float) -> FloatArray:
    c, s = np.cos(az), np.sin(az)
    R = np.array([[c, -s], [s, c]])
    return R @ np.diag([sigma_r**2, sigma_t**2]) @ R.T


def fuse_frame(
    image: ImageDetections | None,
    laser: LaserDetections | None,
    *,
    camera: EquirectCamera | None,
    laser_z: FloatArray | float = 0.3,
    scan_points: FloatArray | None = None,
    laser_static: NDArray[np.bool_] | None = None,
    rays: ScanRays | None = None,
    config: FusionConfig | None = None,
) -> PersonObservations:
    """Fuse one frame's image and laser people into positions in the base frame.

    Args:
        image: boxes (+ keypoints) on the panorama, or None (laser-only).
        laser: laser people in the base frame, or None (camera-only).
        camera: the panorama camera with its pose in the base frame; needed when ``image`` is given.
        laser_z: height of each laser detection's scan plane in the base frame, m (scalar or ``(N,)``).
        scan_points: ``(M, 3)`` valid, non-static scan points in the base frame for the cluster fallback.
        laser_static: ``(N,)`` laser detections on never-moving structure (the static-world map). A box may
            still take one (someone who stands still for the whole recording looks static to the laser),
            but one no box takes is dropped.
        rays: all the frame's beams that returned (static structure included): a box whose image-only
            position the laser saw through makes no observation (:attr:`FusionConfig.see_through_halfwidth`).
        config: association parameters.

    Returns:
        The fused people: one per box that found a position, plus laser detections no box took.
    """
    cfg = config or FusionConfig()
    n_l = 0 if laser is None else len(laser.xy)
    n_b = 0 if image is None else len(image.boxes)
    parts: list[PersonObservations] = []
    used_laser = np.zeros(n_l, dtype=bool)
    absorbed = np.zeros(n_l, dtype=bool)
    beside = np.zeros(n_l, dtype=bool)  # inside a box that took someone else at their range
    static = np.zeros(n_l, bool)  # on never-moving structure
    if laser_static is not None and n_l:
        static = np.asarray(laser_static, bool).reshape(n_l)
    if n_b and image is not None:
        if camera is None:
            raise ValueError("fuse_frame: image detections need the camera")
        W = camera.width
        br = box_ranges(image, camera, config=cfg)
        boxes = image.boxes
        bw = np.maximum(boxes[:, 2] - boxes[:, 0], 1.0)
        cost = np.full((n_b, n_l), _BIG)
        pts = None if scan_points is None else np.asarray(scan_points, dtype=np.float64).reshape(-1, 3)
        u_p, r_p = points_columns(camera, pts) if pts is not None and len(pts) else (np.zeros(0), np.zeros(0))
        if n_l and laser is not None:
            sig_l = cfg.laser_sigmas(laser.kind)
            z = np.broadcast_to(np.asarray(laser_z, dtype=np.float64), (n_l,))
            u_l, r_l = points_columns(camera, np.c_[laser.xy, z])
            for i in range(n_b):
                off = _offset_in_box(u_l, boxes[i, 0], boxes[i, 2], W) / (bw[i] / 2.0)
                inside = np.abs(off) <= 1.0 + 2.0 * cfg.box_margin_frac
                if np.isfinite(br.range[i]):
                    s = np.hypot(br.sigma[i], sig_l)
                    dr = (r_l - br.range[i]) / s
                    gate = np.maximum(cfg.gate_range_min, cfg.gate_sigma * s)
                    ok = inside & (np.abs(r_l - br.range[i]) <= gate)
                    ok &= ~static | (np.abs(dr) <= cfg.static_gate_sigma)
                    c = off**2 + dr**2
                else:  # feet hidden (e.g. by the robot body): the laser decides, nearest first, but not
                    # beyond what the box's top row allows (a person that near is tall in the image)
                    ok = inside & (r_l <= min(cfg.max_range, br.max_range[i]))
                    c = off**2 + r_l / cfg.max_range
                if cfg.static_behind > 0 and len(u_p) and (ok & static).any():
                    # a static detection behind moving scan points in the box: the wall between their legs
                    half = cfg.cluster_core_frac * bw[i] / 2.0
                    core = np.abs(_offset_in_box(u_p, boxes[i, 0], boxes[i, 2], W)) <= half
                    for j in np.flatnonzero(ok & static):
                        nearer = np.count_nonzero(core & (r_p < r_l[j] - cfg.static_behind))
                        ok[j] = nearer < cfg.cluster_min_points
                cost[i, ok] = c[ok]

            def take(i: int, j: int) -> None:
                """Box i and laser person j are one person."""
                used_laser[j] = True
                # the same person's other leg (or a part of them): inside this box and next to its match
                near = np.hypot(*(laser.xy - laser.xy[j]).T) <= cfg.same_person_radius
                off = _offset_in_box(u_l, boxes[i, 0], boxes[i, 2], W) / (bw[i] / 2.0)
                in_box = np.abs(off) <= 1.0 + 2.0 * cfg.box_margin_frac
                absorbed[:] |= near & in_box
                beside[:] |= ~near & in_box & (np.abs(r_l - r_l[j]) <= cfg.beside_box_range)
                sc = 1.0 - (1.0 - image.scores[i]) * (1.0 - laser.scores[j])
                parts.append(
                    _one(
                        laser.xy[j], sig_l[j] ** 2 * np.eye(2), sc, "fused", "laser-detection", boxes[i], i, j
                    )
                )

            rows, cols = linear_sum_assignment(cost)
            for i, j in zip(rows, cols, strict=True):
                if cost[i, j] < _BIG:
                    take(int(i), int(j))
            # A box the range gate kept from every laser person, with one nearer inside it that no box took:
            # its foot row was read too far, and it is that person's (``FusionConfig.nearer_laser``).
            taken = set(rows[cost[rows, cols] < _BIG].tolist())
            for i in np.argsort(br.range) if cfg.nearer_laser else ():
                if i in taken or not np.isfinite(br.range[i]):
                    continue
                off = np.abs(_offset_in_box(u_l, boxes[i, 0], boxes[i, 2], W) / (bw[i] / 2.0))
                cand = np.flatnonzero(
                    ~used_laser
                    & ~absorbed
                    & ~static
                    & (off <= 1.0 + 2.0 * cfg.box_margin_frac)
                    & (r_l < br.range[i])
                )
                if len(cand):
                    take(int(i), int(cand[np.argmin(off[cand])]))
        matched_boxes = {int(p.box_index[0]) for p in parts}
        cam_xy = _cam_xy(camera)
        for i in range(n_b):
            if i in matched_boxes:
                continue
            obs = None
            gate = max(cfg.gate_range_min + 0.2, cfg.gate_sigma * br.sigma[i])  # when the box has a range
            if len(u_p) and pts is not None:
                off = _offset_in_box(u_p, boxes[i, 0], boxes[i, 2], W) / (bw[i] / 2.0)
                sel = np.abs(off) <= cfg.cluster_core_frac
                if np.isfinite(br.range[i]):
                    sel &= np.abs(r_p - br.range[i]) <= gate
                sel &= r_p <= min(cfg.max_range, br.max_range[i])
                idx = np.flatnonzero(sel)
                if len(idx) >= cfg.cluster_min_points:
                    order = idx[np.argsort(r_p[idx])]
                    gaps = np.flatnonzero(np.diff(r_p[order]) > cfg.cluster_gap)
                    starts = np.r_[0, gaps + 1]
                    ends = np.r_[gaps + 1, len(order)]
                    for a, b in zip(starts, ends, strict=True):
                        if b - a >= cfg.cluster_min_points:
                            cl = pts[order[a:b], :2]
                            xy = np.median(cl, axis=0)
                            d = xy - cam_xy
                            xy = xy + cfg.leg_radius * d / max(float(np.linalg.norm(d)), 1e-6)
                            obs = _one(
                                xy,
                                cfg.cluster_sigma**2 * np.eye(2),
                                float(image.scores[i]) * 0.9,
                                "fused",
                                "scan-cluster",
                                boxes[i],
                                i,
                                -1,
                            )
                            break
            if obs is None and np.isfinite(br.range[i]):
                az, r = float(br.az[i]), float(br.range[i])
                xy = cam_xy + r * np.array([np.cos(az), np.sin(az)])
                if (
                    rays is not None
                    and cfg.see_through_halfwidth > 0
                    and rays.seen_through(
                        xy, gate, cfg.see_through_halfwidth, cfg.see_through_span, cfg.cluster_min_points
                    )
                ):
                    continue  # the laser saw through where the box says the person stands
                sig_t = r * cfg.bearing_sigma_frac * bw[i] * 2.0 * np.pi / W
                obs = _one(
                    xy,
                    _polar_cov(az, r, br.sigma[i], max(sig_t, 0.05)),
                    float(image.scores[i]) * 0.8,
                    "image",
                    br.how[i],
                    boxes[i],
                    i,
                    -1,
                )
            if obs is not None:
                parts.append(obs)
    if n_l and laser is not None:
        rest = np.flatnonzero(~used_laser & ~static & ~absorbed)
        if len(rest):
            parts.append(
                PersonObservations(
                    laser.xy[rest],
                    cfg.laser_sigmas(laser.kind[rest])[:, None, None] ** 2 * np.eye(2),
                    laser.scores[rest],
                    ("laser",) * len(rest),
                    tuple("beside-box" if beside[k] else "laser-only" for k in rest),
                    np.full((len(rest), 4), np.nan),
                    np.full(len(rest), -1),
                    rest,
                )
            )
    return PersonObservations.concat(parts)


def _one(
    xy: FloatArray, cov: FloatArray, score: float, source: str, how: str, box: FloatArray, bi: int, li: int
) -> PersonObservations:
    return PersonObservations(
        np.asarray(xy, dtype=np.float64)[None],
        np.asarray(cov)[None],
        np.array([min(max(score, 0.0), 1.0)]),
        (source,),
        (how,),
        np.asarray(box, dtype=np.float64)[None],
        np.array([bi]),
        np.array([li]),
    )
