"""Board target: the thesis's per-face homography (Eqs. 3.14–3.15), the boundary line, the full recording."""

from __future__ import annotations

import argparse
import csv
import json
import math
from pathlib import Path

import numpy as np
import pytest
import yaml
from scipy.spatial.transform import Rotation

from studio.calibrate.extrinsics import fit_extrinsics
from studio.calibrate.targets import ScanPoints, TargetError
from studio.calibrate.targets.board import board_in_scan, board_line_in_face, fit_face_homography
from studio.commands.calibrate_targets import run_targets
from studio.geometry.equirect import EquirectCamera
from studio.geometry.render import ViewRenderer
from studio.geometry.se import Pose3
from studio.geometry.views import PerspectiveView
from studio.sim import simulate
from studio.sim.base import LASER_Z
from studio.sim.calib import TRUE_CAMERA_POSE, render_target_panorama


def _true_homography() -> np.ndarray:
    """Laser plane (x, y, 1) → front face (640 px) of the true camera, exactly."""
    view = PerspectiveView(0.0, 0.0, math.pi / 2, 640, 640)
    K = view.K()
    R_cv = view.R_cam_view()  # optical → camera
    T = TRUE_CAMERA_POSE
    M = K @ R_cv.T @ T.R.T  # base point → face homogeneous px (before translation)
    # p_base = (x, y, LASER_Z): M (p - t) = M [e1 e2 (LASER_Z e3 - t)] (x, y, 1)
    cols = np.column_stack([M[:, 0], M[:, 1], M @ (np.array([0.0, 0.0, LASER_Z]) - T.t)])
    return cols / cols[2, 2]


def test_face_homography_recovers_a_known_homography_from_board_lines() -> None:
    H_true = _true_homography()
    rng = np.random.default_rng(3)
    pts_all, lines_all = [], []
    for _ in range(6):  # six boards in front of the robot
        c = np.array([rng.uniform(1.3, 2.4), rng.uniform(-0.6, 0.6)])
        yaw = rng.uniform(-0.5, 0.5)
        d = np.array([-math.sin(yaw), math.cos(yaw)])
        pts = c + np.outer(np.linspace(-0.35, 0.35, 40), d)
        q = np.column_stack([pts, np.ones(40)]) @ H_true.T
        uv = q[:, :2] / q[:, 2:]
        a, b = uv[0], uv[-1]
        line = np.cross([a[0], a[1], 1.0], [b[0], b[1], 1.0])
        pts_all.append(pts + rng.normal(0, 0.002, pts.shape))
        lines_all.append(np.repeat(line[None], 40, axis=0))
    fit = fit_face_homography("front", np.concatenate(pts_all), np.concatenate(lines_all), n_boards=6)
    assert fit.n_boards == 6
    assert fit.n_points == 240
    assert np.abs(fit.dist_px).mean() < 0.5
    # the line constraints fix H along the boards; points on new boards project within a pixel or two
    test = np.array([[1.8, 0.1, 1.0], [1.5, -0.4, 1.0], [2.2, 0.5, 1.0]])
    q1, q2 = test @ fit.H.T, test @ H_true.T
    assert np.all(np.hypot(*(q1[:, :2] / q1[:, 2:] - q2[:, :2] / q2[:, 2:]).T) < 3.0)


def test_board_boundary_line_and_ends_in_a_view() -> None:
    par = np.array([1.7, 0.2, math.pi + 0.3])
    img = render_target_panorama("board", par)
    view = PerspectiveView(math.atan2(0.2, 1.7), -0.3, math.pi / 2, 640, 640)
    found = board_line_in_face(ViewRenderer().render(img, view))
    assert found is not None
    line, left, right = found
    ex = np.array([-math.sin(par[2]), math.cos(par[2])])
    ends = [np.array([*(par[:2] + s * ex * 0.4), LASER_Z]) for s in (1, -1)]
    uv, _ = EquirectCamera(1920, 960, TRUE_CAMERA_POSE).project(np.array(ends))
    true_view = view.pano_to_view(uv, 1920, 960)
    true_view = true_view[np.argsort(true_view[:, 0])]  # image left first
    got = np.array([left, right])
    assert np.abs(got - true_view).max() < 0.8
    assert np.all(np.abs(got @ line[:2] + line[2]) < 1e-6)


def test_board_segment_in_scan_stands_in_front_of_the_wall() -> None:
    a = np.linspace(-0.6, 0.6, 400)
    r = np.where(np.abs(a) < 0.2, 1.6 / np.cos(a), 3.5 / np.cos(a))
    pts = np.column_stack([r * np.cos(a), r * np.sin(a), np.zeros_like(a)])
    idx = board_in_scan(ScanPoints("/s", 0, pts, np.zeros(3)), width=0.65)
    assert idx is not None
    assert np.all(np.abs(a[idx]) < 0.2)
    assert board_in_scan(ScanPoints("/s", 0, pts, np.zeros(3)), width=2.0) is None


@pytest.mark.slow
def test_simulated_board_homographies_and_spherical_fit(tmp_path: Path) -> None:
    sim = simulate("calib-board", out=tmp_path / "sim", seed=1).out
    truth = yaml.safe_load((sim / "truth.yaml").read_text())
    out = tmp_path / "board.csv"
    args = argparse.Namespace(
        recording=str(sim / "recording.mcap"), rig=str(sim / "rig.yaml"), target="board", out=str(out),
        board_width=0.8, json=str(tmp_path / "r.json"),
    )  # fmt: skip
    assert run_targets(args) == 0
    rep = json.loads((tmp_path / "r.json").read_text())
    hom = rep["homography"]
    assert set(hom["faces"]) >= {"front", "back"}
    assert hom["hit_share"] > 0.8  # thesis Table 4.4 measure, 2 px
    rows = list(csv.DictReader(out.open()))
    xyz = np.array([[float(r[k]) for k in "xyz"] for r in rows])
    uv = np.array([[float(r[k]) for k in "uv"] for r in rows])
    fit = fit_extrinsics(xyz, uv, image_size=(1920, 960))
    true = Pose3.from_xyz_rpy(**truth["camera_pose"])
    assert np.linalg.norm(fit.pose.t - true.t) < 0.01
    assert np.degrees(np.linalg.norm(Rotation.from_matrix(fit.pose.R @ true.R.T).as_rotvec())) < 0.2


def test_recording_without_a_board_is_a_clear_user_error(tmp_path: Path) -> None:
    sim = simulate("calib-checkerboard", out=tmp_path / "sim", seconds=1.0, seed=0).out
    args = argparse.Namespace(
        recording=str(sim / "recording.mcap"),
        rig=str(sim / "rig.yaml"),
        target="board",
        out=str(tmp_path / "x.csv"),
        board_width=0.8,
        json=None,
    )
    with pytest.raises(TargetError, match="no board"):
        run_targets(args)
