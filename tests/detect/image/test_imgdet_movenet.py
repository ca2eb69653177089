"""MoveNet and CenterNet backends: pre/post-processing on synthetic tensors, the bundled models end to end."""

from __future__ import annotations

import math

import cv2
import numpy as np
import pytest
from imgdet_synth import PHOTO, paste_billboard, textured_pano

from studio.detect.image import ImageDetections, ImageDetectorError, get_image_detector
from studio.detect.image.centernet import centernet_postprocess, centernet_preprocess
from studio.detect.image.movenet import movenet_postprocess, movenet_preprocess
from studio.detect.image.sweep import SweepParams
from studio.geometry import pano_box_iou


def test_movenet_preprocess():
    img = np.zeros((64, 96, 3), np.uint8)
    img[..., 0] = 10  # blue
    img[..., 2] = 200  # red
    x = movenet_preprocess(img)
    assert x.shape == (1, 64, 96, 3)
    assert x.dtype == np.int32
    assert x[0, 0, 0].tolist() == [200, 0, 10]  # RGB
    with pytest.raises(ImageDetectorError, match="multiples of 32"):
        movenet_preprocess(np.zeros((50, 64, 3), np.uint8))


def _movenet_row(box, score, kp_score=0.9, kps=None):
    """One person row of MoveNet's output: 17 × (y, x, s) normalised, then ymin, xmin, ymax, xmax, score."""
    y1, x1, y2, x2 = box
    if kps is None:
        kps = [((y1 + y2) / 2, (x1 + x2) / 2)] * 17
    row = []
    for y, x in kps:
        row += [y, x, kp_score]
    return [*row, y1, x1, y2, x2, score]


def test_movenet_postprocess_scales_and_filters():
    out = np.zeros((1, 6, 56), np.float32)
    out[0, 0] = _movenet_row((0.25, 0.5, 0.75, 0.75), 0.8)
    out[0, 1] = _movenet_row((0.1, 0.1, 0.2, 0.2), 0.1)  # below threshold
    d = movenet_postprocess(out, 256, 320, score_threshold=0.2)
    assert len(d) == 1
    np.testing.assert_allclose(d.boxes[0], [128, 80, 192, 240], atol=1e-4)
    assert d.keypoints is not None
    np.testing.assert_allclose(d.keypoints[0, 0], [160, 160, 0.9], atol=1e-4)
    assert math.isclose(d.scores[0], 0.8, rel_tol=1e-6)


def test_movenet_postprocess_box_grows_to_confident_keypoints():
    kps = [(0.5, 0.5)] * 16 + [(0.95, 0.9)]  # an ankle below and right of the network's box
    out = np.zeros((1, 6, 56), np.float32)
    out[0, 0] = _movenet_row((0.2, 0.4, 0.8, 0.6), 0.7, kps=kps)
    d = movenet_postprocess(out, 100, 100)
    np.testing.assert_allclose(d.boxes[0], [40, 20, 90, 95], atol=1e-4)
    out[0, 0, 50] = 0.1  # the ankle is not confident: box unchanged
    d = movenet_postprocess(out, 100, 100)
    np.testing.assert_allclose(d.boxes[0], [40, 20, 60, 80], atol=1e-4)


def test_movenet_postprocess_empty_and_clipped():
    assert len(movenet_postprocess(np.zeros((1, 6, 56)), 64, 64)) == 0
    out = np.zeros((1, 6, 56))
    out[0, 0] = _movenet_row((-0.1, -0.2, 1.3, 0.5), 0.9)
    d = movenet_postprocess(out, 64, 64)
    assert d.boxes[0].tolist() == [0.0, 0.0, 32.0, 64.0]


def test_centernet_pre_and_postprocess():
    x = centernet_preprocess(np.full((32, 32, 3), (1, 2, 3), np.uint8))
    assert x.dtype == np.float32
    assert x[0, 0, 0].tolist() == [3.0, 2.0, 1.0]
    det = np.array(
        [
            [10, 20, 50, 100, 0.9, 0],  # person
            [12, 22, 52, 98, 0.8, 0],  # duplicate → NMS
            [100, 100, 150, 150, 0.95, 2],  # car
            [200, 10, 400, 300, 0.7, 0],  # person, clipped to 384
            [0, 0, 10, 10, 0.1, 0],  # low score
        ],
        np.float32,
    )[None]
    d = centernet_postprocess(det, 384, 384)
    assert d.keypoints is None
    np.testing.assert_allclose(d.boxes, [[10, 20, 50, 100], [200, 10, 384, 300]])
    np.testing.assert_allclose(d.scores, [0.9, 0.7], rtol=1e-6)


@pytest.fixture(scope="module")
def movenet():
    # a light sweep keeps the test quick
    return get_image_detector("movenet", sweep=SweepParams(count=4, fov_deg=100, width=256, height=320))


def test_movenet_blank_panorama_is_empty(movenet):
    for pano in (np.zeros((320, 640, 3), np.uint8), np.full((480, 960, 3), 255, np.uint8)):
        d = movenet.detect(pano)
        assert isinstance(d, ImageDetections)
        assert len(d) == 0
        assert (d.width, d.height) == (pano.shape[1], pano.shape[0])


def test_movenet_rejects_non_panorama(movenet):
    with pytest.raises(ImageDetectorError, match="BGR uint8"):
        movenet.detect(np.zeros((100, 200), np.uint8))
    with pytest.raises(ImageDetectorError, match="BGR uint8"):
        movenet.detect(np.zeros((100, 200, 3), np.float32))


@pytest.mark.skipif(PHOTO is None, reason="matplotlib sample photo not installed")
def test_movenet_finds_photo_person_across_the_seam(movenet):
    photo = cv2.imread(str(PHOTO))
    pano, gt = paste_billboard(
        textured_pano(1280, 640), photo, az=math.pi, dist=1.2, z_bottom=-0.3, height_m=0.9
    )
    d = movenet.detect(pano)
    assert len(d) >= 1
    assert np.all(d.boxes[:, 0] >= 0)
    assert np.all(d.boxes[:, 0] < 1280)
    assert d.keypoints is not None
    assert np.all((d.keypoints[..., 0] >= 0) & (d.keypoints[..., 0] < 1280))
    iou = pano_box_iou(d.boxes, np.asarray(gt)[None], 1280)[:, 0]
    assert iou.max() > 0.3, (d.boxes, gt)
    assert (iou > 0.1).sum() == 1  # one detection for the person on the seam


def test_centernet_end_to_end():
    det = get_image_detector("centernet", count=4, fov_deg=100)
    assert len(det.detect(np.zeros((320, 640, 3), np.uint8))) == 0
    if PHOTO is not None:
        photo = cv2.imread(str(PHOTO))
        pano, gt = paste_billboard(
            textured_pano(1280, 640), photo, az=0.3, dist=1.5, z_bottom=-0.3, height_m=0.9
        )
        d = det.detect(pano)
        assert d.keypoints is None
        assert pano_box_iou(d.boxes, np.asarray(gt)[None], 1280).max() > 0.3


def test_combine_detections_pairs_boxes_and_poses():
    from studio.detect.image.combined import combine_detections

    w, h = 1000, 500
    boxes = ImageDetections(
        [[100, 100, 150, 300], [980, 100, 1030, 300], [500, 50, 520, 90]], [0.9, 0.8, 0.5], None, w, h
    )
    kp = np.zeros((3, 17, 3))
    kp[:, :, 2] = 0.7
    kp[0, :, :2] = [125, 200]
    kp[1, :, :2] = [5, 200]
    kp[2, :, :2] = [700, 200]
    poses = ImageDetections(
        [[105, 110, 148, 280], [990, 110, 1025, 290], [690, 100, 720, 300]], [0.6, 0.7, 0.4], kp, w, h
    )
    out = combine_detections(boxes, poses)
    assert len(out) == 4  # three boxes + the pose CenterNet missed (score 0.4 ≥ 0.35)
    assert out.keypoints is not None
    np.testing.assert_allclose(out.boxes[0], [100, 100, 150, 300])  # CenterNet's box …
    np.testing.assert_allclose(out.keypoints[0, 0], [125, 200, 0.7])  # … with MoveNet's keypoints
    np.testing.assert_allclose(out.keypoints[1, 0], [5, 200, 0.7])  # paired across the seam
    lone = out.boxes.tolist().index([500, 50, 520, 90])
    assert np.all(out.keypoints[lone, :, 2] == 0)
    assert [690, 100, 720, 300] in out.boxes.tolist()
    assert len(combine_detections(boxes, poses, movenet_alone_score=0.5)) == 3


def test_combined_end_to_end_blank():
    det = get_image_detector("combined", centernet_count=4, movenet_sweep=SweepParams(count=4, fov_deg=100))
    d = det.detect(np.zeros((320, 640, 3), np.uint8))
    assert len(d) == 0
    assert d.keypoints is not None
    assert d.keypoints.shape == (0, 17, 3)


def test_thread_plan():
    from studio.detect.image.sweep import thread_plan

    assert thread_plan(2, 5) == (2, 1)  # two single-threaded views at a time
    assert thread_plan(1, 5) == (1, 1)
    assert thread_plan(16, 5) == (5, 3)  # more cores than views: the rest goes into each pass
    assert thread_plan(4, 1) == (1, 4)
    workers, intra = thread_plan(None, 5)
    assert 1 <= workers <= 5
    assert intra >= 1
    with pytest.raises(ImageDetectorError, match="at least 1"):
        thread_plan(0, 5)


@pytest.mark.skipif(PHOTO is None, reason="matplotlib sample photo not installed")
def test_movenet_views_side_by_side_match_one_at_a_time():
    """Views inferred on two threads give the detections of views inferred one after the other."""
    photo = cv2.imread(str(PHOTO))
    pano = textured_pano(1280, 640)
    for az in (0.3, 2.0, 4.4):
        pano, _ = paste_billboard(pano, photo, az=az, dist=1.5, z_bottom=-0.3, height_m=0.9)
    sweep = SweepParams(count=4, fov_deg=100, width=256, height=320)
    one = get_image_detector("movenet", sweep=sweep, threads=1)
    two = get_image_detector("movenet", sweep=sweep, threads=2)
    assert (one.workers, two.workers) == (1, 2)
    a, b = one.detect(pano), two.detect(pano)
    assert len(a) >= 2
    np.testing.assert_allclose(a.boxes, b.boxes, atol=1e-3)
    np.testing.assert_allclose(a.keypoints, b.keypoints, atol=1e-3)
    views = one.render_views(pano)
    for x, y in zip(one.detect_views(views), two.detect_views(views), strict=True):
        np.testing.assert_allclose(x.boxes, y.boxes, atol=1e-3)
