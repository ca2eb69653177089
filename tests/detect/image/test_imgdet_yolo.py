"""YOLO ONNX adapter: output layouts (v5/v7 with objectness, v8/v11 without), letterbox, NMS, and the
detector end to end on tiny ONNX models built here with the ``onnx`` helper API."""

from __future__ import annotations

import math

import numpy as np
import pytest
from imgdet_synth import tiny_yolo

from studio.detect.image import ImageDetectorError, get_image_detector
from studio.detect.image.yolo import Letterbox, letterbox, nms, parse_yolo_output, yolo_postprocess

pytest.importorskip("onnx")

NC = 80


PAD = 120  # candidates per output (real exports have thousands: more candidates than channels)


def _rows_v8(boxes_cxcywh, person, other=0.0):
    n = len(boxes_cxcywh)
    r = np.zeros((max(n, PAD), 4 + NC), np.float32)
    r[:n, :4] = boxes_cxcywh
    r[:n, 4] = person
    r[:n, 5] = other
    return r


def _rows_v5(boxes_cxcywh, obj, person):
    n = len(boxes_cxcywh)
    r = np.zeros((max(n, PAD), 5 + NC), np.float32)
    r[:n, :4] = boxes_cxcywh
    r[:n, 4] = obj
    r[:n, 5] = person
    return r


def test_parse_layouts():
    cxcywh = np.array([[32, 32, 10, 20], [10, 10, 4, 4]] + [[0, 0, 1, 1]] * 198, np.float32)
    v8 = _rows_v8(cxcywh, person=np.r_[0.9, 0.2, np.zeros(198)])
    assert v8.shape == (200, 84)
    b, s, layout = parse_yolo_output(v8.T[None])
    assert layout == "v8"
    np.testing.assert_allclose(b[0], [27, 22, 37, 42])
    np.testing.assert_allclose(s[:2], [0.9, 0.2])
    v5 = _rows_v5(cxcywh, obj=np.r_[0.5, 1.0, np.zeros(198)], person=np.r_[0.8, 0.3, np.zeros(198)])
    b, s, layout = parse_yolo_output(v5[None])
    assert layout == "v5"
    np.testing.assert_allclose(b[0], [27, 22, 37, 42])
    np.testing.assert_allclose(s[:2], [0.4, 0.3])  # objectness × class score
    b, s, layout = parse_yolo_output(v5[None], layout="v5", person_class=1)
    assert s[0] == 0.0
    with pytest.raises(ImageDetectorError, match="output shape"):
        parse_yolo_output(np.zeros((1, 2, 3, 4)))
    with pytest.raises(ImageDetectorError, match="no class"):
        parse_yolo_output(np.zeros((1, 4, 100)))
    with pytest.raises(ImageDetectorError, match="layout"):
        parse_yolo_output(v5[None], layout="v9")


def test_letterbox_round_trip():
    img = np.full((100, 200, 3), 7, np.uint8)
    out, lb = letterbox(img, 64, 64)
    assert out.shape == (64, 64, 3)
    assert lb.scale == pytest.approx(0.32)
    assert (lb.pad_x, lb.pad_y) == (0, 16)
    assert out[0, 0, 0] == 114  # padding
    assert out[32, 32, 0] == 7
    back = lb.to_image(np.array([[0, 16, 64, 48]], float))
    np.testing.assert_allclose(back, [[0, 0, 200, 100]])


def test_nms():
    boxes = np.array([[0, 0, 10, 10], [1, 1, 11, 11], [20, 20, 30, 30]], float)
    assert nms(boxes, np.array([0.5, 0.9, 0.7]), 0.5).tolist() == [1, 2]
    assert nms(boxes, np.array([0.5, 0.9, 0.7]), 0.9).tolist() == [1, 2, 0]


def test_postprocess_threshold_unletterbox_nms():
    rows = _rows_v8(
        np.array([[32, 32, 16, 32], [33, 32, 16, 32], [10, 10, 4, 4]], np.float32), person=[0.9, 0.85, 0.1]
    )
    lb = Letterbox(0.5, 0.0, 8.0)  # a 128 × 96 image in a 64 × 64 input
    d = yolo_postprocess(rows.T[None], lb, 128, 96)
    assert len(d) == 1
    np.testing.assert_allclose(d.boxes[0], [48, 16, 80, 80])


@pytest.mark.parametrize("layout", ["v5", "v8"])
def test_yolo_detector_end_to_end(tmp_path, layout):
    # every view reports one person in its centre: 6 views → 6 people, one per view azimuth
    box = np.array([[32, 32, 8, 24]], np.float32)
    rows = _rows_v5(box, obj=1.0, person=0.9) if layout == "v5" else _rows_v8(box, person=0.9)
    path = tiny_yolo(tmp_path / f"tiny_{layout}.onnx", layout, rows)
    det = get_image_detector(str(path))
    assert det.name == f"yolo:tiny_{layout}.onnx"
    pano = np.zeros((320, 640, 3), np.uint8)
    d = det.detect(pano)
    assert len(d) == 6
    assert d.keypoints is None
    np.testing.assert_allclose(d.scores, 0.9, rtol=1e-6)
    centres = np.sort(((d.boxes[:, 0] + d.boxes[:, 2]) / 2) % 640)
    np.testing.assert_allclose(centres, np.sort((320 - np.arange(6) * 640 / 6) % 640), atol=1.0)


def test_yolo_dynamic_input_and_options(tmp_path):
    rows = _rows_v8(np.array([[320, 320, 40, 120]], np.float32), person=0.6)
    path = tiny_yolo(tmp_path / "dyn.onnx", "v8", rows, size=None)
    det = get_image_detector(str(path), count=4, fov_deg=100, view_size=(640, 640), score_threshold=0.7)
    assert det.input_size is None
    assert len(det.views) == 4
    assert len(det.detect(np.zeros((320, 640, 3), np.uint8))) == 0  # 0.6 < 0.7


def test_yolo_rejects_non_image_model(tmp_path):
    import onnx
    from onnx import TensorProto, helper

    x = helper.make_tensor_value_info("x", TensorProto.FLOAT, [1, 10])
    y = helper.make_tensor_value_info("y", TensorProto.FLOAT, [1, 10])
    m = helper.make_model(
        helper.make_graph([helper.make_node("Relu", ["x"], ["y"])], "g", [x], [y]),
        opset_imports=[helper.make_opsetid("", 17)],
    )
    m.ir_version = 8
    onnx.save(m, str(tmp_path / "mlp.onnx"))
    with pytest.raises(ImageDetectorError, match=r"\[1, 3, H, W\]"):
        get_image_detector(str(tmp_path / "mlp.onnx"))
    assert math.isfinite(1.0)
