"""Appearance cue for tracklet stitching: colour histograms and their Bhattacharyya distance."""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

__all__ = ["bhattacharyya_distance", "bhattacharyya_matrix", "colour_histogram", "mean_histogram"]


def colour_histogram(
    pixels_bgr: ArrayLike,
    *,
    bins: tuple[int, int] = (12, 4),
    min_saturation: int = 0,
) -> NDArray[np.float32]:
    """Hue–saturation histogram of a person's image crop, L1-normalised.

    Hue and saturation are robust to the brightness changes between the lit and shaded sides of a room.

    Args:
        pixels_bgr: (H, W, 3) uint8 BGR crop (e.g. the torso part of the person's panorama box), or (M, 3)
            pixels.
        bins: numbers of hue and saturation bins.
        min_saturation: pixels with a lower saturation (0–255, grey) are left out.

    Returns:
        (bins[0]·bins[1],) float32 histogram summing to 1 (uniform when no pixel counts).
    """
    import cv2  # OpenCV only when crops are described

    px = np.asarray(pixels_bgr, dtype=np.uint8).reshape(-1, 1, 3)
    n = bins[0] * bins[1]
    if len(px) == 0:
        return np.full(n, 1.0 / n, np.float32)
    hsv = cv2.cvtColor(px, cv2.COLOR_BGR2HSV).reshape(-1, 3).astype(np.int64)
    keep = hsv[:, 1] >= min_saturation
    h = np.minimum(hsv[keep, 0] * bins[0] // 180, bins[0] - 1)
    s = np.minimum(hsv[keep, 1] * bins[1] // 256, bins[1] - 1)
    hist = np.bincount(h * bins[1] + s, minlength=n).astype(np.float32)
    total = hist.sum()
    return hist / total if total > 0 else np.full(n, 1.0 / n, np.float32)


def mean_histogram(hists: ArrayLike) -> NDArray[np.float32]:
    """The L1-normalised mean of (M, D) histograms."""
    h = np.asarray(hists, dtype=np.float64).reshape(-1, np.shape(hists)[-1]).mean(axis=0)
    total = h.sum()
    return (h / total if total > 0 else h).astype(np.float32)


def bhattacharyya_distance(p: ArrayLike, q: ArrayLike) -> float:
    """Bhattacharyya (Hellinger) distance ``sqrt(1 - Σ sqrt(p·q))`` of two histograms, in [0, 1].

    Both are L1-normalised first; 0 means identical, 1 means no overlap.
    """
    a = np.clip(np.asarray(p, dtype=np.float64), 0.0, None)
    b = np.clip(np.asarray(q, dtype=np.float64), 0.0, None)
    sa, sb = a.sum(), b.sum()
    if sa <= 0 or sb <= 0:
        return 1.0
    bc = float(np.sum(np.sqrt(a / sa * b / sb)))
    return float(np.sqrt(max(0.0, 1.0 - bc)))


def bhattacharyya_matrix(A: ArrayLike, B: ArrayLike) -> NDArray[np.float64]:
    """Pairwise :func:`bhattacharyya_distance` of (M, D) and (N, D) histograms → (M, N)."""
    a = np.clip(np.asarray(A, dtype=np.float64), 0.0, None)
    b = np.clip(np.asarray(B, dtype=np.float64), 0.0, None)
    a = a / np.maximum(a.sum(axis=1, keepdims=True), 1e-300)
    b = b / np.maximum(b.sum(axis=1, keepdims=True), 1e-300)
    bc = np.sqrt(a) @ np.sqrt(b).T
    return np.sqrt(np.clip(1.0 - bc, 0.0, 1.0))
