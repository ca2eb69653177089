"""Calibration scenarios: files, nominal vs true camera pose, image latency, targets in scans and images."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest
import yaml

from studio.cli import main
from studio.geometry.equirect import EquirectCamera
from studio.geometry.se import Pose3
from studio.io import load_rig, open_recording
from studio.sim import SimError, simulate
from studio.sim.calib import (
    NOMINAL_CAMERA_POSE,
    TRUE_CAMERA_POSE,
    TRUE_LATENCY_S,
    render_target_panorama,
    sample_stations,
    target_state,
)


@pytest.fixture(scope="module")
def ball_sim(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return simulate("calib-ball", out=tmp_path_factory.mktemp("calib") / "ball", seconds=4.0, seed=2).out


def test_calib_ball_writes_recording_nominal_rig_and_truth(ball_sim: Path) -> None:
    assert sorted(p.name for p in ball_sim.iterdir()) == [
        ".studio-files",
        "recording.mcap",
        "rig.yaml",
        "targets.jsonl",
        "truth.yaml",
    ]
    truth = yaml.safe_load((ball_sim / "truth.yaml").read_text())
    true_pose = Pose3.from_xyz_rpy(**truth["camera_pose"])
    assert np.allclose(true_pose.matrix(), TRUE_CAMERA_POSE.matrix(), atol=1e-8)
    assert truth["camera_latency_s"] == TRUE_LATENCY_S
    rig = load_rig(ball_sim / "rig.yaml")
    assert rig.camera is not None
    assert rig.camera.pose is not None
    assert np.allclose(rig.camera.pose.matrix(), NOMINAL_CAMERA_POSE.matrix())  # the rig is NOT the truth
    assert np.linalg.norm(rig.camera.pose.t - true_pose.t) > 0.02
    rows = [json.loads(line) for line in (ball_sim / "targets.jsonl").read_text().splitlines()]
    assert len(rows) == 20  # 4 s at 5 Hz
    for r in rows:
        assert r["stamp_ns"] - r["capture_ns"] == round(TRUE_LATENCY_S * 1e9)
    # the true pixel of the ball's centre is on the ball in the decoded JPEG
    with open_recording(ball_sim / "recording.mcap") as rec:
        raws = list(rec.messages([rig.camera.topic]))
        from studio.io.decode import decode_panorama

        pano = decode_panorama(rec.decode(raws[0]), raws[0].log_ns)
        assert pano.stamp_ns == rows[0]["stamp_ns"]
        u, v = rows[0]["uv"]
        b, g, r = (int(c) for c in pano.image[int(v), int(u)])
        assert r > 180, (b, g, r)
        assert g < 140, (b, g, r)
        assert b < 80, (b, g, r)
        scans = list(rec.messages(["/scan_front"]))
        assert len(scans) > 100


def test_target_state_holds_then_moves_smoothly() -> None:
    st = np.array([[1.0, 0.0, 0.4], [2.0, 0.0, 0.5]])
    p, still = target_state(st, 0.5, hold_s=1.0, move_s=1.0)
    assert still
    assert np.allclose(p, st[0])
    p, still = target_state(st, 1.5, hold_s=1.0, move_s=1.0)
    assert not still
    assert np.allclose(p, [1.5, 0.0, 0.45])
    p, still = target_state(st, 9.0, hold_s=1.0, move_s=1.0)
    assert still
    assert np.allclose(p, st[1])


@pytest.mark.parametrize("kind", ["ball", "board", "checkerboard"])
def test_rendered_target_sits_at_its_projected_pixel(kind: str) -> None:
    row = sample_stations(kind, 6, seed=4)[2]
    img = render_target_panorama(kind, row, width=960, height=480)
    cam = EquirectCamera(960, 480, TRUE_CAMERA_POSE)
    centre = np.array([row[0], row[1], 0.15]) if kind == "board" else row[:3]
    uv, _ = cam.project(centre)
    b, g, r = (int(c) for c in img[int(uv[1]), int(uv[0])])
    if kind == "ball":
        assert r > 150
        assert b < 80
    elif kind == "board":
        assert g > 140
        assert r < 100
    else:
        assert max(b, g, r) < 60 or min(b, g, r) > 200  # black or white square


def test_same_seed_same_truth_other_seed_other_stations(tmp_path: Path) -> None:
    a = sample_stations("ball", 8, seed=1)
    b = sample_stations("ball", 8, seed=1)
    c = sample_stations("ball", 8, seed=2)
    assert np.array_equal(a, b)
    assert not np.array_equal(a[:3], c[:3])
    h = a[:, 2] - 0.30
    assert np.all((h > 0.09) & (h < 0.21))
    az = np.arctan2(a[:, 1], a[:, 0])
    assert np.all(np.diff(az) > 0)  # ordered around the robot
    assert all(math.hypot(x, y) > 1.2 for x, y in a[:, :2])


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"scenario": "calib-nope"}, "unknown scenario 'calib-nope'"),
        ({"scenario": "calib-ball", "seconds": 1.0}, "--seconds must be in"),
        ({"scenario": "calib-ball", "seed": -1}, "--seed must be"),
    ],
)
def test_bad_calib_arguments_raise_sim_error(tmp_path: Path, kwargs: dict, match: str) -> None:
    with pytest.raises(SimError, match=match):
        simulate(out=tmp_path / "x", **kwargs)


def test_cli_unknown_calib_scenario_exits_2(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["simulate", "--scenario", "calib-xyz", "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err
    assert "calib-xyz" in err
    assert "Traceback" not in err


def test_same_seed_gives_identical_calibration_files(ball_sim: Path, tmp_path: Path) -> None:
    again = simulate("calib-ball", out=tmp_path / "again", seconds=4.0, seed=2).out
    for name in ("recording.mcap", "rig.yaml", "truth.yaml", "targets.jsonl"):
        assert (again / name).read_bytes() == (ball_sim / name).read_bytes(), name


def test_cli_simulate_calib_scenario(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "cb"
    assert main(["simulate", "--scenario", "calib-checkerboard", "--seconds", "1", "--out", str(out)]) == 0
    text = capsys.readouterr().out
    assert "truth.yaml" in text
    assert (out / "truth.yaml").exists()
