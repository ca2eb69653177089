"""Colours of the studio recording: one per identity, one per measurement source, range colour maps."""

from __future__ import annotations

import colorsys

import cv2
import numpy as np
from numpy.typing import NDArray

__all__ = ["ERROR_FN", "ERROR_FP", "GT_UNMATCHED", "SOURCE_COLORS", "id_color", "id_colors", "range_colors"]

U8 = NDArray[np.uint8]

SOURCE_COLORS: dict[str, tuple[int, int, int]] = {
    "fused": (40, 200, 90),
    "laser": (255, 150, 0),
    "image": (70, 140, 255),
    "interpolated": (160, 160, 160),
    "track": (160, 160, 160),
    "manual": (230, 230, 230),
    "gt": (230, 230, 230),
}
"""RGB per :attr:`LabelPerson.source` / :data:`studio.fuse.base.SOURCES`."""

ERROR_FP = (255, 40, 40)
ERROR_FN = (255, 0, 255)
GT_UNMATCHED = (235, 235, 235)

_GOLDEN = 0.618033988749895


def id_color(track_id: int) -> tuple[int, int, int]:
    """A bright RGB colour for an identity; neighbouring ids get far-apart hues (golden-ratio steps)."""
    h = (0.13 + _GOLDEN * int(track_id)) % 1.0
    r, g, b = colorsys.hsv_to_rgb(h, 0.75, 0.95)
    return (round(r * 255), round(g * 255), round(b * 255))


def id_colors(ids: NDArray[np.int64] | list[int]) -> U8:
    """``(N, 3)`` uint8 RGB colours of identities."""
    arr = np.asarray(ids, dtype=np.int64).reshape(-1)
    if not len(arr):
        return np.zeros((0, 3), np.uint8)
    return np.array([id_color(int(i)) for i in arr], dtype=np.uint8)


_TURBO: U8 = np.ascontiguousarray(
    np.asarray(
        cv2.applyColorMap(np.arange(256, dtype=np.uint8).reshape(-1, 1), cv2.COLORMAP_TURBO), np.uint8
    ).reshape(256, 3)[:, ::-1]
)


def range_colors(r: NDArray[np.floating], *, r_max: float = 10.0) -> U8:
    """``(N, 3)`` uint8 RGB turbo colours of ranges ``r`` (metres; near = blue … far = red; NaN = far)."""
    v = np.nan_to_num(np.asarray(r, dtype=np.float64).reshape(-1), nan=r_max) * (255.0 / r_max)
    return _TURBO[np.clip(v, 0, 255).astype(np.uint8)]
