"""Calibration commands read the camera's panoramas: an image that is not 2:1 is one clear error."""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np
import pytest

from studio.calibrate.people_data import PeopleCalibrationError, collect_people
from studio.calibrate.targets import TargetError, iter_panoramas
from studio.io import open_recording
from studio.io.rig import parse_rig
from studio.io.writer import RecordingWriter

T0 = 1_700_000_000_000_000_000


def _square_images(path: Path) -> Path:
    ok, jpg = cv2.imencode(".jpg", np.full((100, 100, 3), 128, np.uint8))
    assert ok
    with RecordingWriter(path) as w:
        for k in range(3):
            w.write_compressed_image("/cam", T0 + k * 100_000_000, "camera", jpg.tobytes())
    return path


RIG = parse_rig(
    {
        "base_frame": "base_link",
        "camera": {"topic": "/cam", "pose": {"z": 1.0}},
        "lasers": [{"topic": "/scan", "pose": {"z": 0.3}}],
    }
)


def test_calibration_targets_refuse_square_images(tmp_path: Path) -> None:
    with (
        open_recording(_square_images(tmp_path / "r.mcap")) as rec,
        pytest.raises(TargetError, match=r"100×100 px; an equirectangular panorama is twice as wide"),
    ):
        next(iter_panoramas(rec, RIG))


def test_calibration_from_people_refuses_square_images(tmp_path: Path) -> None:
    with pytest.raises(PeopleCalibrationError, match=r"100×100 px; an equirectangular panorama"):
        collect_people(_square_images(tmp_path / "r.mcap"), RIG)
