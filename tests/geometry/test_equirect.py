"""The equirectangular camera: rays, projection with a camera pose, ground back-projection, image checks."""

from __future__ import annotations

import numpy as np
import pytest

from studio.errors import StudioError
from studio.geometry import EquirectCamera, GeometryError, Pose3

W, H = 1920, 960
POSE = Pose3.from_xyz_rpy(0.12, -0.05, 1.15, roll=0.03, pitch=-0.05, yaw=0.4)


def cyc(d: np.ndarray, period: float) -> np.ndarray:
    return (np.asarray(d) + period / 2) % period - period / 2


def test_default_pose_is_identity_and_with_pose() -> None:
    cam = EquirectCamera(W, H)
    np.testing.assert_array_equal(cam.pose.R, np.eye(3))
    np.testing.assert_array_equal(cam.pose.t, np.zeros(3))
    moved = cam.with_pose(POSE)
    assert moved.pose is POSE
    assert (moved.width, moved.height) == (W, H)
    assert cam.pose is not POSE
    assert moved == EquirectCamera(W, H, Pose3(POSE.R.copy(), POSE.t.copy()))
    assert moved != cam
    assert len({cam, moved, EquirectCamera(W, H)}) == 2


def test_pixel_rays_pixel_round_trip_incl_seam_and_poles() -> None:
    cam = EquirectCamera(W, H)
    rng = np.random.default_rng(0)
    edge = np.array(
        [
            [0.0, 0.5],
            [W - 1e-9, 0.5],
            [1e-9, H - 0.5],
            [W / 2, 1e-3],
            [10.0, H - 1e-3],
            [W - 0.5, H / 2],
            [0.0, H / 2],
        ]
    )
    uv = np.concatenate([rng.uniform([0, 0], [W, H], (10000, 2)), edge])
    r = cam.rays(uv)
    np.testing.assert_allclose(np.linalg.norm(r, axis=-1), 1.0, atol=1e-12)
    uv2 = cam.pixel_of_rays(r)
    assert np.max(np.abs(cyc(uv2[:, 0] - uv[:, 0], W))) < 1e-3
    assert np.max(np.abs(uv2[:, 1] - uv[:, 1])) < 1e-3
    # exact poles: every column of row 0 is the zenith
    np.testing.assert_allclose(cam.rays([[5.0, 0.0], [1000.0, 0.0]]), [[0, 0, 1], [0, 0, 1]], atol=1e-15)


def test_pixel_angles_round_trip_on_camera() -> None:
    cam = EquirectCamera(W, H)
    az = np.array([-np.pi, -1.0, 0.0, 2.0, np.nextafter(np.pi, 0.0)])
    el = np.array([-np.pi / 2, -0.3, 0.0, 1.0, np.pi / 2])
    u, v = cam.angles_to_pixel(az, el)
    az2, el2 = cam.pixel_to_angles(u, v)
    assert np.max(np.abs(cyc(az2 - az, 2 * np.pi))) < 1e-6
    assert np.max(np.abs(el2 - el)) < 1e-6


def test_project_hand_computed_with_yawed_camera() -> None:
    """Camera turned 90° left on a 1 m mast: a point ahead of the base is on the camera's right."""
    cam = EquirectCamera(W, H, Pose3.from_xyz_rpy(0.0, 0.0, 1.0, yaw=np.pi / 2))
    uv, depth = cam.project(np.array([[3.0, 0.0, 1.0], [0.0, 2.0, 3.0], [0.0, 0.0, -1.0]]))
    np.testing.assert_allclose(uv[0], [3 * W / 4, H / 2], atol=1e-9)  # right → 3W/4, on the horizon
    np.testing.assert_allclose(uv[1], [W / 2, H / 4], atol=1e-9)  # camera-forward, 45° up
    assert uv[2, 1] == pytest.approx(H)  # straight down → bottom edge
    np.testing.assert_allclose(depth, [3.0, np.sqrt(8.0), 2.0])


def test_project_backproject_consistency_with_pose() -> None:
    cam = EquirectCamera(W, H, POSE)
    rng = np.random.default_rng(1)
    pts = rng.uniform([-10, -10, -2], [10, 10, 4], (5000, 3))
    uv, depth = cam.project(pts)
    assert uv.shape == (5000, 2)
    assert depth.shape == (5000,)
    assert np.all((uv[:, 0] >= 0) & (uv[:, 0] < W) & (uv[:, 1] >= 0) & (uv[:, 1] <= H))
    np.testing.assert_allclose(depth, np.linalg.norm(pts - POSE.t, axis=1), rtol=1e-12)
    np.testing.assert_allclose(cam.backproject(uv, depth), pts, atol=1e-9)
    # bearing in base frame points from the camera centre to the point
    b = cam.bearing_base(uv)
    np.testing.assert_allclose(b, (pts - POSE.t) / depth[:, None], atol=1e-12)
    # the pose really matters: an identity-pose camera sees them elsewhere
    uv0, _ = EquirectCamera(W, H).project(pts)
    assert np.median(np.abs(cyc(uv0[:, 0] - uv[:, 0], W))) > 10.0


def test_project_centre_point_is_nan() -> None:
    cam = EquirectCamera(W, H, POSE)
    uv, depth = cam.project(POSE.t[None, :])
    assert np.all(np.isnan(uv))
    assert depth[0] == 0.0


def test_backproject_to_ground_hand_computed() -> None:
    cam = EquirectCamera(W, H, Pose3.from_xyz_rpy(0.0, 0.0, 1.15))
    # az = 0, el = -45° → 1.15 m ahead; az = +90°, el = -45° → 1.15 m left; above the horizon → NaN
    uv = np.array([[W / 2, 3 * H / 4], [W / 4, 3 * H / 4], [W / 2, H / 4], [W / 2, H / 2], [W / 2, H]])
    g = cam.backproject_to_ground(uv)
    np.testing.assert_allclose(g[0], [1.15, 0.0, 0.0], atol=1e-12)
    np.testing.assert_allclose(g[1], [0.0, 1.15, 0.0], atol=1e-12)
    assert np.all(np.isnan(g[2]))
    assert np.all(np.isnan(g[3]))  # the horizon never reaches the ground
    np.testing.assert_allclose(g[4], [0.0, 0.0, 0.0], atol=1e-12)  # straight down
    # a plane above the camera is reached by rays going up
    up = cam.backproject_to_ground(uv, ground_z=2.15)
    np.testing.assert_allclose(up[2], [1.0, 0.0, 2.15], atol=1e-12)
    assert np.all(np.isnan(up[0]))


def test_backproject_to_ground_inverts_project_with_pose() -> None:
    cam = EquirectCamera(W, H, POSE)
    rng = np.random.default_rng(2)
    for gz in (0.0, 0.3):
        pts = np.column_stack([rng.uniform(-8, 8, (2000, 2)), np.full(2000, gz)])
        uv, _ = cam.project(pts)
        np.testing.assert_allclose(cam.backproject_to_ground(uv, ground_z=gz), pts, atol=1e-8)


BAD_IMAGES = [
    ((H, W), "shape"),
    ((H, W, 4), "shape"),
    ((H, W, 1), "shape"),
    ((H, H, 3), "2:1"),
    ((480, 960, 3), "expects"),
    ((H + 1, W, 3), "2:1"),
]


@pytest.mark.parametrize(("shape", "words"), BAD_IMAGES)
def test_check_image_rejects(shape: tuple[int, ...], words: str) -> None:
    cam = EquirectCamera(W, H)
    with pytest.raises(GeometryError, match=words) as info:
        cam.check_image(np.zeros(shape, np.uint8))
    assert isinstance(info.value, StudioError)
    assert "\n" not in str(info.value)


def test_check_image_accepts_and_for_image() -> None:
    img = np.zeros((H, W, 3), np.uint8)
    EquirectCamera(W, H).check_image(img)
    cam = EquirectCamera.for_image(img, pose=POSE)
    assert (cam.width, cam.height) == (W, H)
    assert cam.pose is POSE
    with pytest.raises(GeometryError):
        EquirectCamera.for_image([[1, 2]])
    with pytest.raises(GeometryError):
        EquirectCamera.for_image(np.zeros((10, 30, 3)))


@pytest.mark.parametrize(("w", "h"), [(0, 10), (10, -1), (10.5, 5), (True, 5)])
def test_bad_camera_size(w: object, h: object) -> None:
    with pytest.raises(GeometryError):
        EquirectCamera(w, h)  # type: ignore[arg-type]
