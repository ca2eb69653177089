"""Conventions of the spherical (equirectangular) camera, and seam-aware boxes on the panorama.

Camera frame
    ROS body convention (REP-103): x forward, y left, z up. A direction ``(x, y, z)`` has
    azimuth ``az = atan2(y, x)`` (radians, counter-clockwise, left positive, in [-π, π)) and elevation
    ``el = atan2(z, hypot(x, y))`` (radians, up positive, in [-π/2, π/2]).

Lens centres
    The camera is central by default (every ray starts at the origin). With a lens offset ``b`` (metres,
    :class:`~studio.geometry.equirect.EquirectCamera`'s ``lens_offset``, rig.yaml ``camera.lens_offset``)
    it models a dual-fisheye camera: the front lens centre at ``(+b, 0, 0)``, the back one at
    ``(−b, 0, 0)``; a point ``(x, y, z)`` is seen along ``(x − sign(x)·b, y, z)`` and a pixel's ray starts
    at ``(sign(ray_x)·b, 0, 0)``. The angle/pixel functions below are about directions only.

Equirectangular pixels
    Continuous coordinates measured from the left/top edge of the image: pixel ``(i, j)`` (column, row)
    covers ``[i, i+1) × [j, j+1)`` and its centre is ``(i + 0.5, j + 0.5)``. For an image ``W × H``::

        u = (0.5 - az / (2π)) · W        (az = 0 → centre column W/2, az = +π/2 (left) → W/4,
                                          az = ±π → the seam at u = 0 ≡ W)
        v = (0.5 - el / π) · H           (el = +π/2 → top edge v = 0, el = -π/2 → bottom edge v = H)

    ``u`` is always wrapped into ``[0, W)``. OpenCV's ``remap`` indexes pixel centres, so a remap look-up
    table holds ``u - 0.5, v - 0.5``.

Boxes on the panorama
    ``[u1, v1, u2, v2]`` in panorama pixels. A box lies on a cylinder: a box across the seam is kept as ONE
    box with ``u1`` in ``[0, W)`` and ``u2 > W`` (``u2 - W`` is the part past the seam). The functions below
    (:func:`normalize_pano_box`, :func:`pano_box_iou`, :func:`merge_pano_boxes`, :func:`pano_box_nms`,
    :func:`pano_box_center_az`) treat a box near ``u = W`` and one near ``u = 0`` as neighbours.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

__all__ = [
    "TWO_PI",
    "angles_to_pixel",
    "angles_to_rays",
    "merge_pano_boxes",
    "normalize_pano_box",
    "pano_box_center_az",
    "pano_box_iou",
    "pano_box_nms",
    "pixel_to_angles",
    "rays_to_angles",
    "wrap_u",
]

FloatArray = NDArray[np.float64]
TWO_PI = 2.0 * np.pi


def wrap_u(u: ArrayLike, width: float) -> FloatArray:
    """Wrap panorama columns into ``[0, width)``.

    Args:
        u: columns, px, any shape.
        width: panorama width W, px.

    Returns:
        Same shape, float64, every value in ``[0, W)`` (also for tiny negative inputs, where a plain modulo
        would round to exactly ``W``).
    """
    w = float(width)
    out = np.mod(np.asarray(u, dtype=np.float64), w)
    return np.where(out >= w, out - w, out)[()]


def angles_to_pixel(
    az: ArrayLike, el: ArrayLike, width: float, height: float
) -> tuple[FloatArray, FloatArray]:
    """Azimuth/elevation (rad) → equirectangular pixel ``(u, v)`` (px, continuous, u wrapped to [0, W)).

    Args:
        az: azimuth, rad, any shape (left positive).
        el: elevation, rad, broadcastable with ``az``.
        width: panorama width W, px.
        height: panorama height H, px.
    """
    a = np.asarray(az, dtype=np.float64)
    e = np.asarray(el, dtype=np.float64)
    u = wrap_u((0.5 - a / TWO_PI) * float(width), width)
    v = (0.5 - e / np.pi) * float(height)
    return u, v


def pixel_to_angles(u: ArrayLike, v: ArrayLike, width: float, height: float) -> tuple[FloatArray, FloatArray]:
    """Equirectangular pixel ``(u, v)`` → azimuth in [-π, π) and elevation (rad).

    Columns outside ``[0, W)`` are taken modulo W (the image wraps around). Rows outside ``[0, H]`` give
    elevations beyond ±π/2 (no clipping: the mapping is linear).
    """
    uu = np.asarray(u, dtype=np.float64)
    vv = np.asarray(v, dtype=np.float64)
    az = (0.5 - wrap_u(uu, width) / float(width)) * TWO_PI  # in (-π, π]
    az = np.where(az >= np.pi, az - TWO_PI, az)[()]
    el = (0.5 - vv / float(height)) * np.pi
    return az, el


def angles_to_rays(az: ArrayLike, el: ArrayLike) -> FloatArray:
    """Unit direction vectors ``(..., 3)`` (x forward, y left, z up) of azimuth/elevation angles (rad)."""
    a = np.asarray(az, dtype=np.float64)
    e = np.asarray(el, dtype=np.float64)
    a, e = np.broadcast_arrays(a, e)
    ce = np.cos(e)
    return np.stack([ce * np.cos(a), ce * np.sin(a), np.sin(e)], axis=-1)


def rays_to_angles(rays: ArrayLike) -> tuple[FloatArray, FloatArray]:
    """Azimuth and elevation (rad) of direction vectors ``(..., 3)`` (need not be unit; zero → NaN)."""
    r = np.asarray(rays, dtype=np.float64)
    if r.shape[-1:] != (3,):
        raise ValueError(f"rays must have shape (..., 3), got {r.shape}")
    x, y, z = r[..., 0], r[..., 1], r[..., 2]
    rho = np.hypot(x, y)
    az = np.arctan2(y, x)
    az = np.where(az >= np.pi, az - TWO_PI, az)
    el = np.arctan2(z, rho)
    zero = (rho == 0.0) & (z == 0.0)
    if np.any(zero):
        az = np.where(zero, np.nan, az)
        el = np.where(zero, np.nan, el)
    return az, el


def _as_boxes(box: ArrayLike) -> FloatArray:
    b = np.asarray(box, dtype=np.float64)
    if b.ndim == 1:
        b = b[None, :]
    if b.ndim != 2 or b.shape[1] != 4:
        raise ValueError(f"boxes must have shape (4,) or (N, 4) [u1, v1, u2, v2], got {np.shape(box)}")
    return b


def normalize_pano_box(box: ArrayLike, width: float) -> FloatArray:
    """Bring panorama boxes to the canonical seam form.

    Args:
        box: ``(4,)`` or ``(N, 4)`` ``[u1, v1, u2, v2]``, px; ``u2 >= u1`` (``u2`` may exceed W).
        width: panorama width W, px.

    Returns:
        Same shape as ``box``: ``u1`` wrapped into ``[0, W)``, ``u2 = u1 + (u2 - u1)`` with the box width
        clipped to ``[0, W]``; ``v1, v2`` unchanged.
    """
    b = np.asarray(box, dtype=np.float64)
    bb = _as_boxes(b).copy()
    w = np.clip(bb[:, 2] - bb[:, 0], 0.0, float(width))
    bb[:, 0] = wrap_u(bb[:, 0], width)
    bb[:, 2] = bb[:, 0] + w
    return bb[0] if b.ndim == 1 else bb


def pano_box_iou(a: ArrayLike, b: ArrayLike, width: float) -> FloatArray:
    """Intersection over union of boxes on the panorama cylinder.

    A box near ``u = W`` overlaps a box near ``u = 0`` (and a box written past the seam, ``u2 > W``, is the
    same as its wrapped copy).

    Args:
        a: ``(N, 4)`` or ``(4,)`` boxes ``[u1, v1, u2, v2]``, px.
        b: ``(M, 4)`` or ``(4,)`` boxes, px.
        width: panorama width W, px.

    Returns:
        ``(N, M)`` IoU in [0, 1].
    """
    A = normalize_pano_box(_as_boxes(a), width)
    B = normalize_pano_box(_as_boxes(b), width)
    w = float(width)
    inter_u = np.zeros((A.shape[0], B.shape[0]))
    for k in (-1.0, 0.0, 1.0):
        lo = np.maximum(A[:, None, 0], B[None, :, 0] + k * w)
        hi = np.minimum(A[:, None, 2], B[None, :, 2] + k * w)
        inter_u += np.clip(hi - lo, 0.0, None)
    inter_v = np.clip(
        np.minimum(A[:, None, 3], B[None, :, 3]) - np.maximum(A[:, None, 1], B[None, :, 1]), 0.0, None
    )
    inter = np.minimum(inter_u, w) * inter_v
    area_a = (A[:, 2] - A[:, 0]) * np.clip(A[:, 3] - A[:, 1], 0.0, None)
    area_b = (B[:, 2] - B[:, 0]) * np.clip(B[:, 3] - B[:, 1], 0.0, None)
    union = area_a[:, None] + area_b[None, :] - inter
    with np.errstate(invalid="ignore", divide="ignore"):
        iou = np.where(union > 0.0, inter / union, 0.0)
    return np.clip(iou, 0.0, 1.0)


def pano_box_center_az(box: ArrayLike, width: float) -> FloatArray:
    """Azimuth (rad, in [-π, π)) of the centre column of panorama boxes.

    ``box`` ``(4,)`` gives a scalar, ``(N, 4)`` gives ``(N,)``; ``width`` is the panorama width W, px.
    """
    b = np.asarray(box, dtype=np.float64)
    bb = normalize_pano_box(_as_boxes(b), width)
    uc = 0.5 * (bb[:, 0] + bb[:, 2])
    az = (0.5 - wrap_u(uc, width) / float(width)) * TWO_PI
    az = np.where(az >= np.pi, az - TWO_PI, az)
    return az[0] if b.ndim == 1 else az


def merge_pano_boxes(boxes: ArrayLike, width: float) -> FloatArray:
    """The smallest box on the cylinder that covers all ``boxes`` (``(N, 4)``, px) → ``(4,)``, seam form.

    The covering arc starts at one of the boxes' left edges; the shortest such cover is returned. If the
    boxes go all the way round, the result spans the full width ``[0, W]``.
    """
    bb = normalize_pano_box(_as_boxes(boxes), width)
    if bb.shape[0] == 0:
        raise ValueError("merge_pano_boxes needs at least one box")
    w = float(width)
    starts = bb[:, 0]
    widths = bb[:, 2] - bb[:, 0]
    # For each candidate start s_i, shift every box's start into [s_i, s_i + W) and measure the cover.
    shifted = starts[None, :] + w * ((starts[None, :] - starts[:, None]) < 0.0)
    ends = np.max(shifted + widths[None, :], axis=1)
    cover = ends - starts
    i = int(np.argmin(cover))
    v1, v2 = float(bb[:, 1].min()), float(bb[:, 3].max())
    if cover[i] >= w:
        return np.array([0.0, v1, w, v2])
    return np.array([starts[i], v1, starts[i] + cover[i], v2])


def pano_box_nms(
    boxes: ArrayLike, scores: ArrayLike, width: float, *, iou_threshold: float = 0.5
) -> NDArray[np.intp]:
    """Greedy non-maximum suppression of panorama boxes with the seam-aware IoU.

    Args:
        boxes: ``(N, 4)`` boxes, px.
        scores: ``(N,)`` scores (higher is better).
        width: panorama width W, px.
        iou_threshold: a box is dropped when its IoU with a kept, higher-scoring box exceeds this.

    Returns:
        Indices of the kept boxes, by decreasing score.
    """
    bb = _as_boxes(boxes)
    s = np.asarray(scores, dtype=np.float64).reshape(-1)
    if s.shape[0] != bb.shape[0]:
        raise ValueError(f"{bb.shape[0]} boxes but {s.shape[0]} scores")
    order = np.argsort(-s, kind="stable")
    iou = pano_box_iou(bb, bb, width)
    suppressed = np.zeros(bb.shape[0], dtype=bool)
    keep: list[int] = []
    for i in order:
        if suppressed[i]:
            continue
        keep.append(int(i))
        suppressed |= iou[i] > iou_threshold
    return np.asarray(keep, dtype=np.intp)
