"""PanNote's ball target: ``x, y, z, u, v`` correspondences from a recording, without a trained network.

Laser: each scan is cut into runs of consecutive valid beams (split where neighbours are more than
:data:`SPLIT_M` apart); a run is the ball when a circle fits it (geometric least squares) with a radius
``r ≤ R`` and the arc bulges towards the laser. The ball's centre is ``h = sqrt(R² − r²)`` above the laser
plane (the ball is held with its centre above the plane). While the ball holds still, the points of every
scan of the still period are pooled into one circle fit per laser (millimetre precision).

Image: the ball's colour (saturated orange/red, HSV) on a reduced panorama gives its direction; a
perspective view centred on that direction is rendered, a soft colour mask's centroid re-centres the view
(three times: a sphere seen by a pinhole camera looking at its centre images as a circle centred on the
principal point, so the centroid converges to the centre's direction), and the centre's panorama pixel
follows exactly.

Time: a panorama is paired with the laser track at ``stamp − offset``. The camera pose is first fitted on
panoramas taken while the ball was still (for any offset within ``max_offset_s``), then the offset that
best explains the panoramas taken while it moved is searched (pixel residuals under that pose).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import cv2
import numpy as np
from numpy.typing import NDArray
from scipy.optimize import least_squares

from studio.calibrate.targets import ScanPoints, TargetError, TargetTrack
from studio.geometry.base import angles_to_pixel, pixel_to_angles, rays_to_angles
from studio.geometry.render import ViewRenderer
from studio.geometry.views import PerspectiveView

__all__ = [
    "SPLIT_M",
    "BallCorrespondences",
    "ball_correspondences",
    "ball_in_scan",
    "ball_track",
    "find_ball_in_panorama",
    "fit_ball_circle",
    "fit_circle",
]

FloatArray = NDArray[np.float64]
SPLIT_M = 0.08
_RENDERER = ViewRenderer(max_entries=16)


def fit_circle(pts: FloatArray, *, refine: bool = True) -> tuple[float, float, float, float]:
    """Circle through 2-D points (N, 2) m: algebraic (Kåsa) fit, then geometric least squares (``refine``).

    Returns:
        ``cx, cy, r, rms`` metres (rms of the radial residuals).
    """
    x, y = pts[:, 0], pts[:, 1]
    a = np.stack([x, y, np.ones_like(x)], axis=1)
    sol, *_ = np.linalg.lstsq(a, x * x + y * y, rcond=None)
    cx, cy = sol[0] / 2, sol[1] / 2
    r = math.sqrt(max(sol[2] + cx * cx + cy * cy, 1e-12))
    if not refine:
        return float(cx), float(cy), r, float(np.sqrt(np.mean((np.hypot(x - cx, y - cy) - r) ** 2)))

    def res(p: FloatArray) -> FloatArray:
        out: FloatArray = np.hypot(x - p[0], y - p[1]) - p[2]
        return out

    fit = least_squares(res, np.array([cx, cy, r]), method="lm")
    cx, cy, r = (float(v) for v in fit.x)
    return cx, cy, abs(r), float(np.sqrt(np.mean(fit.fun**2)))


def fit_ball_circle(pts: FloatArray, origin: FloatArray) -> tuple[float, float, float, float]:
    """Circle through a laser's hits on a round target, with residuals along the beams.

    Range noise moves a point along its beam, not along the circle's normal; near the arc's ends the two
    differ and point-to-circle residuals bias the radius low (−2.5 mm at 12 mm noise). Here the residual
    is measured range minus the range at which the beam from ``origin`` enters the circle (beams that
    miss it add their miss distance).

    Args:
        pts: (N, 2+) hit points, metres (only x, y used).
        origin: (2+,) the laser's position, metres.

    Returns:
        ``cx, cy, r, rms`` metres (rms of the range residuals).
    """
    cx, cy, r, _ = fit_circle(pts[:, :2])
    o = np.asarray(origin, dtype=np.float64)[:2]
    d = pts[:, :2] - o
    rho = np.hypot(d[:, 0], d[:, 1])
    d = d / np.maximum(rho, 1e-9)[:, None]

    def res(x: FloatArray) -> FloatArray:
        oc = o - x[:2]
        b = d @ oc
        disc = b * b - (oc @ oc - x[2] ** 2)
        t = -b - np.sqrt(np.maximum(disc, 0.0))
        return np.concatenate([rho - t, np.sqrt(np.maximum(-disc, 0.0))])

    fit = least_squares(res, np.array([cx, cy, r]), method="lm")
    n = pts.shape[0]
    return float(fit.x[0]), float(fit.x[1]), abs(float(fit.x[2])), float(np.sqrt(np.mean(fit.fun[:n] ** 2)))


def _runs(points: FloatArray) -> list[NDArray[np.int64]]:
    """Indices of runs of consecutive valid beams, split where neighbours are more than SPLIT_M apart."""
    valid = np.nonzero(np.isfinite(points[:, 0]))[0]
    if valid.size == 0:
        return []
    p = points[valid, :2]
    gap = np.hypot(*(p[1:] - p[:-1]).T) > SPLIT_M
    return [valid[g] for g in np.split(np.arange(valid.size), np.nonzero(gap)[0] + 1)]


def _ball_fit(pts: FloatArray, origin: FloatArray, radius: float) -> tuple[float, float, float, float] | None:
    if pts.shape[0] < 5:
        return None
    chord = float(np.hypot(*(pts[-1, :2] - pts[0, :2])))
    if not 0.05 < chord < 2.2 * radius:
        return None
    cx, cy, r, rms = fit_circle(pts[:, :2], refine=False)
    if not (0.2 * radius < r < radius + 0.03) or rms > 0.025:
        return None
    mean = pts[:, :2].mean(axis=0)
    if math.hypot(cx - origin[0], cy - origin[1]) <= math.hypot(mean[0] - origin[0], mean[1] - origin[1]):
        return None  # concave towards the laser: a corner, not a ball
    return cx, cy, r, rms


def ball_in_scan(scan: ScanPoints, *, radius: float) -> tuple[FloatArray, float] | None:
    """The ball's circle in one scan: ``(centre x, y, circle radius r)`` metres and the fit rms, or None.

    When several runs qualify, the one with the smallest rms wins.
    """
    best: tuple[FloatArray, float] | None = None
    for idx in _runs(scan.points):
        fit = _ball_fit(scan.points[idx], scan.origin, radius)
        if fit is not None and (best is None or fit[3] < best[1]):
            best = (np.array(fit[:3]), fit[3])
    return best


def _height(r: float, radius: float, laser_z: float) -> float:
    return laser_z + math.sqrt(max(radius * radius - r * r, 0.0))


def ball_track(scans: list[ScanPoints], *, radius: float) -> tuple[TargetTrack, dict[int, FloatArray]]:
    """The ball's track (values ``x, y, z, r`` per scan) and, per still period, a pooled estimate.

    Returns:
        The track and ``{period: (x, y, z, r)}`` from one circle fit per laser over all the period's scans
        (averaged over lasers, weighted by points).

    Raises:
        TargetError: no scan shows the ball.
    """
    stamps, values, idx_of = [], [], []
    for k, s in enumerate(scans):
        hit = ball_in_scan(s, radius=radius)
        if hit is None:
            continue
        c, _ = hit
        stamps.append(s.stamp_ns)
        values.append([c[0], c[1], _height(c[2], radius, float(s.origin[2])), c[2]])
        idx_of.append(k)
    if len(stamps) < 5:
        raise TargetError(
            f"no ball of radius {radius:g} m found in the scans ({len(stamps)} scans with a circle); "
            "is this a ball calibration recording, and is --ball-radius right?"
        )
    track = TargetTrack.build(np.array(stamps, dtype=np.int64), np.array(values))
    order = np.argsort(np.array(stamps), kind="stable")
    scan_idx = np.array(idx_of)[order]
    pooled: dict[int, FloatArray] = {}
    for seg in np.unique(track.segment[track.segment >= 0]):
        members = scan_idx[track.segment == seg]
        centre = np.median(track.values[track.segment == seg, :2], axis=0)
        ests, weights = [], []
        for topic in sorted({scans[i].topic for i in members}):
            pts_l, origin = [], None
            for i in members:
                s = scans[i]
                if s.topic != topic:
                    continue
                near = np.hypot(s.points[:, 0] - centre[0], s.points[:, 1] - centre[1]) < radius + 0.05
                pts_l.append(s.points[near])
                origin = s.origin
            pts = np.concatenate(pts_l) if pts_l else np.zeros((0, 3))
            if pts.shape[0] < 10 or origin is None:
                continue
            cx, cy, r, _ = fit_ball_circle(pts, origin)
            ests.append([cx, cy, _height(r, radius, float(origin[2])), r])
            weights.append(pts.shape[0])
        if ests:
            pooled[int(seg)] = np.average(np.array(ests), axis=0, weights=np.array(weights, dtype=float))
    return track, pooled


# ---------------------------------------------------------------------------------------------- image
def _orange(img: NDArray[np.uint8]) -> NDArray[np.float32]:
    """Soft mask in [0, 1] of saturated orange/red pixels (hue ≤ 20° or ≥ 340°, saturation ≥ ~45 %)."""
    hsv = cv2.cvtColor(img, cv2.COLOR_BGR2HSV)
    h = hsv[..., 0].astype(np.float32)
    s = hsv[..., 1].astype(np.float32)
    val = hsv[..., 2].astype(np.float32)
    hue_ok = ((h <= 12) | (h >= 170)) & (val >= 60)
    soft = np.clip((s - 60.0) / 120.0, 0.0, 1.0)
    return np.where(hue_ok, soft, 0.0).astype(np.float32)


def find_ball_in_panorama(
    img: NDArray[np.uint8], *, min_area_px: int = 20, iterations: int = 4, view_px: int = 320
) -> tuple[float, float, float] | None:
    """The ball's centre pixel in an equirectangular panorama.

    Args:
        img: BGR panorama (H, W, 3).
        min_area_px: smallest blob on the 1/4-size panorama.
        iterations: re-centring steps of the perspective view.
        view_px: size of the square perspective view, px.

    Returns:
        ``u, v`` px (continuous convention) and the ball's angular radius, rad; None without a ball.
    """
    H, W = img.shape[:2]
    small = np.asarray(cv2.resize(img, (W // 4, H // 4), interpolation=cv2.INTER_AREA), np.uint8)
    mask = (_orange(small) > 0.5).astype(np.uint8)
    n, _lab, stats, cent = cv2.connectedComponentsWithStats(np.concatenate([mask, mask], axis=1))
    if n <= 1:
        return None
    best = 1 + int(np.argmax(stats[1:, cv2.CC_STAT_AREA]))
    if stats[best, cv2.CC_STAT_AREA] < min_area_px:
        return None
    u0 = (cent[best, 0] + 0.5) * 4 % W
    v0 = (cent[best, 1] + 0.5) * 4
    az, el = pixel_to_angles(np.array([u0]), np.array([v0]), W, H)
    alpha = math.sqrt(stats[best, cv2.CC_STAT_AREA] / math.pi) * 4 * 2 * math.pi / W
    fov = min(max(6.0 * alpha, math.radians(8)), math.radians(100))
    az_f, el_f = float(az[0]), float(el[0])
    for _ in range(iterations):
        view = PerspectiveView(az_f, max(min(el_f, 1.5), -1.5), fov, view_px, view_px)
        w = _orange(_RENDERER.render(img, view))
        tot = float(w.sum())
        if tot < 5.0:
            return None
        ys, xs = np.mgrid[0:view_px, 0:view_px]
        cu = float((w * (xs + 0.5)).sum() / tot)
        cv = float((w * (ys + 0.5)).sum() / tot)
        ray = view.rays(np.array([[cu, cv]]))
        a2, e2 = rays_to_angles(ray)
        az_f, el_f = float(a2[0]), float(e2[0])
        alpha = math.atan(math.sqrt(tot / math.pi) / view.focal)
        fov = min(max(4.0 * alpha, math.radians(8)), math.radians(100))
    u, v = angles_to_pixel(np.array([az_f]), np.array([el_f]), W, H)
    return float(u[0]), float(v[0]), alpha


# ---------------------------------------------------------------------------------------------- pairing
@dataclass(frozen=True)
class BallCorrespondences:
    """Correspondences of the ball's centre.

    Attributes:
        xyz: (N, 3) centre in the base frame, metres.
        uv: (N, 2) its panorama pixel, px.
        stamp_ns: (N,) image header stamps, ns.
        still: (N,) True where the ball held still around the image (those rows fit the pose).
        offset_s: image stamp minus capture time found by the search, s (None: not searched / no motion).
        offset_curve: ``(offset s, median residual px)`` of the search.
        n_images: panoramas read; n_ball_images: those showing the ball.
        image_size: ``(W, H)`` px.
    """

    xyz: FloatArray
    uv: FloatArray
    stamp_ns: NDArray[np.int64]
    still: NDArray[np.bool_]
    offset_s: float | None
    offset_curve: list[tuple[float, float]] = field(default_factory=list)
    n_images: int = 0
    n_ball_images: int = 0
    image_size: tuple[int, int] = (0, 0)


def ball_correspondences(
    scans: list[ScanPoints],
    detections: list[tuple[int, float, float]],
    *,
    radius: float,
    image_size: tuple[int, int],
    max_offset_s: float = 0.5,
    offset_step_s: float = 0.01,
    n_images: int = 0,
) -> BallCorrespondences:
    """Pair the ball in the panoramas (``(stamp_ns, u, v)``) with the ball in the scans.

    Args:
        scans: the recording's scans (:func:`studio.calibrate.targets.read_scans`).
        detections: the ball's centre pixel per panorama.
        radius: the ball's radius, metres.
        image_size: panorama ``(W, H)`` px.
        max_offset_s: the time offset is searched in ``[-max_offset_s, max_offset_s]`` s (0: no search).
        offset_step_s: search step, s.
        n_images: panoramas read (for the report).

    Raises:
        TargetError: no ball in the scans or panoramas, or too few still pairs to fit a pose.
    """
    from studio.calibrate.extrinsics import CalibrationError, fit_extrinsics, pixel_residuals

    if not detections:
        raise TargetError(f"no ball found in the {n_images} panoramas (orange/red, saturated)")
    track, pooled = ball_track(scans, radius=radius)
    margin = int((abs(max_offset_s) + 0.1) * 1e9)

    periods = track.periods()

    def pair(offset_s: float, *, still_only: bool) -> list[tuple[int, FloatArray, int]]:
        """(detection index, xyz, still period or -1) of the panoramas the laser track covers."""
        out = []
        off = int(offset_s * 1e9)
        for k, (t, _u, _v) in enumerate(detections):
            if still_only:
                seg = track.still_at(t - margin, t + margin, periods)
            else:
                seg = track.still_at(t - off - int(0.1e9), t - off + int(0.1e9), periods)
            if seg >= 0 and seg in pooled:
                out.append((k, pooled[seg][:3], seg))
                continue
            if still_only:
                continue
            val = track.at(t - off)
            if val is not None:
                out.append((k, val[:3], -1))
        return out

    W, H = image_size
    uv_all = np.array([[u, v] for _, u, v in detections])
    stamps_all = np.array([t for t, _, _ in detections], dtype=np.int64)

    def rows_of(
        offset_s: float, *, still_only: bool
    ) -> tuple[FloatArray, FloatArray, NDArray[np.int64], NDArray[np.bool_]]:
        """Still periods averaged to one row each (uv and stamp means), then the moving rows."""
        groups: dict[int, list[int]] = {}
        out_xyz, out_uv, out_t, out_still = [], [], [], []
        for k, x, seg in pair(offset_s, still_only=still_only):
            if seg >= 0:
                groups.setdefault(seg, []).append(k)
            else:
                out_xyz.append(x)
                out_uv.append(uv_all[k])
                out_t.append(stamps_all[k])
                out_still.append(False)
        for key, ks in sorted(groups.items()):
            uvs = uv_all[ks]
            du = (uvs[:, 0] - uvs[0, 0] + W / 2) % W - W / 2
            out_xyz.insert(0, pooled[key][:3])
            out_uv.insert(0, np.array([(uvs[0, 0] + du.mean()) % W, uvs[:, 1].mean()]))
            out_t.insert(0, int(np.mean(stamps_all[ks])))
            out_still.insert(0, True)
        return (
            np.array(out_xyz).reshape(-1, 3),
            np.array(out_uv).reshape(-1, 2),
            np.array(out_t, dtype=np.int64),
            np.array(out_still, dtype=bool),
        )

    xyz0, uv0, _, _ = rows_of(0.0, still_only=True)
    if xyz0.shape[0] < 6:
        raise TargetError(
            f"the ball holds still at only {xyz0.shape[0]} stations seen by the camera (need 6): hold it "
            f"still for at least {2 * max_offset_s + 0.4:.1f} s at each station"
        )
    try:
        fit0 = fit_extrinsics(xyz0, uv0, image_size=(W, H))
    except CalibrationError as exc:
        raise TargetError(f"the still ball positions do not give a camera pose: {exc}") from None
    offset: float | None = None
    curve: list[tuple[float, float]] = []
    if max_offset_s > 0:
        scores: dict[float, float] = {}

        def score(off: float) -> float:
            off = round(off, 6)
            if off not in scores:
                xyz, uv, _, still = rows_of(off, still_only=False)
                if int((~still).sum()) < 3:
                    scores[off] = math.inf
                else:
                    res = pixel_residuals(fit0.pose, xyz[~still], uv[~still], image_size=(W, H))
                    scores[off] = float(np.median(np.hypot(res[:, 0], res[:, 1])))
            return scores[off]

        coarse = 5 * offset_step_s  # coarse grid, then the fine step around its best
        grid = np.arange(-max_offset_s, max_offset_s + 1e-9, coarse)
        c_best = min(grid, key=lambda o: score(float(o)))
        fine = np.arange(c_best - coarse, c_best + coarse + 1e-9, offset_step_s)
        best_off = min(fine, key=lambda o: score(float(o)))
        if math.isfinite(score(float(best_off))):
            offset = round(float(best_off), 6)
        curve = sorted((o, round(v, 4)) for o, v in scores.items() if math.isfinite(v))
    xyz_f, uv_f, t_f, still_f = rows_of(offset if offset is not None else 0.0, still_only=False)
    return BallCorrespondences(
        xyz=xyz_f,
        uv=uv_f,
        stamp_ns=t_f,
        still=still_f,
        offset_s=offset,
        offset_curve=curve,
        n_images=n_images,
        n_ball_images=len(detections),
        image_size=(W, H),
    )
