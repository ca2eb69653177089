"""Perspective views: model, view ↔ panorama pixel mapping, exact box mapping (across the seam, poles)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from studio.geometry import GeometryError, PerspectiveView, cube_faces, horizon_views, rot_from_rpy

W, H = 1920, 960


def cyc(d: np.ndarray, period: float) -> np.ndarray:
    return (np.asarray(d) + period / 2) % period - period / 2


def independent_ray(view: PerspectiveView, uv: np.ndarray) -> np.ndarray:
    """Camera-frame ray of view pixels, written independently of PerspectiveView.rays.

    Body-frame look direction x = 1, left = -(u - cx)/f, up = -(v - cy)/f, then turned by the view's pitch
    (a positive ROS pitch tilts x down, so the view's pitch enters negated) and yaw.
    """
    f = (view.width / 2) / math.tan(view.fov / 2)
    body = np.column_stack(
        [np.ones(len(uv)), -(uv[:, 0] - view.width / 2) / f, -(uv[:, 1] - view.height / 2) / f]
    )
    body /= np.linalg.norm(body, axis=1, keepdims=True)
    return body @ rot_from_rpy(0.0, -view.pitch, view.yaw).T


def pano_of_rays(r: np.ndarray) -> np.ndarray:
    az = np.arctan2(r[:, 1], r[:, 0])
    el = np.arctan2(r[:, 2], np.hypot(r[:, 0], r[:, 1]))
    return np.column_stack([((0.5 - az / (2 * np.pi)) * W) % W, (0.5 - el / np.pi) * H])


VIEWS = [
    PerspectiveView(0.0, 0.0, math.radians(90), 256, 256),
    PerspectiveView(math.pi, 0.0, math.radians(90), 320, 240),  # across the seam
    PerspectiveView(-2.5, 0.4, math.radians(70), 300, 200),
    PerspectiveView(1.0, -1.2, math.radians(120), 200, 300),
    PerspectiveView(0.3, math.pi / 2, math.radians(90), 128, 128),  # looking straight up
    PerspectiveView(-0.7, -math.pi / 2, math.radians(100), 160, 128),  # straight down
]


def test_K_and_rotation() -> None:
    v = PerspectiveView(0.0, 0.0, math.radians(90), 640, 480)
    np.testing.assert_allclose(v.K(), [[320, 0, 320], [0, 320, 240], [0, 0, 1]], atol=1e-9)
    assert v.vfov == pytest.approx(2 * math.atan(240 / 320))
    # optical z forward = body x, optical x right = body -y, optical y down = body -z
    np.testing.assert_allclose(v.R_cam_view(), [[0, 0, 1], [-1, 0, 0], [0, -1, 0]], atol=1e-15)
    for view in VIEWS:
        R = view.R_cam_view()
        np.testing.assert_allclose(R.T @ R, np.eye(3), atol=1e-12)
        assert np.linalg.det(R) == pytest.approx(1.0)


@pytest.mark.parametrize("view", VIEWS, ids=lambda v: f"yaw{v.yaw:.2f}_pitch{v.pitch:.2f}")
def test_view_to_pano_matches_independent_model(view: PerspectiveView) -> None:
    rng = np.random.default_rng(0)
    uv = rng.uniform([0, 0], [view.width, view.height], (3000, 2))
    np.testing.assert_allclose(view.rays(uv), independent_ray(view, uv), atol=1e-12)
    got = view.view_to_pano(uv, W, H)
    exp = pano_of_rays(independent_ray(view, uv))
    assert np.max(np.abs(cyc(got[:, 0] - exp[:, 0], W))) < 1e-6
    assert np.max(np.abs(got[:, 1] - exp[:, 1])) < 1e-6
    assert np.all((got[:, 0] >= 0) & (got[:, 0] < W))


@pytest.mark.parametrize("view", VIEWS, ids=lambda v: f"yaw{v.yaw:.2f}_pitch{v.pitch:.2f}")
def test_view_pano_round_trips(view: PerspectiveView) -> None:
    rng = np.random.default_rng(1)
    corners = np.array([[0, 0], [view.width, 0], [0, view.height], [view.width, view.height]], float)
    uv = np.concatenate([rng.uniform([0, 0], [view.width, view.height], (3000, 2)), corners])
    back = view.pano_to_view(view.view_to_pano(uv, W, H), W, H)
    np.testing.assert_allclose(back, uv, atol=1e-3)
    assert np.max(np.abs(back - uv)) < 1e-6
    # panorama → view → panorama for panorama pixels the view sees
    pano = rng.uniform([0, 1], [W, H - 1], (20000, 2))
    vv = view.pano_to_view(pano, W, H)
    seen = np.all(np.isfinite(vv), axis=1) & np.all((vv >= 0) & (vv <= [view.width, view.height]), axis=1)
    assert seen.sum() > 50
    again = view.view_to_pano(vv[seen], W, H)
    assert np.max(np.abs(cyc(again[:, 0] - pano[seen, 0], W))) < 1e-3
    assert np.max(np.abs(again[:, 1] - pano[seen, 1])) < 1e-3


def test_pano_to_view_behind_is_nan() -> None:
    v = PerspectiveView(0.0, 0.0, math.radians(90), 256, 256)
    out = v.pano_to_view([[0.0, H / 2], [W / 4, H / 2], [W / 2, H / 2]], W, H)
    assert np.all(np.isnan(out[0]))  # straight behind
    assert np.all(np.isnan(out[1]))  # 90° to the side: on the image plane's horizon line
    np.testing.assert_allclose(out[2], [128, 128])


# ---------------------------------------------------------------- boxes


def brute_force_box(view: PerspectiveView, box: np.ndarray, n: int = 4000) -> np.ndarray:
    """Bounds of the densely sampled outline (unwrapped along it) and interior."""
    u1, v1, u2, v2 = box
    t = np.linspace(0.0, 1.0, n, endpoint=False)
    outline = np.concatenate(
        [
            np.column_stack([u1 + (u2 - u1) * t, np.full(n, v1)]),
            np.column_stack([np.full(n, u2), v1 + (v2 - v1) * t]),
            np.column_stack([u2 - (u2 - u1) * t, np.full(n, v2)]),
            np.column_stack([np.full(n, u1), v2 - (v2 - v1) * t]),
        ]
    )
    p = view.view_to_pano(outline, W, H)
    u = np.unwrap(p[:, 0], period=W)
    return np.array([u.min(), p[:, 1].min(), u.max(), p[:, 1].max()])


def test_box_across_the_seam_is_one_box() -> None:
    view = PerspectiveView(math.pi, 0.0, math.radians(90), 256, 256)  # looking straight back
    box = np.array([108.0, 98.0, 148.0, 198.0])  # centred in the view
    out = view.box_to_pano(box, W, H)
    assert out.shape == (1, 4)
    u1, _, u2, _ = out[0]
    assert 0 <= u1 < W
    assert u2 > W
    assert (u1 + u2) / 2 == pytest.approx(W, abs=1e-6)  # symmetric about the seam
    # matches the brute force outline (shifted to the same copy of the seam)
    bf = brute_force_box(view, box)
    shift = u1 - bf[0]
    assert abs(cyc(shift, W)) < 0.05
    np.testing.assert_allclose(out[0], bf + np.array([shift, 0.0, shift, 0.0]), atol=0.05)
    # the box's own width: 40 view px ≈ atan geometry, by hand
    half = math.atan(20 / 128) / (2 * math.pi) * W
    assert u2 - u1 == pytest.approx(2 * half, abs=1e-9)


def test_box_top_edge_bulges_in_the_panorama() -> None:
    """A straight top edge in a level view is highest (smallest v) in its middle, not at its corners."""
    view = PerspectiveView(0.0, 0.0, math.radians(90), 256, 256)
    box = np.array([28.0, 20.0, 228.0, 120.0])
    out = view.box_to_pano(box, W, H)[0]
    corner_v = view.view_to_pano([[28.0, 20.0], [228.0, 20.0]], W, H)[:, 1]
    mid_v = view.view_to_pano([[128.0, 20.0]], W, H)[0, 1]
    assert mid_v < corner_v.min() - 5
    assert out[1] == pytest.approx(mid_v, abs=1e-9)


def test_box_to_pano_matches_brute_force_random() -> None:
    rng = np.random.default_rng(2)
    for _ in range(60):
        view = PerspectiveView(
            float(rng.uniform(-np.pi, np.pi)),
            float(rng.uniform(-1.2, 1.2)),
            float(rng.uniform(0.5, 2.4)),
            int(rng.integers(64, 400)),
            int(rng.integers(64, 400)),
        )
        a = rng.uniform([0, 0], [view.width, view.height], (2, 2))
        box = np.array([a[:, 0].min(), a[:, 1].min(), a[:, 0].max(), a[:, 1].max()])
        out = view.box_to_pano(box, W, H)[0]
        bf = brute_force_box(view, box)
        assert 0 <= out[0] < W
        assert out[2] - out[0] <= W
        if out[2] - out[0] == W:  # a pole inside: the brute force must cross the whole width too
            assert bf[2] - bf[0] > W * 0.98
            continue
        shift = out[0] - bf[0]
        assert abs(cyc(shift, W)) < 0.05, (view, box)
        # exact bounds contain the sampled ones and are within sampling error of them
        np.testing.assert_allclose(out, bf + np.array([shift, 0.0, shift, 0.0]), atol=0.05)


def test_box_containing_a_pole_spans_full_width() -> None:
    up = PerspectiveView(0.4, math.radians(80), math.radians(90), 256, 256)
    out = up.box_to_pano([[28, 28, 228, 228]], W, H)[0]
    assert out[0] == 0.0
    assert out[2] == W
    assert out[1] == pytest.approx(0.0)
    bf = brute_force_box(up, np.array([28, 28, 228, 228.0]))
    assert out[3] == pytest.approx(bf[3], abs=0.05)
    down = cube_faces(200)["down"]
    out = down.box_to_pano([90, 90, 110, 110], W, H)[0]
    assert (out[0], out[2], out[3]) == (0.0, W, pytest.approx(H))
    # a box beside the pole does not get the full width
    out = down.box_to_pano([150, 150, 190, 190], W, H)[0]
    assert out[2] - out[0] < W / 2


def test_box_to_pano_many_and_unordered_corners() -> None:
    view = PerspectiveView(1.0, 0.2, math.radians(80), 300, 200)
    boxes = np.array([[10, 20, 50, 90], [200, 150, 120, 60]], float)
    out = view.box_to_pano(boxes, W, H)
    assert out.shape == (2, 4)
    np.testing.assert_allclose(out[1], view.box_to_pano([120, 60, 200, 150], W, H)[0])


# ---------------------------------------------------------------- view sets and validation


def test_cube_faces() -> None:
    faces = cube_faces(100)
    assert list(faces) == ["front", "left", "back", "right", "up", "down"]
    for k, v in faces.items():
        assert v.name == k
        assert (v.width, v.height) == (100, 100)
        assert v.focal == pytest.approx(50.0)
    centre = np.array([[50.0, 50.0]])
    np.testing.assert_allclose(faces["front"].view_to_pano(centre, W, H), [[W / 2, H / 2]])
    np.testing.assert_allclose(faces["left"].view_to_pano(centre, W, H), [[W / 4, H / 2]])
    np.testing.assert_allclose(faces["right"].view_to_pano(centre, W, H), [[3 * W / 4, H / 2]])
    assert faces["back"].view_to_pano(centre, W, H)[0, 0] % W == pytest.approx(0.0, abs=1e-9)
    assert faces["up"].view_to_pano(centre, W, H)[0, 1] == pytest.approx(0.0)
    assert faces["down"].view_to_pano(centre, W, H)[0, 1] == pytest.approx(H)
    # up: image top towards the back; down: image top towards the front
    top_up = faces["up"].rays([[50.0, 0.0]])[0]
    top_down = faces["down"].rays([[50.0, 0.0]])[0]
    assert top_up[0] < -0.5
    assert top_down[0] > 0.5
    # the faces tile the sphere: each direction is inside exactly one face (up to the edges)
    rng = np.random.default_rng(3)
    r = rng.normal(size=(5000, 3))
    inside = np.zeros(len(r), int)
    for v in faces.values():
        uv = v.pixel_of_rays(r)
        inside += np.all(np.isfinite(uv), axis=1) & np.all((uv >= 0) & (uv < 100), axis=1)
    assert np.all(inside == 1)


def test_horizon_views() -> None:
    views = horizon_views(count=8, fov=math.radians(60), width=256, height=192, pitch=-0.1, yaw0=0.2)
    assert len(views) == 8
    yaws = np.array([v.yaw for v in views])
    np.testing.assert_allclose(cyc(np.diff(yaws), 2 * np.pi), 2 * np.pi / 8)
    assert yaws[0] == pytest.approx(0.2)
    assert np.all((yaws >= -np.pi) & (yaws < np.pi))
    assert all(v.pitch == -0.1 and v.width == 256 and v.height == 192 for v in views)
    assert len({v.name for v in views}) == 8
    with pytest.raises(GeometryError):
        horizon_views(count=0, fov=1.0, width=10, height=10)


@pytest.mark.parametrize(
    "kwargs",
    [
        {"fov": 0.0},
        {"fov": math.pi},
        {"fov": float("nan")},
        {"pitch": 1.7},
        {"width": 0},
        {"height": 2.5},
        {"yaw": "left"},
    ],
)
def test_view_validation(kwargs: dict[str, object]) -> None:
    base: dict[str, object] = {"yaw": 0.0, "pitch": 0.0, "fov": 1.0, "width": 10, "height": 10}
    base.update(kwargs)
    with pytest.raises(GeometryError):
        PerspectiveView(**base)  # type: ignore[arg-type]


def test_views_are_hashable_keys() -> None:
    a = PerspectiveView(0, 0, 1.0, 10, 10)
    b = PerspectiveView(0.0, 0.0, 1.0, 10, 10)
    assert a == b
    assert hash(a) == hash(b)
    assert isinstance(a.yaw, float)
