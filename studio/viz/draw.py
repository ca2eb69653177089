"""Pure-numpy drawing helpers for the viewer: seam-split boxes, skeletons, vertical markers, ellipses.

No rerun here, so every helper is unit-testable alone. Pixel conventions are those of
:mod:`studio.geometry` (continuous, from the left/top edge; a box across the seam has ``u2 > W``).
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray

__all__ = [
    "COCO_SKELETON",
    "ellipse_strips",
    "skeleton_strips",
    "split_seam_boxes",
    "vertical_strips",
    "wrapped_box_center",
]

FloatArray = NDArray[np.float64]

COCO_SKELETON: tuple[tuple[int, int], ...] = (
    (0, 1), (0, 2), (1, 3), (2, 4), (5, 6), (5, 7), (7, 9), (6, 8), (8, 10),
    (5, 11), (6, 12), (11, 12), (11, 13), (13, 15), (12, 14), (14, 16),
)  # fmt: skip
"""Keypoint pairs of the 17 COCO / MoveNet body keypoints (nose, eyes, ears, shoulders, elbows, wrists,
hips, knees, ankles; left before right)."""


def split_seam_boxes(boxes: Any, width: float) -> tuple[FloatArray, NDArray[np.int64]]:
    """Split panorama boxes that cross the 0/360° seam into two drawable boxes.

    Args:
        boxes: ``(N, 4)`` ``u1, v1, u2, v2`` px; ``u1`` in ``[0, W)``, ``u2`` may exceed ``W``.
        width: panorama width ``W``, px.

    Returns:
        ``(M, 4)`` boxes inside ``[0, W]`` (M ≥ N) and ``(M,)`` the index of the input box of each.
    """
    b = np.asarray(boxes, dtype=np.float64).reshape(-1, 4)
    if not len(b):
        return np.zeros((0, 4)), np.zeros(0, np.int64)
    W = float(width)
    u1 = np.mod(b[:, 0], W)
    u2 = u1 + (b[:, 2] - b[:, 0])
    cross = u2 > W
    main = np.stack([u1, b[:, 1], np.minimum(u2, W), b[:, 3]], axis=1)
    extra = np.stack([np.zeros(cross.sum()), b[cross, 1], u2[cross] - W, b[cross, 3]], axis=1)
    idx = np.concatenate([np.arange(len(b)), np.flatnonzero(cross)])
    return np.concatenate([main, extra]), idx.astype(np.int64)


def wrapped_box_center(boxes: Any, width: float) -> FloatArray:
    """``(N,)`` centre column of panorama boxes, wrapped into ``[0, W)``, px."""
    b = np.asarray(boxes, dtype=np.float64).reshape(-1, 4)
    return np.mod(0.5 * (b[:, 0] + b[:, 2]), float(width))


def skeleton_strips(
    keypoints: Any, width: float, *, min_score: float = 0.3
) -> tuple[list[FloatArray], list[int]]:
    """Line segments of body skeletons on the panorama.

    Args:
        keypoints: ``(N, 17, 3)`` ``u, v, score`` per person (u may exceed ``W`` across the seam).
        width: panorama width, px.
        min_score: both ends of a segment need at least this score.

    Returns:
        Segments (each ``(2, 2)`` px, u wrapped into ``[0, W)``; segments that would jump across the seam are
        dropped) and the person index of each.
    """
    k = np.asarray(keypoints, dtype=np.float64)
    strips: list[FloatArray] = []
    owner: list[int] = []
    if k.ndim != 3 or k.shape[1] < 17 or k.shape[2] < 3:
        return strips, owner
    W = float(width)
    for n in range(k.shape[0]):
        uv = k[n, :, :2].copy()
        uv[:, 0] = np.mod(uv[:, 0], W)
        ok = k[n, :, 2] >= min_score
        for a, b in COCO_SKELETON:
            if ok[a] and ok[b] and abs(uv[a, 0] - uv[b, 0]) < 0.5 * W:
                strips.append(np.stack([uv[a], uv[b]]))
                owner.append(n)
    return strips, owner


def vertical_strips(
    uv_low: FloatArray, uv_high: FloatArray, width: float
) -> tuple[list[FloatArray], NDArray[np.int64]]:
    """Segments from ``uv_low`` to ``uv_high`` (both ``(N, 2)`` px), dropping NaN ones and seam jumps.

    Returns:
        The segments (``(2, 2)`` each) and the input index of each.
    """
    lo = np.asarray(uv_low, dtype=np.float64).reshape(-1, 2)
    hi = np.asarray(uv_high, dtype=np.float64).reshape(-1, 2)
    ok = np.all(np.isfinite(lo), axis=1) & np.all(np.isfinite(hi), axis=1)
    ok &= np.abs(lo[:, 0] - hi[:, 0]) < 0.5 * float(width)
    idx = np.flatnonzero(ok)
    return [np.stack([lo[i], hi[i]]) for i in idx], idx.astype(np.int64)


def ellipse_strips(
    xy: Any, cov: Any, *, n_sigma: float = 2.0, n: int = 24, z: float = 0.0
) -> list[FloatArray]:
    """Closed 3D outlines ``(n + 1, 3)`` of the ``n_sigma`` covariance ellipses of 2D positions.

    Args:
        xy: ``(N, 2)`` centres, metres.
        cov: ``(N, 2, 2)`` covariances, m².
        n_sigma: size of the ellipse in standard deviations.
        n: vertices per ellipse.
        z: height of the outline, metres.
    """
    c = np.asarray(xy, dtype=np.float64).reshape(-1, 2)
    P = np.asarray(cov, dtype=np.float64).reshape(-1, 2, 2)
    t = np.linspace(0.0, 2.0 * np.pi, n + 1)
    circle = np.stack([np.cos(t), np.sin(t)], axis=1)  # (n+1, 2)
    out = []
    for k in range(len(c)):
        w, V = np.linalg.eigh(0.5 * (P[k] + P[k].T))
        A = V * (n_sigma * np.sqrt(np.clip(w, 0.0, None)))
        pts = c[k] + circle @ A.T
        out.append(np.column_stack([pts, np.full(len(pts), z)]))
    return out
