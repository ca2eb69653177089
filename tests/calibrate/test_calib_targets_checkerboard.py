"""Checkerboard intrinsics: per-face errors, the 'ideal spherical' verdict, and a warp that flips it."""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import cv2
import numpy as np
import pytest

from studio.calibrate.targets import TargetError
from studio.calibrate.targets.checkerboard import calibrate_faces
from studio.commands.calibrate_targets import run_intrinsics
from studio.sim import simulate
from studio.sim.calib import render_target_panorama, sample_stations

W, H = 1440, 720


@pytest.fixture(scope="module")
def panoramas() -> list[np.ndarray]:
    """16 noise-free panoramas, four boards in front of each horizontal cube face."""
    return [
        render_target_panorama("checkerboard", row, width=W, height=H)
        for row in sample_stations("checkerboard", 16, seed=3)
    ]


def _warp(img: np.ndarray, k: float) -> np.ndarray:
    """Stretch the elevation by ``1 + k`` about the horizon (a small lens-model error)."""
    v, u = np.mgrid[0:H, 0:W].astype(np.float32)
    mv = (H / 2 + (v + 0.5 - H / 2) * (1 + k) - 0.5).astype(np.float32)
    return cv2.remap(img, u, mv, cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE)


def test_ideal_panoramas_behave_as_the_ideal_spherical_camera(panoramas: list[np.ndarray]) -> None:
    rep = calibrate_faces(panoramas)
    assert rep.verdict == "ideal", rep.table()
    for name in ("front", "left", "back", "right"):
        f = rep.faces[name]
        assert f.n_views >= 3
        assert f.err_free_px < 0.3
        assert f.err_ideal_px < 0.3
        assert f.ideal() is True
    assert rep.face_size == W // 3
    assert rep.to_json()["faces"]["front"]["f_ideal"] == W / 6


def test_a_small_known_distortion_flips_the_verdict(panoramas: list[np.ndarray]) -> None:
    rep = calibrate_faces([_warp(p, 0.02) for p in panoramas])
    assert rep.verdict == "needs correction", rep.table()
    worse = [f for f in rep.faces.values() if f.n_views >= 3 and f.err_ideal_px > 1.5 * f.err_free_px]
    assert worse


def test_no_board_is_a_user_error() -> None:
    blank = render_target_panorama("ball", np.array([1.5, 0.0, 0.45]), width=W, height=H)
    with pytest.raises(TargetError, match="no 8x5 checkerboard"):
        calibrate_faces([blank])


def test_intrinsics_names_what_is_wrong_with_its_source(tmp_path: Path) -> None:
    """A missing path asked for --rig, and a square image said that no checkerboard was found."""

    def run(source: Path) -> int:
        ns = argparse.Namespace(source=str(source), rig=None, pattern=(8, 5), square=0.07, face_size=None)
        return run_intrinsics(ns)

    with pytest.raises(TargetError, match="no such recording or folder"):
        run(tmp_path / "nothere")
    (tmp_path / "pans").mkdir()
    ok, jpg = cv2.imencode(".jpg", np.full((100, 100, 3), 128, np.uint8))
    assert ok
    (tmp_path / "pans" / "a.jpg").write_bytes(jpg.tobytes())
    with pytest.raises(TargetError, match=r"a\.jpg is one image: give the folder"):
        run(tmp_path / "pans" / "a.jpg")
    with pytest.raises(TargetError, match=r"100×100 px; an equirectangular panorama is twice as wide"):
        run(tmp_path / "pans")


@pytest.mark.slow
def test_intrinsics_command_on_a_simulated_recording(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    sim = simulate("calib-checkerboard", out=tmp_path / "sim", seed=2).out
    args = argparse.Namespace(
        source=str(sim / "recording.mcap"),
        rig=str(sim / "rig.yaml"),
        pattern=(8, 5),
        square=0.07,
        face_size=None,
        every=1,
        json=str(tmp_path / "i.json"),
    )
    assert run_intrinsics(args) == 0
    rep = json.loads((tmp_path / "i.json").read_text())
    assert rep["verdict"] == "ideal"
    assert "verdict: ideal" in capsys.readouterr().out
