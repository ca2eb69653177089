"""Scan segmentation over valid returns and per-segment shape features.

Many beams return nothing (dark trousers absorb the laser), so a segment is a run of *valid* returns in
angle order where consecutive returns are closer than a range-adaptive jump distance; missing beams in
between never split a segment by themselves. Parameters are metric (metres, radians), never beam counts,
so they carry over to scanners with another angular resolution.
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

__all__ = [
    "FEATURE_NAMES",
    "SegmentParams",
    "estimate_angle_step",
    "segment_features",
    "segment_scan",
    "valid_mask",
]

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]

FEATURE_NAMES = (
    "n_points",  # number of valid returns
    "width",  # distance first–last return, m
    "range",  # distance of the centroid from the sensor, m
    "line_residual",  # RMS distance to the best line, m
    "circle_radius",  # radius of the best circle (algebraic fit), m, capped at 2
    "circle_residual",  # RMS distance to that circle, m
    "bulge",  # mean distance of the returns from the chord, toward the sensor positive (convex), m
    "occlusion_min",  # min over both ends of (neighbour range − end range), m, clipped to [−1, 1]
    "occlusion_max",  # max over both ends of the same, m
    "coverage",  # valid returns / beams spanned by the segment (missing returns lower it)
    "extent",  # max distance of a return from the centroid, m
    "jaggedness",  # outline length (sum of steps along the outline averaged over ~3 cm) / width
    "incidence",  # |cos| of the angle between the segment's main axis and the beam: 1 = seen edge-on
    "turning",  # mean absolute turning angle between consecutive steps of that outline, rad
    "turning_signed",  # mean signed turning angle, rad, positive when convex toward the sensor
)


@dataclass(frozen=True)
class SegmentParams:
    """Options of :func:`segment_scan`.

    Attributes:
        jump_min: jump distance at short range, metres: consecutive valid returns farther apart split.
        jump_beams: range-adaptive part: the jump distance is at least ``jump_beams × range × angular step``
            (the spacing of neighbouring beams at that range), so sparse far returns stay together.
        min_points: segments with fewer valid returns are dropped.
        max_range: returns farther than this are ignored, metres.
    """

    jump_min: float = 0.13
    jump_beams: float = 2.5
    min_points: int = 3
    max_range: float = 25.0


def valid_mask(points: FloatArray, valid: NDArray[np.bool_] | None) -> NDArray[np.bool_]:
    """Beams that returned something: finite, and True in ``valid`` when given."""
    pts = np.asarray(points, dtype=np.float64)
    ok = np.all(np.isfinite(pts), axis=1)
    if valid is not None:
        v = np.asarray(valid, dtype=bool).reshape(-1)
        if v.shape[0] != pts.shape[0]:
            raise ValueError(f"valid must have shape ({pts.shape[0]},), got {v.shape}")
        ok &= v
    return ok


def estimate_angle_step(points: FloatArray, *, origin: ArrayLike = (0.0, 0.0)) -> float:
    """The scanner's angular step (rad): median bearing change per beam index between finite returns.

    Args:
        points: ``(M, 2)`` beams in angle order, NaN where invalid.
        origin: ``(2,)`` sensor position in the frame of ``points``.
    """
    pts = np.asarray(points, dtype=np.float64).reshape(-1, 2)
    rel = pts - np.asarray(origin, dtype=np.float64).reshape(2)
    fi = np.flatnonzero(np.all(np.isfinite(rel), axis=1))
    if fi.size < 2:
        return float(np.radians(0.5))
    bear = np.unwrap(np.arctan2(rel[fi, 1], rel[fi, 0]))
    steps = np.abs(np.diff(bear)) / np.diff(fi)
    return float(np.median(steps))


def segment_scan(
    points: FloatArray,
    valid: NDArray[np.bool_] | None = None,
    *,
    origin: ArrayLike = (0.0, 0.0),
    params: SegmentParams | None = None,
    angle_step: float | None = None,
) -> list[IntArray]:
    """Split one scan into segments of valid returns.

    Args:
        points: ``(M, 2)`` float64, beams in angle order, metres; invalid ones NaN or masked.
        valid: ``(M,)`` bool, optional mask of returns.
        origin: ``(2,)`` sensor position in the frame of ``points``, metres.
        params: segmentation options.
        angle_step: the scanner's angular step, rad; default: estimated from all beams' bearings.

    Returns:
        Per segment the ``int64`` indices of its points (into ``points``), in angle order. A 360° scan whose
        last and first segments touch is joined across the wrap.
    """
    p = params or SegmentParams()
    pts = np.asarray(points, dtype=np.float64).reshape(-1, 2)
    o = np.asarray(origin, dtype=np.float64).reshape(2)
    ok = valid_mask(pts, valid)
    rel_all = pts - o
    rng_all = np.hypot(rel_all[:, 0], rel_all[:, 1])
    ok &= rng_all <= p.max_range
    idx = np.flatnonzero(ok)
    if idx.size == 0:
        return []
    rel = rel_all[idx]
    rng = rng_all[idx]
    if angle_step is None:
        angle_step = estimate_angle_step(pts, origin=o)
    d = np.hypot(*(rel[1:] - rel[:-1]).T)
    thr = np.maximum(p.jump_min, p.jump_beams * np.minimum(rng[1:], rng[:-1]) * angle_step)
    cuts = np.flatnonzero(d > thr) + 1
    bounds = np.concatenate([[0], cuts, [idx.size]])
    segs = [idx[a:b] for a, b in itertools.pairwise(bounds)]
    # join across the wrap of a full-circle scan
    if len(segs) > 1:
        bear = np.arctan2(rel[:, 1], rel[:, 0])
        n_beams = pts.shape[0]
        if angle_step * n_beams >= 2.0 * np.pi - 2.0 * angle_step:
            gap = np.hypot(*(rel[0] - rel[-1]))
            t = max(p.jump_min, p.jump_beams * min(rng[0], rng[-1]) * angle_step)
            if gap <= t and abs(float(np.angle(np.exp(1j * (bear[0] - bear[-1]))))) < 0.5:
                segs[0] = np.concatenate([segs.pop(), segs[0]])
    return [s.astype(np.int64) for s in segs if s.size >= p.min_points]


_MAX_RADIUS = 2.0
_NEIGHBOUR_GAP = float(np.radians(3.0))


_OUTLINE_SCALE = 0.03


def _outline(
    q: FloatArray, seg_of: IntArray, starts: IntArray, lens: IntArray, width: FloatArray
) -> FloatArray:
    """Each return replaced by the mean of the returns of its segment within a window of at most
    ``_OUTLINE_SCALE`` (``2h + 1`` returns, ``h`` from the segment's mean spacing; 1 return, so unchanged,
    where returns are more than a third of that apart)."""
    spacing = width / np.maximum(lens - 1, 1)
    h = np.floor(0.5 * (_OUTLINE_SCALE / np.maximum(spacing, 1e-6) - 1.0)).clip(0, None).astype(np.int64)
    if not h.any():
        return q
    k = np.arange(len(q))
    lo = np.maximum(k - h[seg_of], starts[seg_of])
    hi = np.minimum(k + h[seg_of], (starts + lens - 1)[seg_of])
    cs = np.concatenate([np.zeros((1, 2)), np.cumsum(q, axis=0)])
    return (cs[hi + 1] - cs[lo]) / (hi - lo + 1)[:, None]


def segment_features(
    points: FloatArray,
    segments: list[IntArray],
    valid: NDArray[np.bool_] | None = None,
    *,
    origin: ArrayLike = (0.0, 0.0),
) -> FloatArray:
    """Shape features of each segment, columns as :data:`FEATURE_NAMES`.

    Args:
        points: ``(M, 2)`` float64, the scan (as given to :func:`segment_scan`).
        segments: per segment the indices of its points.
        valid: ``(M,)`` bool, the mask given to :func:`segment_scan`.
        origin: ``(2,)`` sensor position, metres.

    Returns:
        ``(S, F)`` float64 features, S segments.
    """
    pts = np.asarray(points, dtype=np.float64).reshape(-1, 2)
    o = np.asarray(origin, dtype=np.float64).reshape(2)
    out = np.zeros((len(segments), len(FEATURE_NAMES)))
    if not segments:
        return out
    ok = valid_mask(pts, valid)
    idx_ok = np.flatnonzero(ok)
    rng_all = np.hypot(*(pts - o).T)
    # all segments' points concatenated; per-segment sums with np.add.reduceat
    lens = np.array([len(s) for s in segments], dtype=np.int64)
    starts = np.concatenate([[0], np.cumsum(lens)[:-1]])
    flat = np.concatenate(segments)
    q = pts[flat]
    seg_of = np.repeat(np.arange(len(segments)), lens)

    def ssum(v: FloatArray) -> FloatArray:
        return np.add.reduceat(v, starts, axis=0)

    n = lens.astype(np.float64)
    c = ssum(q) / n[:, None]
    u = q - c[seg_of]
    sxx, syy, sxy = ssum(u[:, 0] ** 2), ssum(u[:, 1] ** 2), ssum(u[:, 0] * u[:, 1])
    # line fit: smallest eigenvalue of the 2×2 covariance
    tr, det = (sxx + syy) / n, (sxx * syy - sxy**2) / n**2
    lam_min = np.maximum(tr / 2.0 - np.sqrt(np.maximum(tr**2 / 4.0 - det, 0.0)), 0.0)
    line_res = np.sqrt(lam_min)
    # circle fit (Kåsa) in centred coordinates: centre = C⁻¹ Σ u |u|² / 2, r² = Σ|u|²/n + |centre|²
    b = (u**2).sum(1)
    sxb, syb = ssum(u[:, 0] * b), ssum(u[:, 1] * b)
    detc = sxx * syy - sxy**2
    good = detc > 1e-12 * (sxx + syy) ** 2
    safe = np.where(good, detc, 1.0)
    cx = 0.5 * (syy * sxb - sxy * syb) / safe
    cy = 0.5 * (sxx * syb - sxy * sxb) / safe
    rad2 = ssum(b) / n + cx**2 + cy**2
    good &= np.isfinite(rad2) & (rad2 > 0.0) & (rad2 <= _MAX_RADIUS**2)
    rad = np.where(good, np.sqrt(np.where(good, rad2, 1.0)), _MAX_RADIUS)
    dist = np.hypot(u[:, 0] - cx[seg_of], u[:, 1] - cy[seg_of]) - rad[seg_of]
    circ_res = np.where(good, np.sqrt(ssum(dist**2) / n), line_res)
    # bulge: signed distance of the returns from the chord first–last, toward the sensor positive
    first, last = pts[flat[starts]], pts[flat[starts + lens - 1]]
    chord = last - first
    width = np.hypot(chord[:, 0], chord[:, 1])
    nrm = np.stack([-chord[:, 1], chord[:, 0]], 1) / np.maximum(width, 1e-12)[:, None]
    flip = (first + last) / 2.0 - o
    nrm *= np.where((nrm * flip).sum(1) > 0.0, -1.0, 1.0)[:, None]
    bulge = np.where(width > 1e-9, ssum(((q - first[seg_of]) * nrm[seg_of]).sum(1)) / n, 0.0)
    extent = np.maximum.reduceat(np.hypot(u[:, 0], u[:, 1]), starts)
    # occlusion: the neighbouring valid returns behind (positive) or in front (negative) of the ends; no
    # return within ``_NEIGHBOUR_GAP`` rad of an end counts as free space behind it
    end_a, end_b = flat[starts], flat[starts + lens - 1]
    occ = np.ones((len(segments), 2))
    for col, ends, shift in ((0, end_a, -1), (1, end_b, 1)):
        j = np.searchsorted(idx_ok, ends) + shift
        inside = (j >= 0) & (j < idx_ok.size)
        jj = idx_ok[np.clip(j, 0, max(idx_ok.size - 1, 0))]
        va, vb = pts[jj] - o, pts[ends] - o
        gap = np.abs(np.arctan2(va[:, 0] * vb[:, 1] - va[:, 1] * vb[:, 0], (va * vb).sum(1)))
        use = inside & (gap <= _NEIGHBOUR_GAP)
        occ[use, col] = np.clip(rng_all[jj] - rng_all[ends], -1.0, 1.0)[use]
    span = np.abs(end_b - end_a) + 1
    out[:, 0] = n
    out[:, 1] = width
    out[:, 2] = np.hypot(*(c - o).T)
    out[:, 3] = line_res
    out[:, 4] = rad
    out[:, 5] = circ_res
    out[:, 6] = bulge
    out[:, 7] = occ.min(1)
    out[:, 8] = occ.max(1)
    out[:, 9] = np.minimum(n / span, 1.0)
    out[:, 10] = extent
    # boundary: steps between consecutive returns of a segment (the last step of each segment is unused),
    # along the outline averaged over ~``_OUTLINE_SCALE`` so range noise on dense returns (a leg near the
    # scanner) does not read as a jagged surface
    step = np.diff(_outline(q, seg_of, starts, lens, width), axis=0, append=q[-1:])
    last_of = starts + lens - 1
    step[last_of] = 0.0
    step_len = np.hypot(step[:, 0], step[:, 1])
    out[:, 11] = ssum(step_len) / np.maximum(width, 1e-3)
    # incidence: main axis (largest eigenvector of the covariance) against the beam through the centroid
    lam_max = tr - lam_min
    ax = np.stack([sxy, lam_max * n - sxx], 1)
    ax = np.where(np.hypot(ax[:, 0], ax[:, 1])[:, None] > 1e-12, ax, np.stack([lam_max * n - syy, sxy], 1))
    ax /= np.maximum(np.hypot(ax[:, 0], ax[:, 1]), 1e-12)[:, None]
    ray = (c - o) / np.maximum(np.hypot(*(c - o).T), 1e-12)[:, None]
    out[:, 12] = np.abs((ax * ray).sum(1))
    # turning angles between consecutive steps; sign so that convex toward the sensor is positive
    nxt = np.roll(step, -1, axis=0)
    ang = np.arctan2(step[:, 0] * nxt[:, 1] - step[:, 1] * nxt[:, 0], (step * nxt).sum(1))
    use = (step_len > 1e-9) & (np.roll(step_len, -1) > 1e-9)
    use[last_of] = False
    cnt = np.maximum(ssum(use.astype(np.float64)), 1.0)
    # beams sweep counter-clockwise: a surface bulging toward the sensor turns clockwise (negative)
    out[:, 13] = ssum(np.where(use, np.abs(ang), 0.0)) / cnt
    out[:, 14] = -ssum(np.where(use, ang, 0.0)) / cnt
    return out
