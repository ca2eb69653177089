"""Ball target: circle fit, ball in the panorama, and simulated recording → correspondences → camera pose."""

from __future__ import annotations

import argparse
import csv
import math
from pathlib import Path

import numpy as np
import pytest
import yaml

from studio.calibrate.extrinsics import fit_extrinsics
from studio.calibrate.targets import ScanPoints, TargetError
from studio.calibrate.targets.ball import ball_in_scan, find_ball_in_panorama, fit_ball_circle, fit_circle
from studio.commands.calibrate_targets import run_targets
from studio.errors import StudioError
from studio.geometry.equirect import EquirectCamera
from studio.geometry.se import Pose3
from studio.sim import simulate
from studio.sim.base import SimRig
from studio.sim.calib import TRUE_CAMERA_POSE, render_target_panorama
from studio.sim.laser import LaserCaster


def _ball_hits(rng: np.random.Generator | None, centre: tuple[float, float], r: float) -> np.ndarray:
    from studio.sim.calib import _world

    rig = SimRig()
    spec = rig.lasers[0]
    legs = np.array([[[centre[0], centre[1], r], [centre[0], centre[1], r]]])
    res = LaserCaster(_world(), rig).cast(spec, np.zeros(3), legs, np.zeros(1), rng)
    a = spec.angles()
    m = (res.person >= 0) & np.isfinite(res.ranges)
    return np.stack([res.ranges[m] * np.cos(a[m]) + 0.4, res.ranges[m] * np.sin(a[m])], axis=1)


def test_range_residual_circle_fit_removes_the_radius_bias() -> None:
    rng = np.random.default_rng(0)
    r_true = 0.2
    plain, ranged = [], []
    for _ in range(30):
        p = _ball_hits(rng, (1.6, 0.3), r_true)
        plain.append(fit_circle(p)[2] - r_true)
        ranged.append(fit_ball_circle(p, np.array([0.4, 0.0]))[2] - r_true)
    assert abs(np.mean(ranged)) < 0.001  # mm-level
    assert np.mean(plain) < -0.0015  # the point-to-circle fit is biased low (grazing beams)
    exact = _ball_hits(None, (1.6, 0.3), r_true)
    assert fit_ball_circle(exact, np.array([0.4, 0.0]))[2] == pytest.approx(r_true, abs=1e-6)


def test_ball_in_scan_ignores_walls_and_finds_the_circle() -> None:
    p = _ball_hits(np.random.default_rng(1), (2.0, -0.5), 0.22)
    wall = np.stack([np.full(200, 3.0), np.linspace(-2, 2, 200)], axis=1)
    pts = np.concatenate([wall[:60], p, wall[140:]])
    pts3 = np.column_stack([pts, np.zeros(len(pts))])
    hit = ball_in_scan(ScanPoints("/s", 0, pts3, np.array([0.4, 0.0, 0.3])), radius=0.25)
    assert hit is not None
    # one noisy scan, algebraic fit (the pooled range-residual fit is the precise one)
    assert np.allclose(hit[0][:2], [2.0, -0.5], atol=0.025)
    assert hit[0][2] == pytest.approx(0.22, abs=0.025)
    assert (
        ball_in_scan(ScanPoints("/s", 0, np.column_stack([wall, np.zeros(200)]), np.zeros(3)), radius=0.25)
        is None
    )


@pytest.mark.parametrize("centre", [(1.8, 0.4, 0.45), (-2.0, 0.02, 0.42), (0.9, -1.3, 0.5)])
def test_ball_centre_in_panorama_is_sub_pixel(centre: tuple[float, float, float]) -> None:
    img = render_target_panorama("ball", np.array(centre), width=1280, height=640)
    found = find_ball_in_panorama(img)
    assert found is not None
    uv, _ = EquirectCamera(1280, 640, TRUE_CAMERA_POSE).project(np.array(centre))
    du = (found[0] - uv[0] + 640) % 1280 - 640  # (-2.0, 0.02) lies across the seam
    assert abs(du) < 0.3
    assert abs(found[1] - uv[1]) < 0.4


def test_no_ball_in_a_panorama_without_one() -> None:
    board = render_target_panorama("board", np.array([1.5, 0.0, math.pi]), width=1280, height=640)
    assert find_ball_in_panorama(board) is None


def _args(sim: Path, out: Path, **kw: object) -> argparse.Namespace:
    base = {
        "recording": str(sim / "recording.mcap"),
        "rig": str(sim / "rig.yaml"),
        "target": "ball",
        "out": str(out),
        "ball_radius": 0.25,
        "max_offset": 0.5,
        "include_moving": False,
        "json": None,
    }
    base.update(kw)
    return argparse.Namespace(**base)


@pytest.mark.slow
def test_simulated_ball_recovers_camera_pose_and_time_offset(tmp_path: Path) -> None:
    sim = simulate("calib-ball", out=tmp_path / "sim", seed=5).out
    truth = yaml.safe_load((sim / "truth.yaml").read_text())
    out = tmp_path / "ball.csv"
    assert run_targets(_args(sim, out, json=str(tmp_path / "r.json"))) == 0
    rows = list(csv.DictReader(out.open()))
    assert rows
    assert set(rows[0]) >= {"x", "y", "z", "u", "v", "t", "stamp_ns", "still", "target"}
    xyz = np.array([[float(r[k]) for k in "xyz"] for r in rows])
    uv = np.array([[float(r[k]) for k in "uv"] for r in rows])
    fit = fit_extrinsics(xyz, uv, image_size=(1920, 960))
    true = Pose3.from_xyz_rpy(**truth["camera_pose"])
    assert np.linalg.norm(fit.pose.t - true.t) < 0.01
    rot = np.degrees(np.linalg.norm(_rotvec(fit.pose.R @ true.R.T)))
    assert rot < 0.2
    import json

    rep = json.loads((tmp_path / "r.json").read_text())
    assert abs(rep["time_offset_s"] - truth["camera_latency_s"]) < 1.0 / truth["camera_rate_hz"]


def _rotvec(R: np.ndarray) -> np.ndarray:
    from scipy.spatial.transform import Rotation

    return np.asarray(Rotation.from_matrix(R).as_rotvec())


def test_recording_without_the_ball_is_a_clear_user_error(tmp_path: Path) -> None:
    sim = simulate("calib-checkerboard", out=tmp_path / "sim", seconds=1.0, seed=0).out
    with pytest.raises(TargetError, match="no ball") as exc:
        run_targets(_args(sim, tmp_path / "x.csv"))
    assert isinstance(exc.value, StudioError)
    assert not (tmp_path / "x.csv").exists()
