"""The thesis's green/white board: per-face homographies (Eqs. 3.14–3.15) and spherical correspondences.

The board stands vertical; its lower part is green, its upper part white, and the colour boundary is at
the laser's height, so the laser points on the board lie on the image of that boundary.

Laser: a run of consecutive beams (split where neighbours are more than 8 cm apart) is the board when a
line fits it (rms < 1.5 cm), it is about ``width`` long and both neighbouring beams lie farther away (the
board stands in front of the background). While the board holds still, the points of all its scans are
pooled: a line fit and the known width give its two ends at the laser plane.

Image: the panorama taken in the middle of each still period; a 90° perspective view is centred on the
green blob (and, for the homography, the nearest cube face is used when the board lies wholly on it). On
a view the green/white boundary is found per column with sub-pixel
interpolation of a soft green mask and fitted with a line ``A·u + B·v = 1`` (face px); the board's vertical
edges below the boundary are fitted the same way, and their crossings with the boundary line are the
board's ends, mapped back to panorama pixels.

Per face (thesis): a homography ``H`` maps laser ``(x, y, 1)`` to the face; every board laser point ``p``
gives ``lᵀ H p = 0`` with ``l = (A, B, −1)``. The stacked rows' SVD null vector is the initial value,
then least squares on the algebraic residual (Eq. 3.14), then Gauss–Newton (Levenberg–Marquardt) on the
pixel point-to-line distance (Eq. 3.15). Accuracy (thesis Table 4.4): the share of board laser points
projected within ``hit_px`` of their board's line.

Spherical: the two board ends per still period give ``x, y, z, u, v`` rows for
:func:`studio.calibrate.extrinsics.fit_extrinsics` (z = the laser plane's height in the base frame).
"""

from __future__ import annotations

import math
from collections.abc import Iterable
from dataclasses import dataclass, field
from typing import Any

import cv2
import numpy as np
from numpy.typing import NDArray
from scipy.optimize import least_squares

from studio.calibrate.targets import ScanPoints, TargetError, TargetTrack
from studio.geometry.base import pixel_to_angles
from studio.geometry.render import ViewRenderer
from studio.geometry.views import PerspectiveView, cube_faces
from studio.io.base import Panorama

__all__ = [
    "BoardCalibration",
    "FaceHomography",
    "board_calibration",
    "board_in_scan",
    "board_line_in_face",
    "fit_face_homography",
]

FloatArray = NDArray[np.float64]
SPLIT_M = 0.08
FACES = ("front", "left", "back", "right")
_RENDERER = ViewRenderer(max_entries=8)


# ---------------------------------------------------------------------------------------------- laser
def _line_fit(pts: FloatArray) -> tuple[FloatArray, FloatArray, float]:
    """Centre, unit direction and rms distance of a 2-D total least squares line."""
    c = pts.mean(axis=0)
    _, s, vt = np.linalg.svd(pts - c, full_matrices=False)
    return c, vt[0], float(s[-1] / math.sqrt(max(pts.shape[0], 1)))


def board_in_scan(scan: ScanPoints, *, width: float) -> NDArray[np.int64] | None:
    """Beam indices of the board in one scan (the closest qualifying run), or None."""
    p = scan.points
    valid = np.nonzero(np.isfinite(p[:, 0]))[0]
    if valid.size < 5:
        return None
    q = p[valid, :2]
    gap = np.hypot(*(q[1:] - q[:-1]).T) > SPLIT_M
    best, best_r = None, math.inf
    rng = np.hypot(q[:, 0] - scan.origin[0], q[:, 1] - scan.origin[1])
    for idx in np.split(np.arange(valid.size), np.nonzero(gap)[0] + 1):
        if idx.size < 8:
            continue
        c, d, rms = _line_fit(q[idx])
        proj = (q[idx] - c) @ d
        length = float(proj.max() - proj.min())
        if rms > 0.015 or not (0.6 * width <= length <= width + 0.1):
            continue
        lo, hi = idx[0], idx[-1]
        if lo == 0 or hi == valid.size - 1:
            continue
        if rng[lo - 1] < rng[lo] + 0.15 or rng[hi + 1] < rng[hi] + 0.15:
            continue
        mean_r = float(rng[idx].mean())
        if mean_r < best_r:
            best, best_r = valid[idx], mean_r
    return best


# ---------------------------------------------------------------------------------------------- image
def _green(img: NDArray[np.uint8]) -> NDArray[np.float32]:
    """Soft mask in [0, 1] of the board's green: ``G − (R + B) / 2`` over the green's own level.

    The measure is linear in the mix of green with white (or the grey/beige background), so its 0.5
    crossing is the 50 % coverage point of an edge pixel (a saturation threshold would not be).
    """
    f = img.astype(np.float32)
    m = f[..., 1] - 0.5 * (f[..., 0] + f[..., 2])
    strong = m[m > 30.0]
    level = float(np.percentile(strong, 90)) if strong.size >= 20 else 110.0
    return np.clip(m / max(level, 30.0), 0.0, 1.0).astype(np.float32)


def _crossings(g: FloatArray, *, up: bool) -> float:
    """Sub-pixel position (continuous px) where a 1-D profile ``g`` (green ~1 at its end, ~0 at its start
    when ``up`` is False) crosses 0.5, searched from the green end; NaN if none."""
    prof = g[::-1] if up else g
    n = prof.size
    idx = np.nonzero(prof >= 0.5)[0]
    if idx.size == 0 or idx[0] == 0:
        return math.nan
    k = int(idx[0])
    a, b = prof[k - 1], prof[k]
    x = (k - 1) + (0.5 - a) / max(b - a, 1e-6) + 0.5  # continuous coordinate of the crossing
    return (n - x) if up else x


def _fit_line_pts(pts: FloatArray) -> FloatArray | None:
    """Homogeneous line ``(a, b, c)`` with ``a² + b² = 1`` through 2-D points (robust: two trims)."""
    if pts.shape[0] < 5:
        return None
    keep = np.ones(pts.shape[0], bool)
    for _ in range(3):
        c, d, _ = _line_fit(pts[keep])
        n = np.array([-d[1], d[0]])
        dist = np.abs((pts - c) @ n)
        thr = max(3.0 * float(np.median(dist[keep])) * 1.4826, 0.3)
        keep = dist <= thr
        if keep.sum() < 5:
            return None
    c, d, _ = _line_fit(pts[keep])
    n = np.array([-d[1], d[0]])
    return np.array([n[0], n[1], -float(n @ c)])


def board_line_in_face(face: NDArray[np.uint8]) -> tuple[FloatArray, FloatArray, FloatArray] | None:
    """The board's boundary line and its two ends in a face image.

    Returns:
        ``line`` ``(a, b, c)`` (``a·u + b·v + c = 0``, face px, continuous convention) and the left and right
        ends ``(u, v)`` (crossings with the board's edge lines), or None.
    """
    g = _green(face)
    mask = (g > 0.5).astype(np.uint8)
    n, _, stats, _ = cv2.connectedComponentsWithStats(mask)
    if n <= 1:
        return None
    k = 1 + int(np.argmax(stats[1:, cv2.CC_STAT_AREA]))
    x0, y0, w, h = (int(stats[k, i]) for i in range(4))
    if stats[k, cv2.CC_STAT_AREA] < 200 or w < 20:
        return None
    pts = []
    for col in range(x0 + max(w // 10, 2), x0 + w - max(w // 10, 2)):
        top = max(y0 - 10, 1)
        prof = g[top : y0 + h // 2 + 1, col].astype(np.float64)
        y = _crossings(prof, up=False)
        if math.isfinite(y):
            pts.append((col + 0.5, top + y))
    line = _fit_line_pts(np.array(pts)) if pts else None
    if line is None or abs(line[1]) < 1e-6:
        return None
    ends = []
    for side in (0, 1):
        col = x0 + 2 if side == 0 else x0 + w - 3
        rows_g = np.nonzero(mask[:, col])[0]
        if rows_g.size < 8:
            return None
        epts = []
        for row in range(int(rows_g[0]) + 3, int(rows_g[-1]) - 2):
            if side == 0:
                lo = max(x0 - 10, 1)
                x = _crossings(g[row, lo : x0 + w // 2].astype(np.float64), up=False)
                if math.isfinite(x):
                    epts.append((lo + x, row + 0.5))
            else:
                hi = min(x0 + w + 10, face.shape[1] - 1)
                x = _crossings(g[row, x0 + w // 2 : hi].astype(np.float64), up=True)
                if math.isfinite(x):
                    epts.append((x0 + w // 2 + x, row + 0.5))
        edge = _fit_line_pts(np.array(epts)) if len(epts) >= 5 else None
        if edge is None:
            return None
        p = np.cross(line, edge)
        if abs(p[2]) < 1e-12:
            return None
        ends.append(p[:2] / p[2])
    return line, ends[0], ends[1]


# ---------------------------------------------------------------------------------------------- homography
@dataclass(frozen=True)
class FaceHomography:
    """The thesis's per-face homography (laser plane → face pixels).

    Attributes:
        face: face name; H: (3, 3) homography, laser ``(x, y, 1)`` (base frame, metres) → face px.
        n_boards: boards (still periods) used; n_points: laser points used.
        dist_px: (n_points,) final point-to-line distances, px.
    """

    face: str
    H: FloatArray
    n_boards: int
    n_points: int
    dist_px: FloatArray = field(repr=False)


def _dist(H: FloatArray, pts: FloatArray, lines: FloatArray) -> FloatArray:
    q = pts @ H.T
    uv = q[:, :2] / q[:, 2:3]
    out: FloatArray = (np.einsum("ij,ij->i", uv, lines[:, :2]) + lines[:, 2]) / np.hypot(
        lines[:, 0], lines[:, 1]
    )
    return out


def fit_face_homography(face: str, pts: FloatArray, lines: FloatArray, *, n_boards: int) -> FaceHomography:
    """Fit ``H`` to laser points ``(N, 2)`` m and their boards' lines ``(N, 3)`` ``(a, b, c)`` face px.

    SVD null vector of the stacked ``lᵀ H p = 0`` rows, least squares on the algebraic residual (Eq. 3.14)
    and Gauss–Newton on the pixel point-to-line distance (Eq. 3.15), in normalised coordinates.
    """
    p = np.column_stack([pts, np.ones(pts.shape[0])])
    # normalise: laser points to zero mean / unit spread; lines to unit (a, b)
    mu, sc = p[:, :2].mean(axis=0), float(np.sqrt(2) / max(p[:, :2].std(axis=0).mean(), 1e-9))
    T = np.array([[sc, 0, -sc * mu[0]], [0, sc, -sc * mu[1]], [0, 0, 1.0]])
    pn = p @ T.T
    ln = lines / np.linalg.norm(lines, axis=1, keepdims=True)
    A = np.einsum("ni,nj->nij", ln, pn).reshape(-1, 9)
    _, _, vt = np.linalg.svd(A, full_matrices=False)
    h0 = vt[-1]

    def alg(h: FloatArray) -> FloatArray:  # Eq. 3.14, with ‖h‖ = 1 held by a soft constraint
        out: FloatArray = np.append(A @ h, 10.0 * (h @ h - 1.0))
        return out

    h1 = least_squares(alg, h0, method="lm").x
    Hn = h1.reshape(3, 3)

    def geo(h: FloatArray) -> FloatArray:  # Eq. 3.15: pixel point-to-line distances
        return _dist(h.reshape(3, 3), pn, lines)

    h2 = least_squares(geo, Hn.ravel() / np.linalg.norm(Hn), method="lm").x
    H = h2.reshape(3, 3) @ T
    H /= H[2, 2] if abs(H[2, 2]) > 1e-12 else np.linalg.norm(H)
    return FaceHomography(face, H, n_boards, pts.shape[0], _dist(H, p, lines))


# ---------------------------------------------------------------------------------------------- all
@dataclass(frozen=True)
class BoardCalibration:
    """Everything the board gives.

    Attributes:
        xyz, uv, stamp_ns: board-end correspondences (2 per still period), base frame metres / px / ns.
        faces: per-face homographies (faces with at least 4 boards).
        hit_px: the accuracy threshold, px; hit_share: share of board laser points within it (all faces).
        n_images, n_boards: panoramas read, still boards paired with a panorama; image_size: (W, H).
    """

    xyz: FloatArray
    uv: FloatArray
    stamp_ns: NDArray[np.int64]
    faces: dict[str, FaceHomography]
    hit_px: float
    hit_share: float | None
    n_images: int
    n_boards: int
    image_size: tuple[int, int]

    def to_json(self) -> dict[str, Any]:
        return {
            "n_boards": self.n_boards,
            "homography": {
                "hit_px": self.hit_px,
                "hit_share": None if self.hit_share is None else round(self.hit_share, 4),
                "faces": {
                    k: {
                        "n_boards": f.n_boards,
                        "n_points": f.n_points,
                        "mean_dist_px": round(float(np.abs(f.dist_px).mean()), 4),
                        "hit_share": round(float((np.abs(f.dist_px) <= self.hit_px).mean()), 4),
                        "H": [[round(float(x), 8) for x in row] for row in f.H],
                    }
                    for k, f in self.faces.items()
                },
            },
        }


def board_calibration(
    scans: list[ScanPoints],
    panoramas: Iterable[Panorama],
    *,
    width: float = 0.8,
    margin_s: float = 0.3,
    hit_px: float = 2.0,
    face_size: int | None = None,
) -> BoardCalibration:
    """Board correspondences and per-face homographies from a board calibration recording.

    Args:
        scans: the recording's scans in the base frame.
        panoramas: its panoramas (read once, in order).
        width: the board's width, metres.
        margin_s: a panorama is used when the board was still from ``margin_s`` before to ``margin_s``
            after its stamp (covers an unknown camera latency up to that).
        hit_px: accuracy threshold of the thesis measure, px.
        face_size: cube face size, px (default ``W / 3``).

    Raises:
        TargetError: no board in the scans or panoramas, or no still board seen by both.
    """
    stamps, vals, members = [], [], []
    for k, s in enumerate(scans):
        idx = board_in_scan(s, width=width)
        if idx is None:
            continue
        c, d, _ = _line_fit(s.points[idx, :2])
        stamps.append(s.stamp_ns)
        vals.append([c[0], c[1]])
        members.append((k, idx))
    if len(stamps) < 5:
        raise TargetError(
            f"no board of width {width:g} m found in the scans ({len(stamps)} scans with one); "
            "is this a board "
            "calibration recording, and is --board-width right?"
        )
    track = TargetTrack.build(np.array(stamps, dtype=np.int64), np.array(vals))
    order = np.argsort(np.array(stamps), kind="stable")
    periods = track.periods()
    # pooled laser points per still period
    pooled: dict[int, tuple[FloatArray, float]] = {}
    mem_sorted = [members[i] for i in order]
    for seg in range(periods.shape[0]):
        seg_pts = [
            scans[k].points[idx, :2]
            for (k, idx), sg in zip(mem_sorted, track.segment, strict=True)
            if sg == seg
        ]
        zs = [
            float(scans[k].origin[2])
            for (k, _), sg in zip(mem_sorted, track.segment, strict=True)
            if sg == seg
        ]
        if seg_pts:
            pooled[seg] = (np.concatenate(seg_pts), float(np.mean(zs)))
    # one panorama per still period (the one nearest the period's middle that is still within the margin)
    margin = int(margin_s * 1e9)
    chosen: dict[int, Panorama] = {}
    n_img = 0
    size = (0, 0)
    mid = periods.mean(axis=1) if periods.size else np.zeros(0)
    for pano in panoramas:
        n_img += 1
        size = (pano.width, pano.height)
        seg = track.still_at(pano.stamp_ns - margin, pano.stamp_ns + margin, periods)
        if seg < 0 or seg not in pooled:
            continue
        old = chosen.get(seg)
        if old is None or abs(pano.stamp_ns - mid[seg]) < abs(old.stamp_ns - mid[seg]):
            chosen[seg] = pano
    if not chosen:
        raise TargetError(f"no panorama of the {n_img} shows the board while it holds still")
    W, H = size
    view_size = int(face_size or round(W / 3))
    faces = cube_faces(view_size)
    xyz_rows, uv_rows, st_rows = [], [], []
    per_face: dict[str, list[tuple[FloatArray, FloatArray]]] = {k: [] for k in FACES}
    for seg, pano in sorted(chosen.items()):
        g = _green(
            np.asarray(cv2.resize(pano.image, (W // 4, H // 4), interpolation=cv2.INTER_AREA), np.uint8)
        )
        ys, xs = np.nonzero(g > 0.5)
        if xs.size < 10:
            continue
        az, el = pixel_to_angles(np.array([np.median(xs) * 4 + 2]), np.array([np.median(ys) * 4 + 2]), W, H)
        name = FACES[int(np.round(float(az[0]) / (math.pi / 2))) % 4]
        centred = PerspectiveView(float(az[0]), float(el[0]), math.pi / 2, view_size, view_size)
        found = board_line_in_face(_RENDERER.render(pano.image, centred))
        if found is None:
            continue
        _, e_left, e_right = found
        pts, z = pooled[seg]
        c, d, _ = _line_fit(pts)
        proj = (pts - c) @ d
        centre = c + d * 0.5 * (proj.max() + proj.min())
        ends = [centre - d * width / 2, centre + d * width / 2]
        # match laser ends to image ends by azimuth seen from the base origin (left = larger azimuth)
        a0 = math.atan2(centre[1], centre[0])
        rel = [((math.atan2(e[1], e[0]) - a0 + math.pi) % (2 * math.pi)) - math.pi for e in ends]
        left_end, right_end = (ends[0], ends[1]) if rel[0] > rel[1] else (ends[1], ends[0])
        for e3, e2 in ((left_end, e_left), (right_end, e_right)):
            uvp = centred.view_to_pano(e2[None, :], W, H)[0]
            xyz_rows.append([e3[0], e3[1], z])
            uv_rows.append(uvp)
            st_rows.append(pano.stamp_ns)
        # the thesis's homography needs the whole board on one cube face
        view: PerspectiveView = faces[name]
        ends_face = view.pano_to_view(np.array(uv_rows[-2:]), W, H)
        if not np.all(np.isfinite(ends_face)) or ends_face.min() < 5 or ends_face.max() > view.width - 5:
            continue
        on_face = board_line_in_face(_RENDERER.render(pano.image, view))
        if on_face is None:
            continue
        line = on_face[0]
        per_face[name].append((pts, line))
    if not xyz_rows:
        raise TargetError("the board's green/white boundary was not found on any cube face")
    homs: dict[str, FaceHomography] = {}
    for name, items in per_face.items():
        if len(items) < 4:
            continue
        pts = np.concatenate([p for p, _ in items])
        lines = np.concatenate([np.repeat(line[None, :], p.shape[0], axis=0) for p, line in items])
        homs[name] = fit_face_homography(name, pts, lines, n_boards=len(items))
    share = None
    if homs:
        d_all = np.concatenate([np.abs(h.dist_px) for h in homs.values()])
        share = float((d_all <= hit_px).mean())
    return BoardCalibration(
        xyz=np.array(xyz_rows),
        uv=np.array(uv_rows),
        stamp_ns=np.array(st_rows, dtype=np.int64),
        faces=homs,
        hit_px=hit_px,
        hit_share=share,
        n_images=n_img,
        n_boards=len(xyz_rows) // 2,
        image_size=size,
    )
