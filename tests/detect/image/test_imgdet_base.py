"""Contracts of studio.detect.image.base: the detections dataclasses and the registry."""

from __future__ import annotations

import subprocess
import sys

import numpy as np
import pytest

from studio.detect.image import (
    ImageDetections,
    ImageDetectorError,
    ViewDetections,
    get_image_detector,
    image_detector_names,
)
from studio.errors import StudioError


def test_empty_and_select():
    d = ImageDetections.empty(1920, 960)
    assert len(d) == 0
    assert d.boxes.shape == (0, 4)
    assert d.keypoints is not None
    assert d.keypoints.shape == (0, 17, 3)
    assert ImageDetections.empty(10, 5, keypoints=False).keypoints is None
    d = ImageDetections(
        [[10, 20, 30, 40], [1900, 1, 1950, 9]], [0.5, 0.9], np.zeros((2, 17, 3)), width=1920, height=960
    )
    s = d.select([1])
    assert s.boxes.tolist() == [[1900, 1, 1950, 9]]
    assert s.scores.tolist() == [0.9]
    assert s.boxes.dtype == np.float64
    assert s.width == 1920


@pytest.mark.parametrize(
    ("boxes", "scores", "kp", "match"),
    [
        ([[0, 0, 1, 1]], [0.5, 0.4], None, "scores"),
        ([[0, 0, 1]], [0.5], None, "boxes"),
        ([[5, 0, 1, 1]], [0.5], None, "u2 >= u1"),
        ([[0, 0, 1, 1]], [1.5], None, r"\[0, 1\]"),
        ([[0, 0, 1, 1]], [0.5], np.zeros((1, 16, 3)), "keypoints"),
        ([[100, 0, 101, 1]], [0.5], None, "u1 in"),  # u1 beyond W
        ([[-1, 0, 1, 1]], [0.5], None, "u1 in"),
        ([[0, 0, 150, 1]], [0.5], None, "u1 in"),  # wider than the panorama
        ([[np.nan, 0, 1, 1]], [0.5], None, "finite"),
    ],
)
def test_image_detections_rejects(boxes, scores, kp, match):
    with pytest.raises(ValueError, match=match):
        ImageDetections(np.asarray(boxes, float), scores, kp, 100, 50)


def test_seam_box_allowed():
    d = ImageDetections([[90, 0, 120, 10]], [0.5], None, 100, 50)
    assert d.boxes[0, 2] == 120


def test_view_detections():
    v = ViewDetections([[1, 2, 3, 4]], [0.3])
    assert v.keypoints is None
    assert len(v) == 1
    assert len(ViewDetections.empty()) == 0
    with pytest.raises(ValueError, match="keypoints"):
        ViewDetections([[1, 2, 3, 4]], [0.3], np.zeros((2, 17, 3)))


def test_registry_names_and_errors(tmp_path):
    assert {"movenet", "centernet", "combined"} <= set(image_detector_names())
    with pytest.raises(ImageDetectorError, match="centernet, combined, movenet") as e:
        get_image_detector("nope")
    assert isinstance(e.value, StudioError)
    with pytest.raises(ImageDetectorError, match="not found"):
        get_image_detector(str(tmp_path / "missing.onnx"))
    bad = tmp_path / "bad.onnx"
    bad.write_bytes(b"not a model")
    with pytest.raises(ImageDetectorError, match="cannot load ONNX model"):
        get_image_detector(str(bad))


def test_import_is_lazy():
    code = (
        "import sys, studio.detect.image as m; "
        "assert 'onnxruntime' not in sys.modules, 'onnxruntime imported'; "
        "assert 'studio.detect.image.movenet' not in sys.modules; print('ok')"
    )
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=False)
    assert r.returncode == 0, r.stderr
