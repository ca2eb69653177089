"""Appearance cue for tracking: the colours of a person's clothes, torso and legs, in CIE L*a*b*.

A descriptor is 6 numbers, the median L*, a*, b* of the torso and of the thighs (:data:`APPEARANCE_DIM`).
The regions come from the pose keypoints when the detector gives them (shoulders → hips for the torso,
hips → knees for each thigh), else from fixed fractions of the box. Medians of small central regions keep
the background and a passing neighbour out; L*a*b* makes the distance perceptual, and lightness counts half
(it changes most between the lit and shaded parts of a room).

The distance of two descriptors is the larger of the torso and the legs colour differences (ΔE, CIE76 with
L* weighted by :data:`LIGHTNESS_WEIGHT`): two people differ when either their shirts or their trousers do.
Measured on the simulated ``moving`` recording (7 people, medians of 10 observations): the same person
at different times 2.9 (median) / 6.5 (95 %), two different people 12.9 (5 %) / 33 (median).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

__all__ = [
    "APPEARANCE_DIM",
    "LIGHTNESS_WEIGHT",
    "appearance_distance",
    "appearance_matrix",
    "clothing_colours",
    "median_appearance",
]

APPEARANCE_DIM = 6
LIGHTNESS_WEIGHT = 0.5
_MIN_PIXELS = 4
_KPT_MIN_SCORE = 0.3
# COCO keypoints
_L_SHOULDER, _R_SHOULDER, _L_HIP, _R_HIP, _L_KNEE, _R_KNEE = 5, 6, 11, 12, 13, 14

FloatArray = NDArray[np.float64]


def _pixels(pano: NDArray[np.uint8], u1: float, u2: float, v1: float, v2: float) -> NDArray[np.uint8]:
    """Pixels of a panorama rectangle (columns wrap around the seam), (M, 3)."""
    H, W = pano.shape[:2]
    r1, r2 = max(0, round(v1)), min(H, round(v2))
    c1, c2 = int(np.floor(u1)), int(np.ceil(u2))
    if r2 <= r1 or c2 <= c1:
        return np.zeros((0, 3), np.uint8)
    cols = np.arange(c1, c2) % W
    return pano[r1:r2][:, cols].reshape(-1, 3)


def _box_regions(pano: NDArray[np.uint8], box: FloatArray) -> tuple[NDArray[np.uint8], NDArray[np.uint8]]:
    u1, v1, u2, v2 = box
    w, h = u2 - u1, v2 - v1
    torso = _pixels(pano, u1 + 0.35 * w, u2 - 0.35 * w, v1 + 0.22 * h, v1 + 0.45 * h)
    legs = _pixels(pano, u1 + 0.35 * w, u2 - 0.35 * w, v1 + 0.58 * h, v1 + 0.75 * h)
    return torso, legs


def _keypoint_regions(
    pano: NDArray[np.uint8], box: FloatArray, kp: FloatArray
) -> tuple[NDArray[np.uint8], NDArray[np.uint8]] | None:
    """Torso and thigh pixels from the pose, or None when shoulders or hips are not confident."""
    need = (_L_SHOULDER, _R_SHOULDER, _L_HIP, _R_HIP)
    if np.any(kp[list(need), 2] < _KPT_MIN_SCORE):
        return None
    W = pano.shape[1]
    ref = kp[_L_SHOULDER, 0]
    pts = kp[:, :2].copy()
    pts[:, 0] += W * np.round((ref - pts[:, 0]) / W)  # the person's keypoints on one side of the seam
    sh = 0.5 * (pts[_L_SHOULDER] + pts[_R_SHOULDER])
    hip = 0.5 * (pts[_L_HIP] + pts[_R_HIP])
    torso_h = hip[1] - sh[1]
    if torso_h <= 1.0:
        return None
    half = max(2.0, 0.25 * abs(pts[_L_SHOULDER, 0] - pts[_R_SHOULDER, 0]), 0.12 * torso_h)
    u1, u2 = min(sh[0], hip[0]) - half, max(sh[0], hip[0]) + half
    torso = _pixels(pano, u1, u2, sh[1] + 0.2 * torso_h, sh[1] + 0.85 * torso_h)
    thighs = []
    for h_i, k_i in ((_L_HIP, _L_KNEE), (_R_HIP, _R_KNEE)):
        if kp[k_i, 2] < _KPT_MIN_SCORE:
            continue
        a, b = pts[h_i], pts[k_i]
        mid, hw = 0.5 * (a + b), max(1.5, 0.15 * abs(b[1] - a[1]))
        dv = b[1] - a[1]
        thighs.append(_pixels(pano, mid[0] - hw, mid[0] + hw, a[1] + 0.25 * dv, a[1] + 0.75 * dv))
    legs = np.concatenate(thighs) if thighs else _box_regions(pano, box)[1]
    return torso, legs


def _lab_median(px: NDArray[np.uint8]) -> FloatArray | None:
    import cv2  # OpenCV only when crops are described

    if len(px) < _MIN_PIXELS:
        return None
    lab = cv2.cvtColor(px.reshape(-1, 1, 3).astype(np.float32) / 255.0, cv2.COLOR_BGR2LAB)
    return np.median(lab.reshape(-1, 3), axis=0).astype(np.float64)


def clothing_colours(
    pano: NDArray[np.uint8],
    boxes: ArrayLike,
    keypoints: ArrayLike | None = None,
    *,
    min_height_frac: float = 0.06,
) -> NDArray[np.float32]:
    """Appearance descriptors of the people in one panorama.

    Args:
        pano: (H, W, 3) uint8 BGR panorama.
        boxes: (N, 4) ``u1, v1, u2, v2`` panorama boxes (``u2`` may run past W across the seam).
        keypoints: (N, 17, 3) COCO keypoints ``(u, v, score)`` or None (box fractions are used).
        min_height_frac: boxes shorter than this fraction of the panorama height are not described (a
            person beyond ~8 m: a few blurred pixels, mixed with the background; on simulated walkers such
            boxes were closer to another person's colours than to their own 38 % of the time, vs 1–3 %
            for taller boxes).

    Returns:
        (N, 6) float32 ``[L*, a*, b*]`` of the torso then of the legs; an all-NaN row when the box is too
        small or a region has too few pixels.
    """
    b = np.asarray(boxes, dtype=np.float64).reshape(-1, 4)
    kps = None if keypoints is None else np.asarray(keypoints, dtype=np.float64).reshape(-1, 17, 3)
    out = np.full((len(b), APPEARANCE_DIM), np.nan, np.float32)
    min_h = min_height_frac * pano.shape[0]
    for i, box in enumerate(b):
        if box[3] - box[1] < min_h:
            continue
        regions = None if kps is None else _keypoint_regions(pano, box, kps[i])
        torso, legs = regions if regions is not None else _box_regions(pano, box)
        t, g = _lab_median(torso), _lab_median(legs)
        if t is not None and g is not None:
            out[i] = np.r_[t, g]
    return out


def median_appearance(rows: ArrayLike) -> NDArray[np.float32] | None:
    """The per-channel median of (M, 6) descriptors, ignoring all-NaN rows; None when none is left."""
    a = np.asarray(rows, dtype=np.float64).reshape(-1, APPEARANCE_DIM)
    a = a[np.all(np.isfinite(a), axis=1)]
    return np.median(a, axis=0).astype(np.float32) if len(a) else None


_W = np.array([LIGHTNESS_WEIGHT, 1.0, 1.0])


def appearance_matrix(A: ArrayLike, B: ArrayLike) -> FloatArray:
    """Pairwise :func:`appearance_distance` of (M, 6) and (N, 6) descriptors → (M, N) (NaN rows give NaN)."""
    a = np.asarray(A, dtype=np.float64).reshape(-1, 2, 3) * _W
    b = np.asarray(B, dtype=np.float64).reshape(-1, 2, 3) * _W
    d = np.linalg.norm(a[:, None] - b[None], axis=-1)  # (M, N, 2): torso, legs
    return d.max(axis=-1)


def appearance_rows(A: ArrayLike, B: ArrayLike) -> FloatArray:
    """:func:`appearance_distance` of (M, 6) and (M, 6) descriptors row by row → (M,)."""
    a = np.asarray(A, dtype=np.float64).reshape(-1, 2, 3) * _W
    b = np.asarray(B, dtype=np.float64).reshape(-1, 2, 3) * _W
    return np.linalg.norm(a - b, axis=-1).max(axis=-1)


def appearance_distance(a: ArrayLike, b: ArrayLike) -> float:
    """Colour difference of two people: the larger of the torso and legs ΔE (L* weighted), ≥ 0."""
    return float(appearance_matrix(a, b)[0, 0])
