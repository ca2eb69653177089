"""Extrinsics from correspondences: exactness, noise, outliers, held parameters, degenerate input, CV."""

from __future__ import annotations

import math

import numpy as np
import pytest

from studio.calibrate.extrinsics import (
    CalibrationError,
    check_correspondences,
    cross_validate,
    fit_extrinsics,
    pixel_residuals,
    project_points,
)
from studio.errors import StudioError
from studio.geometry.equirect import EquirectCamera
from studio.geometry.se import Pose3

UHD = (5376, 2688)
KEYS = "col_px_mean col_px_median col_px_p90 row_px_mean row_px_median ang_deg_mean n n_outliers".split()  # noqa: SIM905


def rot_deg(a: Pose3, b: Pose3) -> float:
    c = (np.trace(a.R.T @ b.R) - 1.0) / 2.0
    return math.degrees(math.acos(min(1.0, max(-1.0, c))))


def scene(
    pose: Pose3,
    *,
    n: int = 60,
    seed: int = 0,
    size: tuple[int, int] = UHD,
    sector: float = math.pi,
    z: tuple[float, float] = (0.0, 0.5),
) -> tuple[np.ndarray, np.ndarray]:
    """Ball-like targets 1–6 m around the laser, and their exact pixels."""
    rng = np.random.default_rng(seed)
    r = rng.uniform(1.0, 6.0, n)
    a = rng.uniform(-sector, sector, n)
    xyz = np.stack([r * np.cos(a), r * np.sin(a), rng.uniform(*z, n)], axis=1)
    return xyz, project_points(pose, xyz, image_size=size)


POSES = {
    "level": Pose3.from_xyz_rpy(0.1, 0.05, 1.1, 0.0, 0.0, 0.0),
    "yaw near +pi": Pose3.from_xyz_rpy(-0.2, 0.1, 0.5, 0.01, 0.02, math.pi - 1e-4),
    "yaw near -pi": Pose3.from_xyz_rpy(-0.2, 0.1, 0.5, 0.01, 0.02, -math.pi + 1e-4),
    "upside down": Pose3.from_xyz_rpy(0.0, 0.0, 1.3, math.pi, 0.0, 0.7),
    "tilted": Pose3.from_xyz_rpy(0.3, -0.3, 0.4, 0.2, -0.25, -1.0),
    "below the plane": Pose3.from_xyz_rpy(0.3, -0.3, -0.4, 0.0, 0.0, 2.0),
}


@pytest.mark.parametrize("sector", [math.pi, math.pi / 4], ids=["all around", "front 90deg"])
@pytest.mark.parametrize("name", list(POSES))
def test_noise_free_fit_is_exact_without_initial_guess(name: str, sector: float) -> None:
    true = POSES[name]
    xyz, uv = scene(true, n=30, sector=sector, seed=len(name))
    fit = fit_extrinsics(xyz, uv, image_size=UHD)
    assert np.abs(fit.residual_px).max() < 1e-6
    assert np.linalg.norm(fit.pose.t - true.t) < 1e-7
    assert rot_deg(fit.pose, true) < 1e-5
    assert fit.inliers.all()
    assert fit.n_outliers == 0
    assert fit.ang_err_deg.max() < 1e-6
    assert not fit.z_constant


def test_residuals_wrap_across_the_seam() -> None:
    # a point right behind the camera: u is near 0 or W; 1 px either side must be a 1 px residual
    pose = Pose3.identity()
    xyz = np.array([[-3.0, 1e-9, 0.0]])
    uv = project_points(pose, xyz, image_size=UHD)
    for shift in (-1.0, 1.0):
        obs = uv.copy()
        obs[0, 0] = (obs[0, 0] + shift) % UHD[0]
        r = pixel_residuals(pose, xyz, obs, image_size=UHD)
        assert r[0, 0] == pytest.approx(-shift, abs=1e-6)


def test_project_points_matches_the_camera_model() -> None:
    pose = POSES["tilted"]
    xyz, uv = scene(pose, n=10)
    uv_cam, _ = EquirectCamera(*UHD, pose).project(xyz)
    np.testing.assert_allclose(uv, uv_cam)
    assert ((uv[:, 0] >= 0) & (uv[:, 0] < UHD[0])).all()


def test_constant_z_keeps_columns_exact_and_camera_z_relative() -> None:
    # the ball centre is 0.3 m above the laser plane, but the file says z = 0 (height unknown)
    true = Pose3.from_xyz_rpy(0.12, -0.05, 0.85, 0.0, 0.0, 2.5)
    xyz, _ = scene(true, n=40, z=(0.3, 0.3))
    uv = project_points(true, xyz, image_size=UHD)
    xyz[:, 2] = 0.0
    fit = fit_extrinsics(xyz, uv, image_size=UHD)
    assert fit.z_constant
    assert np.abs(fit.residual_px).max() < 1e-6
    np.testing.assert_allclose(fit.pose.t, [0.12, -0.05, 0.85 - 0.3], atol=1e-7)


def test_half_pixel_noise_gives_sub_centimetre_pose() -> None:
    true = Pose3.from_xyz_rpy(0.15, -0.1, 0.95, 0.02, -0.03, 1.2)
    errs_t, errs_r = [], []
    for seed in range(3):
        xyz, uv = scene(true, n=60, seed=seed)
        uv = uv + np.random.default_rng(100 + seed).normal(0.0, 0.5, uv.shape)
        uv[:, 0] %= UHD[0]
        fit = fit_extrinsics(xyz, uv, image_size=UHD)
        errs_t.append(np.linalg.norm(fit.pose.t - true.t))
        errs_r.append(rot_deg(fit.pose, true))
        assert fit.n_outliers <= 1
        assert 0.3 < fit.sigma_px < 0.8
    assert max(errs_t) < 0.005
    assert max(errs_r) < 0.1


@pytest.mark.parametrize("frac", [0.1, 0.2])
def test_gross_outliers_are_rejected(frac: float) -> None:
    true = Pose3.from_xyz_rpy(-0.1, 0.2, 1.0, 0.01, 0.02, -2.0)
    rng = np.random.default_rng(7)
    xyz, uv = scene(true, n=100, seed=7)
    uv = uv + rng.normal(0.0, 1.0, uv.shape)
    bad = np.zeros(len(uv), dtype=bool)
    bad[rng.choice(len(uv), int(frac * len(uv)), replace=False)] = True
    uv[bad, 0] += rng.choice([-1.0, 1.0], bad.sum()) * rng.uniform(60, 600, bad.sum())
    uv[bad, 1] += rng.uniform(-150, 150, bad.sum())
    uv[:, 0] %= UHD[0]
    uv[:, 1] = np.clip(uv[:, 1], 0, UHD[1] - 1)
    fit = fit_extrinsics(xyz, uv, image_size=UHD)
    assert (~fit.inliers[bad]).all()  # every gross outlier rejected
    assert fit.inliers[~bad].mean() > 0.97  # and almost no good point
    assert np.linalg.norm(fit.pose.t - true.t) < 0.01
    assert rot_deg(fit.pose, true) < 0.2
    # a plain least-squares fit on the same data is far worse: the robust machinery matters
    plain = fit_extrinsics(xyz, uv, image_size=UHD, loss="linear", outlier_px=1e6)
    assert rot_deg(plain.pose, true) > 3 * rot_deg(fit.pose, true)


def test_outlier_threshold_option() -> None:
    true = POSES["level"]
    xyz, uv = scene(true, n=40)
    uv[3, 0] = (uv[3, 0] + 8.0) % UHD[0]
    assert not fit_extrinsics(xyz, uv, image_size=UHD, outlier_px=5.0).inliers[3]
    assert fit_extrinsics(xyz, uv, image_size=UHD, outlier_px=50.0).inliers[3]


def test_fixed_parameters_are_held_at_initial() -> None:
    true = Pose3.from_xyz_rpy(0.1, 0.0, 1.0, 0.0, 0.0, 0.5)
    xyz, uv = scene(true, n=40)
    initial = Pose3.from_xyz_rpy(0.0, 0.0, 1.0, 0.0, 0.0, 0.4)
    fit = fit_extrinsics(xyz, uv, image_size=UHD, initial=initial, fixed=("z", "roll", "pitch"))
    d = fit.pose.as_dict()
    assert d["z"] == 1.0
    assert d["roll"] == 0.0
    assert d["pitch"] == 0.0
    assert d["yaw"] == pytest.approx(0.5, abs=1e-8)
    assert d["x"] == pytest.approx(0.1, abs=1e-8)
    # holding a wrong value leaves residuals: the parameter really is fixed
    wrong = Pose3.from_xyz_rpy(0.0, 0.0, 1.2, 0.0, 0.0, 0.4)
    held = fit_extrinsics(xyz, uv, image_size=UHD, initial=wrong, fixed=("z",))
    assert held.pose.t[2] == 1.2


def test_initial_guess_is_used_and_translation_only_fit() -> None:
    true = POSES["tilted"]
    xyz, uv = scene(true, n=30)
    start = Pose3(true.R, true.t + np.array([0.3, -0.2, 0.1]))
    fit = fit_extrinsics(xyz, uv, image_size=UHD, initial=start, fixed=("roll", "pitch", "yaw"))
    np.testing.assert_allclose(fit.pose.t, true.t, atol=1e-7)


def _base() -> tuple[np.ndarray, np.ndarray]:
    return scene(POSES["level"], n=12, seed=3)


def _few() -> tuple[np.ndarray, np.ndarray]:
    xyz, uv = _base()
    return xyz[:5], uv[:5]


def _nan() -> tuple[np.ndarray, np.ndarray]:
    xyz, uv = _base()
    xyz[4, 1] = np.nan
    return xyz, uv


def _inf() -> tuple[np.ndarray, np.ndarray]:
    xyz, uv = _base()
    uv[2, 0] = np.inf
    return xyz, uv


def _outside_u() -> tuple[np.ndarray, np.ndarray]:
    xyz, uv = _base()
    uv[6, 0] = UHD[0]
    return xyz, uv


def _outside_v() -> tuple[np.ndarray, np.ndarray]:
    xyz, uv = _base()
    uv[1, 1] = -0.5
    return xyz, uv


def _collinear() -> tuple[np.ndarray, np.ndarray]:
    s = np.linspace(1.0, 5.0, 10)
    xyz = np.stack([s, 0.5 * s + 0.2, np.zeros_like(s)], axis=1)
    return xyz, project_points(POSES["level"], xyz, image_size=UHD)


def _one_place() -> tuple[np.ndarray, np.ndarray]:
    xyz = np.tile([[2.0, 1.0, 0.0]], (8, 1))
    uv = np.tile([[100.0, 1500.0]], (8, 1)) + np.arange(8)[:, None]
    return xyz, uv


def _duplicated() -> tuple[np.ndarray, np.ndarray]:
    xyz, uv = _base()
    xyz[9], uv[9] = xyz[2], uv[2]
    return xyz, uv


def _bad_shape() -> tuple[np.ndarray, np.ndarray]:
    xyz, uv = _base()
    return xyz[:, :2], uv


DEGENERATE = {
    "fewer than 6": (_few, "at least 6"),
    "NaN": (_nan, "row 5"),
    "inf": (_inf, "row 3"),
    "u outside": (_outside_u, "outside"),
    "v outside": (_outside_v, "row 2"),
    "collinear": (_collinear, "one line"),
    "all at one place": (_one_place, "one line"),
    "duplicated": (_duplicated, "row 3, row 10"),
    "shape": (_bad_shape, "shape"),
}


@pytest.mark.parametrize("case", list(DEGENERATE))
def test_degenerate_input_names_the_problem(case: str) -> None:
    make, words = DEGENERATE[case]
    xyz, uv = make()
    with pytest.raises(CalibrationError, match=words) as info:
        fit_extrinsics(xyz, uv, image_size=UHD)
    assert isinstance(info.value, StudioError)
    assert "\n" not in str(info.value)


def test_labels_name_rows_in_messages() -> None:
    xyz, uv = _nan()
    labels = [f"line {i + 2}" for i in range(len(xyz))]
    with pytest.raises(CalibrationError, match="line 6"):
        check_correspondences(xyz, uv, image_size=UHD, labels=labels)


def test_bad_options() -> None:
    xyz, uv = _base()
    with pytest.raises(CalibrationError, match="initial"):
        fit_extrinsics(xyz, uv, image_size=UHD, fixed=("z",))
    with pytest.raises(CalibrationError, match="unknown fixed"):
        fit_extrinsics(xyz, uv, image_size=UHD, initial=Pose3.identity(), fixed=("height",))
    with pytest.raises(CalibrationError, match="loss"):
        fit_extrinsics(xyz, uv, image_size=UHD, loss="l3")
    with pytest.raises(CalibrationError, match="folds"):
        cross_validate(xyz, uv, image_size=UHD, folds=1)


def test_random_pixels_do_not_give_a_confident_pose() -> None:
    xyz, _ = _base()
    rng = np.random.default_rng(0)
    uv = np.stack([rng.uniform(0, UHD[0], len(xyz)), rng.uniform(0, UHD[1], len(xyz))], axis=1)
    try:
        fit = fit_extrinsics(xyz, uv, image_size=UHD)
    except CalibrationError as exc:
        message = str(exc)
    else:
        message = "agrees" if (fit.sigma_px > 20 or fit.n_outliers > 3) else "looks confident"
    assert "agrees" in message


def test_cross_validation_keys_and_values() -> None:
    true = Pose3.from_xyz_rpy(0.1, 0.0, 0.9, 0.01, -0.02, 0.4)
    xyz, uv = scene(true, n=50, seed=11)
    rng = np.random.default_rng(11)
    uv = uv + rng.normal(0.0, 1.0, uv.shape)
    uv[:, 0] %= UHD[0]
    uv[[4, 17], 0] = (uv[[4, 17], 0] + 400.0) % UHD[0]
    cv = cross_validate(xyz, uv, image_size=UHD, folds=5, seed=1)
    j = cv.to_json()
    assert set(KEYS) <= set(j)
    assert j["n"] == 50
    assert j["n_outliers"] == 2
    assert j["folds"] == 5
    # held-out errors of 1 px noise: about 0.8 px mean, never better than in-sample
    assert 0.5 < j["col_px_mean"] < 1.5
    assert j["col_px_median"] <= j["col_px_p90"]
    assert j["col_px_mean_all"] > 10  # the two wrong ones count in the *_all numbers
    assert j["fold_spread_m"] < 0.02
    assert np.bincount(cv.fold).tolist() == [10] * 5
    assert "outliers rejected 2" in cv.table()
    # deterministic
    assert cross_validate(xyz, uv, image_size=UHD, folds=5, seed=1).to_json() == j


def test_cross_validation_with_few_points_is_leave_one_out() -> None:
    xyz, uv = scene(POSES["level"], n=6, seed=5)
    cv = cross_validate(xyz, uv, image_size=UHD, folds=5)
    assert cv.folds == 6  # 5 folds would leave 4 training points; leave-one-out leaves 5
    assert np.nanmax(np.abs(cv.col_err_px)) < 1e-5
