"""Rendering perspective views from an equirectangular panorama with cached ``cv2.remap`` look-up tables.

A look-up table (LUT) is computed once per ``(view, panorama width, panorama height)`` from the exact
mapping :meth:`PerspectiveView.view_to_pano` at every view pixel centre, in float32, then converted by
``cv2.convertMaps`` to OpenCV's fixed-point form (``CV_16SC2`` + interpolation table indices, 1/32 px
steps), which ``cv2.remap`` reads fastest. ``remap`` indexes pixel centres, so the LUT holds
``u - 0.5, v - 0.5`` (see :mod:`studio.geometry.base`).

The seam: columns wrap (``cv2.BORDER_WRAP``), so a view across the 0/360° seam interpolates between the
last and the first panorama columns without padding or copying the panorama. Rows are clamped to the
first/last row centres near the poles (within half a panorama pixel of a pole the value of the nearest
row is used).

Several views of one width are rendered by a single ``remap`` call on their stacked LUTs
(:meth:`ViewRenderer.render_many`). Views meant for a detector should be built at the detector's input
size and rendered straight from the panorama, never resized from a full-size face.
"""

from __future__ import annotations

import threading
from collections import OrderedDict
from collections.abc import Hashable, Sequence
from dataclasses import replace
from typing import TYPE_CHECKING, Any

import cv2
import numpy as np
from numpy.typing import NDArray

from studio.geometry.base import TWO_PI, wrap_u
from studio.geometry.errors import GeometryError

if TYPE_CHECKING:
    from studio.geometry.views import PerspectiveView

__all__ = ["ViewRenderer", "view_maps"]

_Lut = tuple[NDArray[Any], NDArray[Any]]


def view_maps(
    view: PerspectiveView, pano_w: int, pano_h: int
) -> tuple[NDArray[np.float32], NDArray[np.float32]]:
    """Float32 remap tables ``(map_x, map_y)`` of shape ``(view.height, view.width)`` for a panorama.

    ``map_x = u - 0.5`` in ``[-0.5, W - 0.5)`` (to be read with ``BORDER_WRAP``), ``map_y = v - 0.5``
    clamped to ``[0, H - 1]``; ``(u, v)`` is the panorama pixel seen by each view pixel centre.
    """
    # Same mapping as view.view_to_pano at every pixel centre, written with broadcasting (outer sums over
    # rows and columns) so that building a large LUT stays cheap; rays need no normalising for angles.
    f = view.focal
    x = ((np.arange(view.width) + 0.5 - view.width / 2.0) / f)[None, :]
    y = ((np.arange(view.height) + 0.5 - view.height / 2.0) / f)[:, None]
    R = view.R_cam_view()
    rx = R[0, 0] * x + R[0, 1] * y + R[0, 2]
    ry = R[1, 0] * x + R[1, 1] * y + R[1, 2]
    rz = R[2, 0] * x + R[2, 1] * y + R[2, 2]
    az = np.arctan2(ry, rx)
    el = np.arctan2(rz, np.hypot(rx, ry))
    u = wrap_u((0.5 - az / TWO_PI) * pano_w, pano_w)
    v = (0.5 - el / np.pi) * pano_h
    map_x = (u - 0.5).astype(np.float32)
    map_y = np.clip(v - 0.5, 0.0, pano_h - 1.0).astype(np.float32)
    return map_x, map_y


def _check_pano(pano: Any) -> tuple[int, int]:
    shape = getattr(pano, "shape", None)
    if not isinstance(pano, np.ndarray) or shape is None or len(shape) not in (2, 3):
        raise GeometryError(
            "expected a panorama image array (H, W) or (H, W, C), "
            f"got {getattr(pano, 'shape', type(pano).__name__)}"
        )
    h, w = int(shape[0]), int(shape[1])
    if h < 2 or w < 2:
        raise GeometryError(f"panorama is too small to render views from: {w}×{h} px")
    if w > 32767 or h > 32767:
        raise GeometryError(f"panorama is too large for OpenCV's fixed-point remap: {w}×{h} px")
    return w, h


class ViewRenderer:
    """Renders :class:`~studio.geometry.views.PerspectiveView` s from panoramas, caching the remap LUTs.

    Safe to share between threads (the cache is locked; a LUT built twice concurrently is harmless).

    Args:
        max_entries: LUTs kept (least recently used dropped first); one entry ≈ 4 bytes per view pixel.
    """

    def __init__(self, *, max_entries: int = 64) -> None:
        self._max = max(1, int(max_entries))
        self._cache: OrderedDict[Hashable, _Lut] = OrderedDict()
        self._lock = threading.Lock()

    def __len__(self) -> int:
        return len(self._cache)

    def clear(self) -> None:
        """Forget every cached LUT."""
        with self._lock:
            self._cache.clear()

    def _get(self, key: Hashable, build: Any) -> _Lut:
        with self._lock:
            lut = self._cache.get(key)
            if lut is not None:
                self._cache.move_to_end(key)
                return lut
        lut = build()
        with self._lock:
            self._cache[key] = lut
            self._cache.move_to_end(key)
            while len(self._cache) > self._max:
                self._cache.popitem(last=False)
        return lut

    def lut(self, view: PerspectiveView, pano_w: int, pano_h: int, *, nearest: bool = False) -> _Lut:
        """The fixed-point LUT ``(map1, map2)`` of ``view`` for a ``pano_w × pano_h`` panorama (cached).

        A view whose yaw is a whole number of panorama columns sees the panorama of the view at yaw 0
        shifted by that many columns: its LUT is that one's, shifted (only the yaw-0 one is cached, so views
        that follow people around the horizon cost no new table each).
        """
        cols = view.yaw / TWO_PI * pano_w
        shift = round(cols)
        if shift != 0 and abs(cols - shift) < 1e-6:
            m1, m2 = self.lut(replace(view, yaw=0.0, name=""), pano_w, pano_h, nearest=nearest)
            m1 = m1.copy()
            # turning left (yaw +) looks at smaller u; x stays in [0, W) (remap wraps the +1 neighbour)
            m1[..., 0] = (m1[..., 0].astype(np.int32) - shift) % pano_w
            return m1, m2

        def build() -> _Lut:
            mx, my = view_maps(view, pano_w, pano_h)
            m1, m2 = cv2.convertMaps(mx, my, cv2.CV_16SC2, nninterpolation=nearest)
            return m1, m2

        return self._get(("one", view, int(pano_w), int(pano_h), bool(nearest)), build)

    def _stacked_lut(
        self, views: tuple[PerspectiveView, ...], pano_w: int, pano_h: int, *, nearest: bool
    ) -> _Lut:
        def build() -> _Lut:
            maps = [view_maps(v, pano_w, pano_h) for v in views]
            mx = np.concatenate([m[0] for m in maps], axis=0)
            my = np.concatenate([m[1] for m in maps], axis=0)
            m1, m2 = cv2.convertMaps(mx, my, cv2.CV_16SC2, nninterpolation=nearest)
            return m1, m2

        return self._get(("many", views, int(pano_w), int(pano_h), bool(nearest)), build)

    def render(
        self, pano: NDArray[Any], view: PerspectiveView, *, interpolation: int = cv2.INTER_LINEAR
    ) -> NDArray[Any]:
        """Render one view.

        Args:
            pano: equirectangular image ``(H, W, C)`` or ``(H, W)``, any dtype ``cv2.remap`` takes
                (uint8, uint16, int16, float32, float64).
            view: the view to render.
            interpolation: ``cv2.INTER_LINEAR`` (default), ``INTER_NEAREST``, ``INTER_CUBIC`` or
                ``INTER_LANCZOS4``.

        Returns:
            ``(view.height, view.width, C)`` (or ``(view.height, view.width)``) image of ``pano``'s dtype.
        """
        w, h = _check_pano(pano)
        nearest = interpolation == cv2.INTER_NEAREST
        m1, m2 = self.lut(view, w, h, nearest=nearest)
        return cv2.remap(pano, m1, m2, interpolation, borderMode=cv2.BORDER_WRAP)

    def render_many(
        self, pano: NDArray[Any], views: Sequence[PerspectiveView], *, interpolation: int = cv2.INTER_LINEAR
    ) -> list[NDArray[Any]]:
        """Render several views of one panorama (same order as ``views``).

        Views of equal width are rendered by one ``remap`` over their stacked LUTs; the images returned are
        then row blocks of one array (each C-contiguous).
        """
        vs = tuple(views)
        if not vs:
            return []
        w, h = _check_pano(pano)
        nearest = interpolation == cv2.INTER_NEAREST
        if len(vs) == 1 or len({v.width for v in vs}) != 1:
            return [self.render(pano, v, interpolation=interpolation) for v in vs]
        m1, m2 = self._stacked_lut(vs, w, h, nearest=nearest)
        out = cv2.remap(pano, m1, m2, interpolation, borderMode=cv2.BORDER_WRAP)
        images = []
        row = 0
        for v in vs:
            images.append(out[row : row + v.height])
            row += v.height
        return images
