"""Extrinsics on realistic and on broken input: a mirrored laser, weak geometry, few points, a sweep."""

from __future__ import annotations

import itertools
import math
from pathlib import Path

import numpy as np
import pytest

from studio.calibrate.extrinsics import CalibrationError, cross_validate, fit_extrinsics, project_points
from studio.cli import main
from studio.geometry.se import Pose3

UHD = (3840, 1920)  # a Ricoh Theta's UHD panorama
TRUE = Pose3.from_xyz_rpy(-0.25, 0.03, 0.45, 0.01, -0.015, 0.8)


def ring(
    n: int, *, seed: int, sector: float = 2 * math.pi, z: tuple[float, float] = (0.1, 0.3)
) -> np.ndarray:
    """Ball centres 1–6 m around the laser in a sector of the given width (radians)."""
    rng = np.random.default_rng(seed)
    a = rng.uniform(-sector / 2, sector / 2, n) + 0.3
    r = rng.uniform(1.0, 6.0, n)
    return np.stack([r * np.cos(a), r * np.sin(a), rng.uniform(*z, n)], axis=1)


def observe(pose: Pose3, xyz: np.ndarray, *, noise: float, seed: int) -> np.ndarray:
    uv = project_points(pose, xyz, image_size=UHD)
    uv = uv + np.random.default_rng(seed + 1000).normal(0.0, noise, uv.shape)
    uv[:, 0] %= UHD[0]
    uv[:, 1] = np.clip(uv[:, 1], 0.0, UHD[1] - 1.0)
    return uv


# ---------------------------------------------------------------------------------------- mirrored laser
def test_mirrored_laser_with_heights_is_refused(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    xyz = ring(40, seed=1, z=(0.0, 0.35))
    uv = observe(TRUE, xyz, noise=2.0, seed=1)
    fit_extrinsics(xyz, uv, image_size=UHD)  # as recorded: fine
    flipped = xyz * [1.0, -1.0, 1.0]  # the laser mounted upside down, scans not turned over
    with pytest.raises(CalibrationError, match=r"y axis looks mirrored.*Negate the y column") as info:
        fit_extrinsics(flipped, uv, image_size=UHD)
    assert "\n" not in str(info.value)
    # the command: exit 2, one line, nothing written
    p = tmp_path / "c.csv"
    p.write_text("x,y,z,u,v\n" + "\n".join(",".join(f"{c:.6f}" for c in r) for r in np.c_[flipped, uv]))
    out = tmp_path / "calib.yaml"
    args = ["calibrate", "extrinsics", "--correspondences", str(p), "--image-size", "3840x1920"]
    assert main([*args, "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1
    assert "mirrored" in err
    assert not out.exists()


@pytest.mark.parametrize("height", [0.1, 0.3, 0.6])
def test_mirrored_laser_with_unknown_heights_is_refused(height: float) -> None:
    # every z = 0 (unknown) and the ball centre `height` above the laser: a mirror is then a half turn
    # about x, so a rigid pose does fit, upside down; that is refused as a mirrored laser
    xyz = ring(30, seed=2, z=(height, height))
    uv = observe(TRUE, xyz, noise=2.0, seed=2)
    xyz[:, 2] = 0.0
    assert fit_extrinsics(xyz, uv, image_size=UHD).pose.R[2, 2] > 0.99
    with pytest.raises(CalibrationError, match="camera comes out upside down"):
        fit_extrinsics(xyz * [1.0, -1.0, 1.0], uv, image_size=UHD)


def test_upside_down_camera_is_still_fitted_when_heights_tell() -> None:
    true = Pose3.from_xyz_rpy(0.05, 0.0, 0.9, math.pi, 0.0, -0.4)
    xyz = ring(30, seed=3, z=(0.0, 0.5))
    uv = observe(true, xyz, noise=0.0, seed=3)
    fit = fit_extrinsics(xyz, uv, image_size=UHD)
    assert np.abs(fit.residual_px).max() < 1e-6
    # with one z for all points the two cannot be told apart: refused, unless asked not to check
    xyz[:, 2] = 0.2
    uv = observe(true, xyz, noise=0.0, seed=3)
    with pytest.raises(CalibrationError, match="check_mirror=False"):
        fit_extrinsics(xyz, uv, image_size=UHD)
    fit = fit_extrinsics(xyz, uv, image_size=UHD, check_mirror=False)
    np.testing.assert_allclose(fit.pose.t, true.t, atol=1e-6)


# ---------------------------------------------------------------------------------------- weak geometry
def _nearly_collinear() -> np.ndarray:
    rng = np.random.default_rng(4)
    s = np.linspace(1.0, 5.0, 20)
    return np.stack([s, 2 * s - 3 + rng.normal(0, 0.03, 20), 0.2 + rng.normal(0, 0.03, 20)], axis=1)


def _one_azimuth() -> np.ndarray:
    return ring(20, seed=5, sector=0.0, z=(0.0, 0.3))


@pytest.mark.parametrize(
    ("make", "words"),
    [(_nearly_collinear, "nearly on one line"), (_one_azimuth, "all within 0° of azimuth")],
    ids=["nearly collinear", "one azimuth"],
)
def test_undetermined_pose_is_refused(make: object, words: str) -> None:
    xyz = make()  # type: ignore[operator]
    uv = observe(TRUE, xyz, noise=2.0, seed=6)
    with pytest.raises(CalibrationError, match=f"do not determine the camera pose.*{words}"):
        fit_extrinsics(xyz, uv, image_size=UHD)
    fit_extrinsics(xyz, uv, image_size=UHD, check_geometry=False)  # the check, not the fit, refuses


@pytest.mark.parametrize("n", [6, 7, 8])
def test_few_points_all_around_give_a_pose_and_leave_one_out(n: int) -> None:
    xyz = ring(n, seed=10 + n)
    uv = observe(TRUE, xyz, noise=2.0, seed=10 + n)
    cv = cross_validate(xyz, uv, image_size=UHD, folds=5)
    assert cv.folds == (6 if n == 6 else 5)  # 5 folds would leave 4 of 6 points to train on
    assert cv.fit.n_outliers == 0  # no good point thrown away because the fit follows the others
    assert np.linalg.norm(cv.fit.pose.t - TRUE.t) < 0.05
    assert np.isfinite(cv.col_err_px).all()
    assert cv.to_json()["col_px_mean"] < 5.0  # 2 px noise, 6 parameters on 4–7 training points


def test_more_folds_than_points_is_leave_one_out(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    xyz = ring(8, seed=20)
    uv = observe(TRUE, xyz, noise=1.0, seed=20)
    p = tmp_path / "c.csv"
    p.write_text("x,y,z,u,v\n" + "\n".join(",".join(f"{c:.6f}" for c in r) for r in np.c_[xyz, uv]))
    args = ["calibrate", "extrinsics", "--correspondences", str(p), "--image-size", "3840x1920"]
    assert main([*args, "--folds", "50", "--out", str(tmp_path / "calib.yaml")]) == 0
    out = capsys.readouterr().out
    assert "(8-fold CV)" in out
    assert "8-fold cross-validation instead of --folds 50" in out


def test_every_point_an_outlier_is_refused() -> None:
    xyz = ring(30, seed=7)
    rng = np.random.default_rng(7)
    uv = np.stack([rng.uniform(0, UHD[0], 30), rng.uniform(0, UHD[1], 30)], axis=1)
    with pytest.raises(CalibrationError, match="no camera pose agrees with"):
        fit_extrinsics(xyz, uv, image_size=UHD)


# ---------------------------------------------------------------------------------------- sweep
SWEEP = list(
    itertools.product(
        [2 * math.pi, math.pi / 2],  # all around / a 90° sector
        ["unknown z", "measured z"],
        [(0.1, 0.1), (0.5, 0.5)],  # camera (behind, above) the laser, metres
    )
)


@pytest.mark.parametrize(("sector", "zmode", "cam"), SWEEP)
def test_sweep_held_out_column_error_stays_at_the_noise(
    sector: float, zmode: str, cam: tuple[float, float]
) -> None:
    """1–6 m, 2 or 5 px noise, 10 % of the columns 50–500 px wrong, no initial guess."""
    seed = SWEEP.index((sector, zmode, cam))
    noise = 2.0 if seed % 2 else 5.0
    rng = np.random.default_rng(seed)
    true = Pose3.from_xyz_rpy(-cam[0], 0.02, cam[1], 0.015, -0.01, rng.uniform(-math.pi, math.pi))
    n = 40
    xyz = ring(n, seed=seed, sector=sector, z=(0.3, 0.3) if zmode == "unknown z" else (0.0, 0.6))
    uv = observe(true, xyz, noise=noise, seed=seed)
    bad = rng.choice(n, n // 10, replace=False)
    uv[bad, 0] = (uv[bad, 0] + rng.choice([-1, 1], len(bad)) * rng.uniform(50, 500, len(bad))) % UHD[0]
    if zmode == "unknown z":
        xyz[:, 2] = 0.0  # the ball centre is 0.3 m above the laser, the file says 0
    cv = cross_validate(xyz, uv, image_size=UHD, folds=5)
    j = cv.to_json()
    assert not cv.fit.inliers[bad].any()  # every wrong pixel rejected
    assert j["n_outliers"] <= len(bad) + 2
    expected = noise * math.sqrt(2 / math.pi)  # mean |N(0, σ)|
    assert j["col_px_mean"] < 1.6 * expected
    assert j["col_px_median"] < 1.8 * noise * 0.6745
