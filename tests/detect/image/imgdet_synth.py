"""Synthetic data for the image detector tests: oracle views of known people, billboards, tiny YOLO models."""

from __future__ import annotations

import math
from pathlib import Path

import cv2
import numpy as np
from numpy.typing import NDArray

from studio.detect.image.base import ViewDetections
from studio.detect.image.sweep import SweepParams, ViewSweepDetector
from studio.geometry import PerspectiveView

PHOTO = next(
    iter(
        Path(__file__)
        .resolve()
        .parents[3]
        .glob(".venv/lib/python3*/site-packages/matplotlib/mpl-data/sample_data/grace_hopper.jpg")
    ),
    None,
)


def person_outline(az: float, dist: float, *, cam_z: float = 1.1, height: float = 1.7, width: float = 0.5):
    """Dense outline points (az, el) of a standing person (a vertical rectangle facing the camera)."""
    ys = np.linspace(-width / 2, width / 2, 21)
    zs = np.linspace(-cam_z, height - cam_z, 41)
    pts = [(dist, y, z) for y in ys for z in (zs[0], zs[-1])] + [
        (dist, y, z) for z in zs for y in (ys[0], ys[-1])
    ]
    p = np.asarray(pts, dtype=np.float64)
    ca, sa = math.cos(az), math.sin(az)
    x, y = ca * p[:, 0] - sa * p[:, 1], sa * p[:, 0] + ca * p[:, 1]
    return np.arctan2(y, x), np.arctan2(p[:, 2], np.hypot(x, y))


def person_keypoints(az: float, dist: float, *, cam_z: float = 1.1) -> NDArray[np.float64]:
    """17 (az, el) keypoints spread over a standing person (rough body layout), shape (17, 2)."""
    heights = [1.6, 1.62, 1.62, 1.6, 1.6, 1.4, 1.4, 1.1, 1.1, 0.85, 0.85, 0.9, 0.9, 0.5, 0.5, 0.08, 0.08]
    sides = [
        0,
        -0.03,
        0.03,
        -0.07,
        0.07,
        -0.2,
        0.2,
        -0.25,
        0.25,
        -0.25,
        0.25,
        -0.1,
        0.1,
        -0.1,
        0.1,
        -0.1,
        0.1,
    ]
    out = []
    for h, s in zip(heights, sides, strict=True):
        x, y = dist, -s
        ca, sa = math.cos(az), math.sin(az)
        xr, yr = ca * x - sa * y, sa * x + ca * y
        out.append((math.atan2(yr, xr), math.atan2(h - cam_z, math.hypot(xr, yr))))
    return np.asarray(out)


def angles_to_uv(az: NDArray[np.float64], el: NDArray[np.float64], w: int, h: int) -> NDArray[np.float64]:
    u = ((0.5 - az / (2 * math.pi)) * w) % w
    v = (0.5 - el / math.pi) * h
    return np.stack([u, v], axis=-1)


class OracleSweep(ViewSweepDetector):
    """A 'network' that sees the given people exactly: each view reports the clipped projection of each
    person in front of it (box of the visible outline, keypoints with score 0.9 inside the view)."""

    name = "oracle"

    def __init__(self, people: list[tuple[float, float]], pano_w: int, pano_h: int, **sweep: object) -> None:
        super().__init__(sweep=SweepParams(**sweep))  # type: ignore[arg-type]
        self.people = people
        self.pano_w, self.pano_h = pano_w, pano_h
        self._view_iter: list[PerspectiveView] = []

    def render_views(
        self, pano: NDArray[np.uint8], views: list[PerspectiveView] | None = None
    ) -> list[NDArray[np.uint8]]:
        self._view_iter = list(self.views if views is None else views)
        return super().render_views(pano, views)

    def detect_view(self, image: NDArray[np.uint8]) -> ViewDetections:
        view = self._view_iter.pop(0)
        boxes, kps = [], []
        for az, dist in self.people:
            a, e = person_outline(az, dist)
            uv = view.pano_to_view(angles_to_uv(a, e, self.pano_w, self.pano_h), self.pano_w, self.pano_h)
            ok = np.all(np.isfinite(uv), axis=1)
            uv = uv[ok]
            inside = (uv[:, 0] >= 0) & (uv[:, 0] <= view.width) & (uv[:, 1] >= 0) & (uv[:, 1] <= view.height)
            if inside.sum() < 5:
                continue
            x1, y1 = np.clip(uv.min(axis=0), 0, None)
            x2, y2 = uv.max(axis=0)
            x2, y2 = min(x2, view.width), min(y2, view.height)
            if x2 - x1 < 2 or y2 - y1 < 2:
                continue
            boxes.append([x1, y1, x2, y2])
            ka, ke = person_keypoints(az, dist).T
            kuv = view.pano_to_view(angles_to_uv(ka, ke, self.pano_w, self.pano_h), self.pano_w, self.pano_h)
            kin = (
                np.all(np.isfinite(kuv), axis=1)
                & (kuv[:, 0] >= 0)
                & (kuv[:, 0] <= view.width)
                & (kuv[:, 1] >= 0)
                & (kuv[:, 1] <= view.height)
            )
            kuv = np.nan_to_num(kuv)
            kps.append(np.concatenate([kuv, np.where(kin, 0.9, 0.0)[:, None]], axis=1))
        if not boxes:
            return ViewDetections.empty()
        return ViewDetections(np.asarray(boxes), np.full(len(boxes), 0.8), np.asarray(kps))


def paste_billboard(
    pano: NDArray[np.uint8],
    photo: NDArray[np.uint8],
    *,
    az: float,
    dist: float,
    z_bottom: float,
    height_m: float,
) -> tuple[NDArray[np.uint8], tuple[float, float, float, float]]:
    """Paste ``photo`` as a vertical plane facing the camera (azimuth ``az`` rad, ``dist`` m, bottom edge
    ``z_bottom`` m relative to the camera); returns the panorama and the photo's panorama box (seam form)."""
    H, W = pano.shape[:2]
    ph, pw = photo.shape[:2]
    width_m = height_m * pw / ph
    v, u = np.mgrid[0:H, 0:W]
    azp = (0.5 - (u + 0.5) / W) * 2 * np.pi
    el = (0.5 - (v + 0.5) / H) * np.pi
    a = azp - az
    dx, dy, dz = np.cos(el) * np.cos(a), np.cos(el) * np.sin(a), np.sin(el)
    with np.errstate(divide="ignore", invalid="ignore"):
        t = dist / dx
        y, z = t * dy, t * dz
    ok = (dx > 1e-6) & (np.abs(y) < width_m / 2) & (z >= z_bottom) & (z <= z_bottom + height_m)
    mx = np.where(ok, (width_m / 2 - y) / width_m * pw - 0.5, -1).astype(np.float32)
    my = np.where(ok, (z_bottom + height_m - z) / height_m * ph - 0.5, -1).astype(np.float32)
    src = cv2.remap(photo, mx, my, cv2.INTER_LINEAR)
    out = pano.copy()
    out[ok] = src[ok]
    rows = np.nonzero(ok.any(axis=1))[0]
    cols = np.nonzero(ok.any(axis=0))[0]
    if cols[0] == 0 and cols[-1] == W - 1:  # across the seam
        gaps = np.nonzero(np.diff(cols) > 1)[0]
        u1, u2 = float(cols[gaps[0] + 1]), float(cols[gaps[0]] + 1 + W)
    else:
        u1, u2 = float(cols[0]), float(cols[-1] + 1)
    return out, (u1, float(rows[0]), u2, float(rows[-1] + 1))


def textured_pano(w: int = 1280, h: int = 640, seed: int = 0) -> NDArray[np.uint8]:
    rng = np.random.default_rng(seed)
    noise = rng.integers(60, 200, (h // 8, w // 8, 3)).astype(np.uint8)
    return cv2.resize(noise, (w, h), interpolation=cv2.INTER_CUBIC)


def tiny_yolo(path: Path, layout: str, rows: NDArray[np.float32], *, size: int | None = 64) -> Path:
    """A tiny ONNX 'YOLO' whose output is the constant ``rows`` in the given layout (+ 0 × mean(input)).

    ``rows``: (N, 5 + C) for v5 (cx, cy, w, h, obj, classes…) or (N, 4 + C) for v8; the v8 model outputs
    their transpose ``[1, 4 + C, N]``. ``size=None`` makes the input's H, W dynamic.
    """
    import onnx
    from onnx import TensorProto, helper, numpy_helper

    const = rows[None] if layout == "v5" else rows.T[None]
    const = np.ascontiguousarray(const.astype(np.float32))
    hw: list[int | str] = [size, size] if size is not None else ["h", "w"]
    x = helper.make_tensor_value_info("images", TensorProto.FLOAT, [1, 3, *hw])
    y = helper.make_tensor_value_info("output0", TensorProto.FLOAT, list(const.shape))
    nodes = [
        helper.make_node("ReduceMean", ["images"], ["m"], keepdims=0),
        helper.make_node("Mul", ["m", "zero"], ["z"]),
        helper.make_node("Add", ["table", "z"], ["output0"]),
    ]
    inits = [
        numpy_helper.from_array(const, "table"),
        numpy_helper.from_array(np.array(0.0, np.float32), "zero"),
    ]
    graph = helper.make_graph(nodes, "tiny_yolo", [x], [y], inits)
    model = helper.make_model(graph, opset_imports=[helper.make_opsetid("", 17)])
    model.ir_version = 8
    onnx.checker.check_model(model)
    onnx.save(model, str(path))
    return path
