"""Intrinsics check of the panorama: a checkerboard on the cube faces (issue #7 part 1, thesis Table 4.1).

Each panorama is cut into the four horizontal cube faces (90°, ``f = size / 2``); the checkerboard's inner
corners are found with OpenCV (``findChessboardCornersSB``, after ``findChessboardCorners``' fast
presence check). Per face, over the views that show the board:

* **free** model: ``cv2.calibrateCamera`` (fx, fy, cx, cy, k1, k2, p1, p2) — its mean reprojection error
  is the per-face number of the thesis's Table 4.1;
* **ideal** model: the ideal spherical camera's face, ``fx = fy = size / 2``, principal point at the face
  centre, no distortion; only the board poses are fitted (``solvePnP``), and its mean reprojection error
  is reported beside the free one.

Verdict: the panorama *behaves as the ideal spherical camera* when, on every face with enough views, the
ideal model's error is at most ``IDEAL_RATIO · free + IDEAL_MARGIN_PX`` (the free model has 8 more
parameters and always fits a little better); otherwise it *needs a correction model* (e.g. per-lens
parallax of a dual-fisheye camera), and the per-face numbers say where. The free focal lengths are
reported but not judged: with a few near-frontal views they trade off against the distortion terms and
the board distance (a few % on an ideal face).

Pixel convention: OpenCV's corners have pixel centres at integers; the ideal principal point is therefore
``size / 2 - 0.5`` (see :mod:`studio.geometry.views`).
"""

from __future__ import annotations

import math
from collections.abc import Iterable
from dataclasses import dataclass, field
from typing import Any

import cv2
import numpy as np
from numpy.typing import NDArray

from studio.calibrate.targets import TargetError
from studio.geometry.render import ViewRenderer
from studio.geometry.views import cube_faces

__all__ = [
    "FACES",
    "IDEAL_MARGIN_PX",
    "IDEAL_RATIO",
    "FaceIntrinsics",
    "IntrinsicsReport",
    "calibrate_faces",
    "find_corners",
]

FloatArray = NDArray[np.float64]
FACES = ("front", "left", "back", "right")
IDEAL_MARGIN_PX = 0.02
IDEAL_RATIO = 1.2
MIN_VIEWS = 3


def find_corners(face: NDArray[np.uint8], pattern: tuple[int, int]) -> FloatArray | None:
    """Inner corners ``(N, 2)`` (OpenCV pixel convention) of a checkerboard with ``pattern`` inner corners
    (columns, rows) in a face image, or None."""
    gray = cv2.cvtColor(face, cv2.COLOR_BGR2GRAY) if face.ndim == 3 else face
    ok, _ = cv2.findChessboardCorners(
        gray, pattern, flags=cv2.CALIB_CB_FAST_CHECK | cv2.CALIB_CB_ADAPTIVE_THRESH
    )
    if not ok:
        return None
    ok, corners = cv2.findChessboardCornersSB(gray, pattern, flags=cv2.CALIB_CB_ACCURACY)
    if not ok or corners is None:
        return None
    out: FloatArray = corners.reshape(-1, 2).astype(np.float64)
    return out


@dataclass(frozen=True)
class FaceIntrinsics:
    """One cube face's calibration.

    Attributes:
        face: face name; size: face size, px; n_views: views with the board.
        err_free_px: mean reprojection error of the free model, px (thesis Table 4.1).
        err_ideal_px: mean reprojection error of the ideal spherical face, px.
        fx, fy, cx, cy: free intrinsics, px (OpenCV convention); dist: ``k1 k2 p1 p2 k3``.
        f_ideal: ``size / 2``, px.
    """

    face: str
    size: int
    n_views: int
    err_free_px: float = math.nan
    err_ideal_px: float = math.nan
    fx: float = math.nan
    fy: float = math.nan
    cx: float = math.nan
    cy: float = math.nan
    dist: tuple[float, ...] = ()
    f_ideal: float = math.nan

    def ideal(self) -> bool | None:
        """Whether this face behaves as the ideal face (None: too few views)."""
        if self.n_views < MIN_VIEWS:
            return None
        return bool(self.err_ideal_px <= IDEAL_RATIO * self.err_free_px + IDEAL_MARGIN_PX)


@dataclass(frozen=True)
class IntrinsicsReport:
    """Per-face intrinsics and the verdict.

    Attributes:
        faces: per-face results (faces without views included, ``n_views`` 0).
        image_size: panorama ``(W, H)``; face_size: px; n_panoramas: panoramas read.
        verdict: ``"ideal"`` or ``"needs correction"``.
        reason: one line that explains the verdict.
    """

    faces: dict[str, FaceIntrinsics]
    image_size: tuple[int, int]
    face_size: int
    n_panoramas: int
    verdict: str
    reason: str
    extra: dict[str, Any] = field(default_factory=dict)

    def to_json(self) -> dict[str, Any]:
        return {
            "verdict": self.verdict,
            "reason": self.reason,
            "image_size": list(self.image_size),
            "face_size": self.face_size,
            "n_panoramas": self.n_panoramas,
            "faces": {
                k: {
                    "n_views": f.n_views,
                    "err_free_px": _r(f.err_free_px),
                    "err_ideal_px": _r(f.err_ideal_px),
                    "fx": _r(f.fx),
                    "fy": _r(f.fy),
                    "cx": _r(f.cx),
                    "cy": _r(f.cy),
                    "f_ideal": _r(f.f_ideal),
                    "dist": [_r(d, 6) for d in f.dist],
                    "ideal": f.ideal(),
                }
                for k, f in self.faces.items()
            },
        }

    def table(self) -> str:
        lines = [
            f"{'face':<6} {'views':>5} {'err free px':>11} {'err ideal px':>12} "
            f"{'fx':>8} {'fy':>8} {'f ideal':>8}"
        ]
        for k, f in self.faces.items():
            lines.append(
                f"{k:<6} {f.n_views:>5} {f.err_free_px:>11.3f} {f.err_ideal_px:>12.3f} "
                f"{f.fx:>8.2f} {f.fy:>8.2f} "
                f"{f.f_ideal:>8.2f}"
            )
        lines.append(f"verdict: {self.verdict} — {self.reason}")
        return "\n".join(lines)


def _r(x: float, nd: int = 4) -> float | None:
    return None if not math.isfinite(x) else round(float(x), nd)


def _object_points(pattern: tuple[int, int], square: float) -> NDArray[np.float32]:
    nx, ny = pattern
    g = np.zeros((nx * ny, 3), np.float32)
    g[:, :2] = np.mgrid[0:nx, 0:ny].T.reshape(-1, 2) * square
    return g


def _mean_err(
    obj: list[NDArray[np.float32]],
    img: list[NDArray[np.float32]],
    K: FloatArray,
    dist: FloatArray,
    rvecs: Any,
    tvecs: Any,
) -> float:
    errs = []
    for o, i, r, t in zip(obj, img, rvecs, tvecs, strict=True):
        proj, _ = cv2.projectPoints(o, r, t, K, dist)
        errs.append(np.linalg.norm(proj.reshape(-1, 2) - i.reshape(-1, 2), axis=1))
    return float(np.mean(np.concatenate(errs)))


def _face(
    name: str, size: int, obj: list[NDArray[np.float32]], img: list[NDArray[np.float32]]
) -> FaceIntrinsics:
    f0 = size / 2.0
    if len(img) < MIN_VIEWS:
        return FaceIntrinsics(name, size, len(img), f_ideal=f0)
    K0 = np.array([[f0, 0, size / 2 - 0.5], [0, f0, size / 2 - 0.5], [0, 0, 1.0]])
    flags = cv2.CALIB_USE_INTRINSIC_GUESS | cv2.CALIB_FIX_K3
    _, K, dist, rvecs, tvecs = cv2.calibrateCamera(
        obj, img, (size, size), K0.copy(), np.zeros(5), flags=flags
    )
    err_free = _mean_err(obj, img, np.asarray(K, np.float64), np.asarray(dist, np.float64), rvecs, tvecs)
    zero = np.zeros(5)
    rv, tv = [], []
    for o, i in zip(obj, img, strict=True):
        _, r, t = cv2.solvePnP(o, i, K0, zero, flags=cv2.SOLVEPNP_ITERATIVE)
        r, t = cv2.solvePnPRefineLM(o, i, K0, zero, r, t)
        rv.append(r)
        tv.append(t)
    err_ideal = _mean_err(obj, img, K0, zero, rv, tv)
    return FaceIntrinsics(
        name, size, len(img), err_free, err_ideal,
        float(K[0, 0]), float(K[1, 1]), float(K[0, 2]), float(K[1, 2]),
        tuple(float(d) for d in dist.ravel()[:5]), f0,
    )  # fmt: skip


def calibrate_faces(
    panoramas: Iterable[NDArray[np.uint8]],
    *,
    pattern: tuple[int, int] = (8, 5),
    square: float = 0.07,
    face_size: int | None = None,
) -> IntrinsicsReport:
    """Find the checkerboard on the horizontal cube faces of each panorama and calibrate every face.

    Args:
        panoramas: BGR equirectangular images (H, W, 3), all the same size.
        pattern: inner corners (columns, rows).
        square: square size, metres (only scales the board poses).
        face_size: face size, px (default ``W / 3`` rounded, about the panorama's resolution at the face
            centre).

    Raises:
        TargetError: no panorama, or the board was found on no face.
    """
    renderer = ViewRenderer(max_entries=8)
    obj_pts = _object_points(pattern, square)
    per_face: dict[str, list[NDArray[np.float32]]] = {k: [] for k in FACES}
    n = 0
    size = 0
    W = H = 0
    for pano in panoramas:
        if n == 0:
            H, W = pano.shape[:2]
            size = int(face_size or round(W / 3))
            faces = cube_faces(size)
            views = [faces[k] for k in FACES]
        n += 1
        for name, img in zip(FACES, renderer.render_many(pano, views), strict=True):
            c = find_corners(img, pattern)
            if c is not None:
                per_face[name].append(c.astype(np.float32).reshape(-1, 1, 2))
    if n == 0:
        raise TargetError("no panorama to calibrate")
    if not any(per_face.values()):
        raise TargetError(
            f"no {pattern[0]}x{pattern[1]} checkerboard (inner corners) found on the cube faces "
            f"of {n} panoramas"
        )
    res = {k: _face(k, size, [obj_pts] * len(v), v) for k, v in per_face.items()}
    judged = {k: f.ideal() for k, f in res.items() if f.ideal() is not None}
    if not judged:
        verdict, reason = (
            "needs correction",
            f"no face has {MIN_VIEWS} views of the board: cannot confirm the ideal model",
        )
    elif all(judged.values()):
        worst = max(res[k].err_ideal_px for k in judged)
        verdict = "ideal"
        reason = (
            f"on {len(judged)} faces the ideal spherical face (f = size/2) fits within {worst:.3f} px, "
            "as well as "
            f"a free pinhole + distortion model"
        )
    else:
        bad = [k for k, ok in judged.items() if not ok]
        verdict = "needs correction"
        reason = (
            "faces "
            + ", ".join(
                f"{k} (ideal {res[k].err_ideal_px:.3f} px vs free {res[k].err_free_px:.3f} px)" for k in bad
            )
            + " do not behave as the ideal spherical camera"
        )
    return IntrinsicsReport(res, (W, H), size, n, verdict, reason)
