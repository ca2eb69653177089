"""The dual-lens camera model in the calibration: fitting ``b``, choosing the model, CLI and calib.yaml."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest
import yaml
from test_calib_cli import extrinsics_args

from studio.calibrate.extrinsics import (
    CalibrationError,
    cross_validate,
    fit_extrinsics,
    pixel_residuals,
    project_points,
)
from studio.calibrate.lens import choose_lens_model
from studio.cli import main
from studio.geometry.equirect import EquirectCamera
from studio.geometry.se import Pose3

SIZE = (3840, 1920)
TRUE = Pose3.from_xyz_rpy(0.16, -0.03, 1.35, -0.02, -0.01, 2.9)
B = 0.013


def scene(*, b: float, n: int = 70, noise: float = 0.0, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """Ball targets 1–4 m all around the robot and their pixels in a camera with lens offset ``b``."""
    rng = np.random.default_rng(seed)
    r = rng.uniform(1.0, 4.0, n)
    a = rng.uniform(-math.pi, math.pi, n)
    xyz = np.stack([r * np.cos(a), r * np.sin(a), rng.uniform(0.1, 0.2, n)], axis=1)
    uv = project_points(TRUE, xyz, image_size=SIZE, lens_offset=b) + rng.normal(0.0, noise, (n, 2))
    uv[:, 0] %= SIZE[0]
    return xyz, uv


def test_project_points_matches_the_camera() -> None:
    xyz, _ = scene(b=0.0)
    cam = EquirectCamera(*SIZE, TRUE, lens_offset=B)
    np.testing.assert_allclose(project_points(TRUE, xyz, image_size=SIZE, lens_offset=B), cam.project(xyz)[0])
    uv = cam.project(xyz)[0]
    assert np.abs(pixel_residuals(TRUE, xyz, uv, image_size=SIZE, lens_offset=B)).max() < 1e-8
    assert np.abs(pixel_residuals(TRUE, xyz, uv, image_size=SIZE)).max() > 1.0


def test_noise_free_fit_recovers_the_lens_offset() -> None:
    xyz, uv = scene(b=B)
    fit = fit_extrinsics(xyz, uv, image_size=SIZE, lens_offset=None)
    assert fit.lens_fitted
    assert fit.lens_offset == pytest.approx(B, abs=1e-3)
    assert abs(fit.lens_offset - B) < 1e-5  # noise-free: essentially exact
    assert np.linalg.norm(fit.pose.t - TRUE.t) < 1e-4
    assert np.abs(fit.residual_px).max() < 1e-3
    assert fit.n_outliers == 0
    held = fit_extrinsics(xyz, uv, image_size=SIZE)  # the central model cannot fit the parallax
    assert not held.lens_fitted
    assert held.lens_offset == 0.0
    assert np.abs(held.residual_px[held.inliers, 0]).mean() > 1.0
    fixed = fit_extrinsics(xyz, uv, image_size=SIZE, lens_offset=B)  # held at the true value: exact
    assert np.abs(fixed.residual_px).max() < 1e-3


def test_noisy_fit_and_its_uncertainty() -> None:
    xyz, uv = scene(b=B, noise=1.0, n=80, seed=3)
    fit = fit_extrinsics(xyz, uv, image_size=SIZE, lens_offset=None)
    assert 0.0 < fit.lens_offset_std < 0.005
    assert abs(fit.lens_offset - B) < 4 * fit.lens_offset_std


@pytest.mark.parametrize("bad", [math.nan, 0.2, -0.5])
def test_bad_lens_offset(bad: float) -> None:
    xyz, uv = scene(b=0.0)
    with pytest.raises(CalibrationError, match="lens offset"):
        fit_extrinsics(xyz, uv, image_size=SIZE, lens_offset=bad)


def test_cross_validation_uses_the_fold_lens_offsets() -> None:
    xyz, uv = scene(b=B)
    cv = cross_validate(xyz, uv, image_size=SIZE, lens_offset=None)
    assert cv.to_json()["col_px_mean"] < 0.01
    assert cv.to_json()["lens_offset_m"] == pytest.approx(B, abs=1e-4)


def test_choice_keeps_the_dual_lens_model_when_it_pays_off() -> None:
    xyz, uv = scene(b=B, noise=0.5, seed=1)
    choice = choose_lens_model(xyz, uv, image_size=SIZE)
    assert choice.dual_kept, choice.reason
    assert choice.lens_offset == pytest.approx(B, abs=3e-3)
    j = choice.to_json()
    assert j["lens_model"] == "dual"
    assert j["col_px_mean"] < 0.9 * j["col_px_mean_single"]
    assert "kept" in choice.reason


@pytest.mark.parametrize("noise", [0.0, 0.7])
def test_choice_keeps_the_central_model_without_parallax(noise: float) -> None:
    xyz, uv = scene(b=0.0, noise=noise, seed=2)
    choice = choose_lens_model(xyz, uv, image_size=SIZE)
    assert not choice.dual_kept, choice.reason
    assert choice.lens_offset == 0.0
    assert choice.kept is choice.single
    assert choice.to_json()["lens_model"] == "single"


def test_cli_writes_the_lens_offset_and_project_uses_it(tmp_path: Path) -> None:
    xyz, uv = scene(b=B, noise=0.3, seed=4)
    csv = tmp_path / "corr.csv"
    np.savetxt(csv, np.column_stack([xyz, uv]), delimiter=",", header="x,y,z,u,v", comments="")
    out = tmp_path / "calib.yaml"
    js = tmp_path / "m.json"
    args = ["calibrate", "extrinsics", "--correspondences", str(csv), "--image-size", "3840x1920"]
    assert main([*args, "--json", str(js), "--out", str(out)]) == 0
    calib = yaml.safe_load(out.read_text())
    assert calib["camera"]["lens_offset"] == pytest.approx(B, abs=2e-3)
    m = json.loads(js.read_text())
    assert m["lens_model"] == "dual"
    assert m["col_px_mean_single"] > m["col_px_mean"]
    pts = tmp_path / "pts.csv"
    np.savetxt(pts, xyz, delimiter=",", header="x,y,z", comments="")
    uv_out = tmp_path / "uv.csv"
    assert (
        main(
            [
                "calibrate",
                "project",
                "--rig",
                str(out),
                "--points",
                str(pts),
                "--image-size",
                "3840x1920",
                "--out",
                str(uv_out),
            ]
        )
        == 0
    )
    got = np.loadtxt(uv_out, delimiter=",", skiprows=1)
    d = got - uv
    d[:, 0] = (d[:, 0] + SIZE[0] / 2) % SIZE[0] - SIZE[0] / 2
    assert np.median(np.abs(d)) < 1.0


def test_cli_central_model_writes_no_lens_offset(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    xyz, uv = scene(b=0.0, noise=0.5, seed=5)
    csv = tmp_path / "corr.csv"
    np.savetxt(csv, np.column_stack([xyz, uv]), delimiter=",", header="x,y,z,u,v", comments="")
    out = tmp_path / "calib.yaml"
    assert main(["calibrate", *extrinsics_args(csv, out)]) == 0
    assert "lens_offset" not in yaml.safe_load(out.read_text())["camera"]
    text = capsys.readouterr().out
    assert "central (one centre)" in text
    assert "dual-lens b" in text
    assert "<- kept" in text
