"""A 360° camera that streams its two unstitched fisheye circles (2:1, like a panorama) is refused with one
clear line instead of being labelled as if it were equirectangular."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import cv2
import numpy as np
import pytest

from studio.io import open_recording
from studio.io.decode import decode_panorama, looks_dual_fisheye
from studio.sim import simulate
from studio.sim.base import SimRig


@pytest.fixture(scope="module")
def panorama(tmp_path_factory: pytest.TempPathFactory) -> np.ndarray:
    """A rendered 960×480 panorama of the simulated room (people, walls, floor, ceiling, the robot)."""
    out = tmp_path_factory.mktemp("pano") / "sim"
    res = simulate("static", out=out, seconds=0.15, seed=2, rig=SimRig(width=960, height=480))
    with open_recording(res.recording) as rec:
        raw = next(iter(rec.messages(["/theta_camera/image/compressed"])))
        return decode_panorama(rec.decode(raw)).image


def dual_fisheye(pano: np.ndarray, radius: float = 0.49, fov_deg: float = 190.0) -> np.ndarray:
    """The two fisheye circles (equidistant, ``fov_deg``, radius ``radius`` × height) a dual-lens camera
    streams of the scene ``pano`` shows: front lens on the left, back lens on the right, black around."""
    h, w = pano.shape[:2]
    R = radius * h
    v, u = np.mgrid[0:h, 0:w].astype(np.float64)
    back = u >= w / 2
    dx = (u - np.where(back, 3 * w / 4, w / 4)) / R
    dy = (h / 2 - v) / R
    rho = np.hypot(dx, dy)
    theta = rho * np.deg2rad(fov_deg / 2)
    with np.errstate(invalid="ignore", divide="ignore"):
        sx, sy = np.where(rho > 0, dx / rho, 0.0), np.where(rho > 0, dy / rho, 0.0)
    fwd, side, up = np.cos(theta), -np.sin(theta) * sx, np.sin(theta) * sy
    fwd, side = np.where(back, -fwd, fwd), np.where(back, -side, side)  # the back lens looks backwards
    az = np.arctan2(side, fwd)
    el = np.arcsin(np.clip(up, -1.0, 1.0))
    mu = ((0.5 - az / (2 * np.pi)) * w) % w
    mv = np.clip((0.5 - el / np.pi) * h, 0, h - 1)
    out = cv2.remap(pano, mu.astype(np.float32), mv.astype(np.float32), cv2.INTER_LINEAR)
    out[rho > 1.0] = 0
    return out


def _jpeg(img: np.ndarray) -> np.ndarray:
    ok, buf = cv2.imencode(".jpg", img, [cv2.IMWRITE_JPEG_QUALITY, 80])
    assert ok
    return cv2.imdecode(buf, cv2.IMREAD_COLOR)


def test_two_fisheye_circles_are_told_from_a_panorama(panorama: np.ndarray) -> None:
    assert not looks_dual_fisheye(panorama)
    for radius in (0.49, 0.45, 0.42):  # lenses whose circles do not quite fill the frame's height
        assert looks_dual_fisheye(_jpeg(dual_fisheye(panorama, radius))), radius


def test_dark_or_masked_panoramas_are_still_panoramas(panorama: np.ndarray) -> None:
    night = (panorama * 0.08).astype(np.uint8)
    masked = panorama.copy()  # the robot and the ceiling blacked out with bands
    h = masked.shape[0]
    masked[: int(0.2 * h)] = 0
    masked[int(0.8 * h) :] = 0
    for img in (night, masked, _jpeg(masked)):
        assert not looks_dual_fisheye(img)


def test_labelling_two_fisheye_circles_is_one_clear_error(panorama: np.ndarray, tmp_path: Path) -> None:
    from studio.geometry.se import Pose2
    from studio.io import Odometry, RecordingWriter

    bag = tmp_path / "fisheye.mcap"
    frame = _jpeg(dual_fisheye(panorama))
    ok, jpeg = cv2.imencode(".jpg", frame)
    assert ok
    t0 = 1_700_000_000_000_000_000
    with RecordingWriter(bag) as wr:
        for k in range(5):
            stamp = t0 + k * 100_000_000
            wr.write_odometry("/odom", Odometry(stamp, "odom", "base_link", Pose2()))
            wr.write_compressed_image("/cam", stamp, "camera", jpeg.tobytes(), "jpeg")
    rig = tmp_path / "rig.yaml"
    rig.write_text(
        "base_frame: base_link\nodometry: {topic: /odom}\ncamera:\n  topic: /cam\n  pose: {z: 1.1}\n"
    )
    res = subprocess.run(
        [
            sys.executable,
            "-m",
            "studio.cli",
            "label",
            str(bag),
            "--rig",
            str(rig),
            "--out",
            str(tmp_path / "run"),
        ],
        capture_output=True,
        text=True,
        timeout=300,
        check=False,
    )
    assert res.returncode == 2, res.stderr
    assert res.stderr.count("\n") == 1
    assert "two fisheye circles side by side" in res.stderr
    assert not (tmp_path / "run").exists()
