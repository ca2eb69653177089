"""ViewRenderer: rendered views checked pixel by pixel against independent per-pixel code."""

from __future__ import annotations

import math

import cv2
import numpy as np
import pytest

from studio.geometry import (
    GeometryError,
    PerspectiveView,
    ViewRenderer,
    cube_faces,
    horizon_views,
    rot_from_rpy,
    view_maps,
)

PW, PH = 512, 256  # small panorama: fast tests
PIX = 2 * math.pi / PW  # angular size of a panorama pixel, rad


def direction_panorama() -> np.ndarray:
    """float32 panorama whose colour at each pixel is the unit ray (x, y, z) of its centre."""
    jj, ii = np.mgrid[0:PH, 0:PW]
    az = (0.5 - (ii + 0.5) / PW) * 2 * np.pi
    el = (0.5 - (jj + 0.5) / PH) * np.pi
    return np.stack([np.cos(el) * np.cos(az), np.cos(el) * np.sin(az), np.sin(el)], -1).astype(np.float32)


def expected_rays(view: PerspectiveView) -> np.ndarray:
    """Per-pixel camera-frame rays of a view, by independent code (see test_views.independent_ray)."""
    f = (view.width / 2) / math.tan(view.fov / 2)
    jj, ii = np.mgrid[0 : view.height, 0 : view.width]
    body = np.stack(
        [np.ones(ii.shape), -(ii + 0.5 - view.width / 2) / f, -(jj + 0.5 - view.height / 2) / f], axis=-1
    )
    body /= np.linalg.norm(body, axis=-1, keepdims=True)
    return body @ rot_from_rpy(0.0, -view.pitch, view.yaw).T


RENDER_VIEWS = [
    PerspectiveView(0.0, 0.0, math.radians(90), 96, 96, name="front"),
    PerspectiveView(math.pi, 0.0, math.radians(90), 121, 81, name="seam"),  # centre column on the seam
    PerspectiveView(-3.0, 0.3, math.radians(60), 64, 100, name="near-seam"),
    PerspectiveView(2.0, -0.9, math.radians(110), 100, 70, name="low"),
    PerspectiveView(0.5, math.pi / 2, math.radians(90), 80, 80, name="zenith"),
    PerspectiveView(-1.0, -math.pi / 2, math.radians(90), 80, 80, name="nadir"),
]


@pytest.mark.parametrize("view", RENDER_VIEWS, ids=lambda v: v.name)
def test_rendered_view_matches_analytic_directions(view: PerspectiveView) -> None:
    pano = direction_panorama()
    img = ViewRenderer().render(pano, view)
    assert img.shape == (view.height, view.width, 3)
    assert img.dtype == np.float32
    exp = expected_rays(view)
    got = img.astype(np.float64)
    got /= np.linalg.norm(got, axis=-1, keepdims=True)
    ang = np.arccos(np.clip(np.sum(got * exp, axis=-1), -1.0, 1.0)) / PIX  # error in panorama pixels
    el = np.arcsin(np.clip(exp[..., 2], -1, 1))
    polar = np.abs(el) > np.pi / 2 - 0.5 * np.pi / PH  # within half a row of a pole: rows are clamped
    assert ang[~polar].max() < 0.06, ang[~polar].max()  # fixed-point LUT: 1/32 px steps
    if polar.any():
        assert ang[polar].max() < 0.6


def bilinear_reference(pano: np.ndarray, view: PerspectiveView) -> np.ndarray:
    """Independent renderer: per-pixel rays → spec formulas → numpy bilinear (columns wrap, rows clamp)."""
    r = expected_rays(view)
    az = np.arctan2(r[..., 1], r[..., 0])
    el = np.arctan2(r[..., 2], np.hypot(r[..., 0], r[..., 1]))
    x = ((0.5 - az / (2 * np.pi)) * PW) % PW - 0.5
    y = np.clip((0.5 - el / np.pi) * PH - 0.5, 0, PH - 1)
    x0, y0 = np.floor(x).astype(int), np.floor(y).astype(int)
    fx, fy = (x - x0)[..., None], (y - y0)[..., None]
    xa, xb = x0 % PW, (x0 + 1) % PW
    ya, yb = y0, np.minimum(y0 + 1, PH - 1)
    p = pano.astype(np.float64)
    top = p[ya, xa] * (1 - fx) + p[ya, xb] * fx
    bot = p[yb, xa] * (1 - fx) + p[yb, xb] * fx
    return top * (1 - fy) + bot * fy


def smooth_uint8_panorama(seed: int = 0) -> np.ndarray:
    rng = np.random.default_rng(seed)
    small = rng.uniform(0, 255, (PH // 8, PW // 8, 3)).astype(np.float32)
    big = cv2.resize(small, (PW, PH), interpolation=cv2.INTER_CUBIC)
    return np.clip(big, 0, 255).astype(np.uint8)


@pytest.mark.parametrize("view", RENDER_VIEWS, ids=lambda v: v.name)
def test_uint8_render_matches_numpy_bilinear(view: PerspectiveView) -> None:
    pano = smooth_uint8_panorama()
    img = ViewRenderer().render(pano, view)
    assert img.dtype == np.uint8
    ref = bilinear_reference(pano, view)
    d = np.abs(img.astype(np.float64) - ref)
    assert d.mean() < 0.6
    assert d.max() <= 4.0


def test_seam_is_continuous() -> None:
    """A view across the seam of a panorama with a sharp jump at the seam must show that jump only
    where the seam is, and blend the last/first columns there (no black border, no duplicated column)."""
    pano = np.full((PH, PW, 3), 50, np.uint8)
    pano[:, : PW // 2] = 200  # left half bright, right half dark: the seam is a 200 ↔ 50 edge
    view = PerspectiveView(math.pi, 0.0, math.radians(60), 65, 32)  # odd width: centre pixel on the seam
    img = ViewRenderer().render(pano, view).astype(int)[..., 0]
    row = img[16]
    # looking back: view's left is the panorama's right end (dark), view's right the start (bright)
    assert row[:31].max() == 50
    assert row[32] == 125  # exactly on the seam: half the last column, half the first (not the border)
    assert row[34:].min() == 200
    assert np.all(np.diff(row) >= 0)


def test_render_many_equals_render() -> None:
    pano = smooth_uint8_panorama(1)
    r = ViewRenderer()
    views = list(cube_faces(48).values()) + horizon_views(count=3, fov=1.2, width=48, height=30)
    many = r.render_many(pano, views)
    assert len(many) == len(views)
    for v, img in zip(views, many, strict=True):
        assert img.shape == (v.height, v.width, 3)
        assert img.flags["C_CONTIGUOUS"]
        np.testing.assert_array_equal(img, r.render(pano, v))
    # mixed widths fall back to one remap per view
    mixed = [views[0], PerspectiveView(0.0, 0.0, 1.0, 30, 20)]
    out = r.render_many(pano, mixed)
    assert [o.shape for o in out] == [(48, 48, 3), (20, 30, 3)]
    assert r.render_many(pano, []) == []


def test_grayscale_nearest_and_cubic() -> None:
    pano = smooth_uint8_panorama(2)
    gray = pano[..., 0].copy()
    v = PerspectiveView(0.7, 0.1, 1.0, 40, 30)
    r = ViewRenderer()
    assert r.render(gray, v).shape == (30, 40)
    near = r.render(pano, v, interpolation=cv2.INTER_NEAREST)
    # nearest: the pixel containing the exact panorama point (except within a LUT step of a pixel edge)
    p = v.view_to_pano(
        np.stack(np.meshgrid(np.arange(40) + 0.5, np.arange(30) + 0.5), -1).reshape(-1, 2), PW, PH
    )
    idx = (np.floor(p[:, 1]).astype(int).clip(0, PH - 1), np.floor(p[:, 0]).astype(int) % PW)
    ref = pano[idx].reshape(30, 40, 3)
    assert np.mean(np.all(near == ref, axis=-1)) > 0.97
    cubic = r.render(pano, v, interpolation=cv2.INTER_CUBIC)
    assert np.abs(cubic.astype(int) - r.render(pano, v).astype(int)).mean() < 2.0


@pytest.mark.parametrize("view", RENDER_VIEWS, ids=lambda v: v.name)
def test_view_maps_equal_view_to_pano(view: PerspectiveView) -> None:
    mx, my = view_maps(view, PW, PH)
    assert mx.shape == my.shape == (view.height, view.width)
    assert mx.dtype == my.dtype == np.float32
    jj, ii = np.mgrid[0 : view.height, 0 : view.width]
    p = view.view_to_pano(np.column_stack([ii.ravel() + 0.5, jj.ravel() + 0.5]), PW, PH)
    du = (mx.ravel() + 0.5 - p[:, 0] + PW / 2) % PW - PW / 2
    assert np.abs(du).max() < 1e-3
    np.testing.assert_allclose(my.ravel(), np.clip(p[:, 1] - 0.5, 0, PH - 1), atol=1e-3)
    assert mx.min() >= -0.5
    assert mx.max() <= PW - 0.5


def test_cache_is_bounded_and_reused() -> None:
    pano = smooth_uint8_panorama(3)
    r = ViewRenderer(max_entries=2)
    views = horizon_views(count=3, fov=1.0, width=16, height=16)
    for v in views:
        r.render(pano, v)
    assert len(r) == 2
    lut = r.lut(views[2], PW, PH)
    assert r.lut(views[2], PW, PH) is lut
    r.clear()
    assert len(r) == 0


@pytest.mark.parametrize("bad", [None, [[1, 2], [3, 4]], np.zeros((1, 1, 3)), np.zeros((4, 8, 3, 1))])
def test_render_rejects_bad_panorama(bad: object) -> None:
    with pytest.raises(GeometryError):
        ViewRenderer().render(bad, PerspectiveView(0.0, 0.0, 1.0, 8, 8))  # type: ignore[arg-type]


@pytest.mark.parametrize("pitch", [0.0, -0.2])
def test_views_at_whole_columns_share_the_yaw0_table(pitch: float) -> None:
    pano = smooth_uint8_panorama(4)
    r = ViewRenderer()
    for col in (1, 37, PW // 2, PW - 1, -200):  # PW // 2: looking back, across the seam
        view = PerspectiveView(col * PIX, pitch, math.radians(50), 40, 60)
        mx, my = view_maps(view, PW, PH)
        direct = cv2.remap(pano, mx, my, cv2.INTER_LINEAR, borderMode=cv2.BORDER_WRAP).astype(int)
        d = np.abs(r.render(pano, view).astype(int) - direct)
        assert d.max() <= 2  # the fixed-point tables round to 1/32 px
    assert len(r) == 1  # one table: the view at yaw 0
    off_grid = PerspectiveView(0.5 * PIX, pitch, math.radians(50), 40, 60)
    r.render(pano, off_grid)
    assert len(r) == 2
