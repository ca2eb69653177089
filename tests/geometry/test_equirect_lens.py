"""The dual-lens (per-lens parallax) model of :class:`EquirectCamera` (``lens_offset``)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from studio.geometry.equirect import EquirectCamera
from studio.geometry.errors import GeometryError
from studio.geometry.se import Pose3

B = 0.013
POSE = Pose3.from_xyz_rpy(0.1, -0.05, 0.8, 0.02, -0.03, 0.7)


def _points(rng: np.random.Generator, n: int, *, min_abs_x: float) -> np.ndarray:
    """Camera-frame points at 0.5..6 m with |x| > min_abs_x, in the base frame of POSE."""
    d = rng.normal(size=(4 * n, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    p = d * rng.uniform(0.5, 6.0, size=(4 * n, 1))
    p = p[np.abs(p[:, 0]) > min_abs_x][:n]
    return POSE.apply(p)


def test_zero_offset_is_the_central_camera() -> None:
    rng = np.random.default_rng(0)
    pts = _points(rng, 200, min_abs_x=0.0)
    a, b = EquirectCamera(3840, 1920, POSE), EquirectCamera(3840, 1920, POSE, lens_offset=0.0)
    uv_a, d_a = a.project(pts)
    uv_b, d_b = b.project(pts)
    assert np.array_equal(uv_a, uv_b)
    assert np.array_equal(d_a, d_b)
    assert np.array_equal(a.ray_origins_base(uv_a), np.broadcast_to(POSE.t, pts.shape))
    assert a == b
    assert hash(a) == hash(b)
    assert a != EquirectCamera(3840, 1920, POSE, lens_offset=B)


@pytest.mark.parametrize("b", [B, -0.02])
def test_project_backproject_round_trip(b: float) -> None:
    rng = np.random.default_rng(1)
    cam = EquirectCamera(3840, 1920, POSE, lens_offset=b)
    pts = _points(rng, 500, min_abs_x=2 * abs(b))
    uv, depth = cam.project(pts)
    back = cam.backproject(uv, depth)
    np.testing.assert_allclose(back, pts, atol=1e-9)
    # the central camera's round trip with the same pixels misses by up to ~b
    central = EquirectCamera(3840, 1920, POSE).backproject(uv, depth)
    assert np.max(np.linalg.norm(central - pts, axis=1)) > 0.5 * abs(b)


def test_ground_round_trip() -> None:
    rng = np.random.default_rng(2)
    cam = EquirectCamera(3840, 1920, Pose3.from_xyz_rpy(0.0, 0.0, 1.1, 0.0, 0.0, 0.4), lens_offset=B)
    xy = rng.uniform(-5, 5, size=(300, 2))
    pts = np.column_stack([xy, np.zeros(len(xy))])
    p_cam = cam.pose.inverse().apply(pts)
    pts = pts[np.abs(p_cam[:, 0]) > 2 * B]
    uv, _ = cam.project(pts)
    np.testing.assert_allclose(cam.backproject_to_ground(uv, ground_z=0.0), pts, atol=1e-9)


def test_hand_computed_pixel() -> None:
    # camera at the origin, identity rotation, W×H = 3600×1800 (10 px per degree)
    cam = EquirectCamera(3600, 1800, lens_offset=0.5)
    # (1.5, 1, 0): front lens at (0.5, 0, 0) sees direction (1, 1, 0): az = +45° → u = 1800 − 450
    uv, depth = cam.project(np.array([[1.5, 1.0, 0.0], [-1.5, 0.0, 1.0]]))
    np.testing.assert_allclose(uv[0], [1350.0, 900.0], atol=1e-9)
    assert depth[0] == pytest.approx(math.sqrt(2.0))
    # (-1.5, 0, 1): back lens at (-0.5, 0, 0) sees (-1, 0, 1): az = 180° → seam (u = 0), el = +45°
    assert uv[1, 0] == pytest.approx(0.0, abs=1e-9) or uv[1, 0] == pytest.approx(3600.0, abs=1e-9)
    assert uv[1, 1] == pytest.approx(900.0 - 450.0)
    np.testing.assert_allclose(cam.ray_origins_base(uv), [[0.5, 0, 0], [-0.5, 0, 0]], atol=1e-12)


def test_continuous_away_from_the_stitching_plane() -> None:
    cam = EquirectCamera(3840, 1920, POSE, lens_offset=B)
    # a path in camera frame that stays at x >= 0.2 m: pixels move smoothly
    s = np.linspace(0.0, 1.0, 2001)
    path_cam = np.column_stack([0.2 + 2 * s, 1.0 + np.sin(6 * s), 0.3 * np.cos(3 * s)])
    uv, _ = cam.project(POSE.apply(path_cam))
    du = np.abs(np.diff(uv, axis=0))
    du[:, 0] = np.minimum(du[:, 0], 3840 - du[:, 0])
    assert du.max() < 5.0
    # crossing x = 0 jumps by the parallax (2b seen from ~1 m ≈ 0.026 rad ≈ 16 px)
    cross = np.array([[1e-6, 1.0, 0.0], [-1e-6, 1.0, 0.0]])
    uv2, _ = cam.project(POSE.apply(cross))
    assert abs(uv2[0, 0] - uv2[1, 0]) > 10.0


@pytest.mark.parametrize("bad", [math.nan, math.inf, "0.01", True])
def test_bad_lens_offset(bad: object) -> None:
    with pytest.raises(GeometryError):
        EquirectCamera(100, 50, lens_offset=bad)  # type: ignore[arg-type]
