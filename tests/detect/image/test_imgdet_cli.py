"""``studio detect-image``: output format, errors (exit 2, one line), atomic output."""

from __future__ import annotations

import json

import cv2
import numpy as np
import pytest
from imgdet_synth import tiny_yolo

from studio.cli import main

pytest.importorskip("onnx")


@pytest.fixture
def yolo_model(tmp_path):
    rows = np.zeros((120, 84), np.float32)
    rows[0, :4] = [32, 32, 8, 24]
    rows[0, 4] = 0.9
    return tiny_yolo(tmp_path / "tiny.onnx", "v8", rows)


def _pano(path, w=640, h=320):
    cv2.imwrite(str(path), np.zeros((h, w, 3), np.uint8))
    return str(path)


def test_detect_image_writes_jsonl(tmp_path, yolo_model, capsys):
    a, b = _pano(tmp_path / "a.png"), _pano(tmp_path / "b.jpg", 320, 160)
    out = tmp_path / "sub" / "dets.jsonl"
    assert main(["detect-image", a, b, "--out", str(out), "--image-detector", str(yolo_model)]) == 0
    lines = [json.loads(x) for x in out.read_text().splitlines()]
    assert [x["image"] for x in lines] == [a, b]
    assert (lines[0]["width"], lines[0]["height"]) == (640, 320)
    assert (lines[1]["width"], lines[1]["height"]) == (320, 160)
    assert len(lines[0]["boxes"]) == 6
    for u1, v1, u2, v2, s in lines[0]["boxes"]:
        assert 0 <= u1 < 640
        assert u2 >= u1
        assert v2 >= v1
        assert s == pytest.approx(0.9, abs=1e-3)
    assert "keypoints" not in lines[0]
    assert "2 image(s), 12 people" in capsys.readouterr().out


def test_detect_image_default_movenet(tmp_path):
    a = _pano(tmp_path / "blank.png")
    out = tmp_path / "d.jsonl"
    assert main(["detect-image", a, "--out", str(out)]) == 0
    rec = json.loads(out.read_text())
    assert rec == {"image": a, "width": 640, "height": 320, "boxes": [], "keypoints": []}


@pytest.mark.parametrize(
    ("make", "detector", "message"),
    [
        (lambda p: str(p / "missing.jpg"), None, "image not found"),
        (
            lambda p: (p / "bad.jpg").write_text("not an image") and str(p / "bad.jpg"),
            "YOLO",
            "cannot decode",
        ),
        (lambda p: _pano(p / "wide.png", 640, 360), None, "640×360 px; an equirectangular panorama is"),
        (lambda p: _pano(p / "ok.png"), "nope", "unknown image detector 'nope'"),
        (lambda p: _pano(p / "ok.png"), "missing.onnx", "model file not found"),
    ],
)
def test_detect_image_errors(tmp_path, yolo_model, capsys, make, detector, message):
    img = make(tmp_path)
    out = tmp_path / "o.jsonl"
    out.write_text("previous\n")
    args = ["detect-image", img, "--out", str(out)]
    if detector is not None:
        args += ["--image-detector", str(yolo_model) if detector == "YOLO" else detector]
    assert main(args) == 2
    err = capsys.readouterr().err
    assert message in err
    assert err.count("\n") == 1
    assert out.read_text() == "previous\n"  # untouched on error


def test_detect_image_out_is_checked_before_the_model_loads(tmp_path, capsys, monkeypatch):
    import studio.commands.detect_image as cmd

    monkeypatch.setattr(cmd, "get_image_detector", lambda name: pytest.fail("the model was loaded"))
    img = _pano(tmp_path / "ok.png")
    (tmp_path / "adir").mkdir()
    (tmp_path / "afile").write_text("x")
    for out, message in (
        (tmp_path / "adir", "is a directory, expected a file name"),
        (tmp_path / "afile" / "o.jsonl", "is not a folder"),
    ):
        assert main(["detect-image", img, "--out", str(out)]) == 2
        err = capsys.readouterr().err
        assert message in err
        assert err.count("\n") == 1
