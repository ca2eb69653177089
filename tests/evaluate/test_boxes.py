"""Box AP on the panorama: hand-made tables, the seam, and a cross-check with pycocotools."""

from __future__ import annotations

import contextlib
import io

import numpy as np
import pytest
from evalfixtures import frame

from studio.evaluate import BoxAP, box_ap, box_ap_labels
from studio.labels import LabelFrame, LabelPerson, LabelSet

W = 1920


def test_perfect_and_empty() -> None:
    g = np.array([[100, 100, 200, 300], [500, 100, 600, 300]], dtype=float)
    r = box_ap([g], [g], [np.array([0.9, 0.8])], width=W)
    assert r.ap == 1.0
    assert r.max_recall == 1.0
    assert box_ap([g], [np.zeros((0, 4))], [np.zeros(0)], width=W).ap == 0.0
    assert np.isnan(box_ap([np.zeros((0, 4))], [g], [np.array([0.9, 0.8])], width=W).ap)


def test_hand_computed_ap() -> None:
    # two GT; predictions by score: TP, FP, TP → P/R points (1, 0.5), (2/3, 1.0)
    g = np.array([[100, 100, 200, 300], [500, 100, 600, 300]], dtype=float)
    p = np.array([[100, 100, 200, 300], [900, 100, 1000, 300], [500, 100, 600, 300]], dtype=float)
    r = box_ap([g], [p], [np.array([0.9, 0.8, 0.7])], width=W)
    assert r.ap == pytest.approx((51 * 1.0 + 50 * 2 / 3) / 101)
    # the same boxes with the FP scored last: AP 1
    r = box_ap([g], [p], [np.array([0.9, 0.1, 0.7])], width=W)
    assert r.ap == pytest.approx(1.0)


def test_one_prediction_matches_one_ground_truth() -> None:
    g = np.array([[100, 100, 200, 300]], dtype=float)
    p = np.array([[100, 100, 200, 300], [102, 100, 202, 300]], dtype=float)
    r = box_ap([g], [p], [np.array([0.9, 0.8])], width=W)
    assert r.ap == pytest.approx(1.0)  # the duplicate is an FP after full recall
    r = box_ap([g], [p], [np.array([0.8, 0.9])], width=W)
    assert r.ap == pytest.approx(1.0)  # the shifted box still has IoU 0.96


SEAM = [
    # (gt box, predicted box, IoU ≥ 0.5?)
    ([1880, 100, 1960, 300], [-40, 100, 40, 300], True),  # the same box written on both sides of the seam
    ([1880, 100, 1960, 300], [1880, 100, 1960, 300], True),
    ([1900, 100, 1940, 300], [0, 100, 20, 300], True),  # 20 px of 40 on each side → IoU 0.5
    ([1880, 100, 1920, 300], [0, 100, 40, 300], False),  # touch at the seam only
    ([10, 100, 60, 300], [1930, 100, 1980, 300], True),  # u2 > W wraps onto the start
    ([10, 100, 60, 300], [1910, 100, 1960, 300], False),  # wrapped: 30 px of 70 → IoU 0.43
]


@pytest.mark.parametrize(("g", "p", "hit"), SEAM)
def test_seam_aware_iou(g: list[float], p: list[float], hit: bool) -> None:
    r = box_ap([np.array([g], float)], [np.array([p], float)], [np.array([0.5])], width=W)
    assert r.ap == (1.0 if hit else 0.0)


def test_ap_at_two_thresholds_from_label_files() -> None:
    def person(i: int, box: tuple[float, float, float, float], score: float | None = None) -> LabelPerson:
        return LabelPerson(id=i, x=1.0, y=0.0, box=box, score=score)

    gt = LabelSet.from_frames([LabelFrame(0, (person(1, (100, 100, 200, 300)),)), frame(1, {})])
    # IoU of the prediction: 60 × 200 / (100 × 200 + 100 × 200 − 60 × 200) = 0.4286 → hit at 0.3 only
    pred = LabelSet.from_frames([LabelFrame(0, (person(5, (140, 100, 240, 300), 0.7),)), frame(1, {})])
    res = box_ap_labels(pred, gt, width=W)
    assert res[0.5].ap == 0.0
    assert res[0.3].ap == 1.0


def test_bad_shapes() -> None:
    m = BoxAP(width=W)
    with pytest.raises(ValueError, match="scores"):
        m.update(np.zeros((1, 4)), np.zeros((2, 4)), np.zeros(1))
    with pytest.raises(ValueError, match="shape"):
        m.update(np.zeros((1, 3)), None, None)
    with pytest.raises(ValueError, match="width"):
        BoxAP(width=0)


@pytest.mark.parametrize("seed", range(6))
def test_equals_pycocotools_away_from_the_seam(seed: int) -> None:
    coco_mod = pytest.importorskip("pycocotools.coco")
    cocoeval = pytest.importorskip("pycocotools.cocoeval")
    rng = np.random.default_rng(seed)
    gts, preds, scores = [], [], []
    images: list[dict] = []
    anns: list[dict] = []
    dets: list[dict] = []
    for img in range(8):
        n = int(rng.integers(0, 6))
        xy = rng.uniform(50, 1500, (n, 2))
        wh = rng.uniform(30, 200, (n, 2))
        g = np.hstack([xy, xy + wh])
        # predictions: jittered copies of some GT plus clutter
        keep = g[rng.random(n) < 0.8]
        p = keep + rng.normal(0, 12, keep.shape)
        c = rng.integers(0, 4)
        cxy = rng.uniform(50, 1500, (c, 2))
        p = np.vstack([p, np.hstack([cxy, cxy + rng.uniform(30, 200, (c, 2))])])
        s = rng.random(len(p))
        gts.append(g)
        preds.append(p)
        scores.append(s)
        images.append({"id": img, "width": W, "height": 960})
        for b in g:
            w, h = b[2] - b[0], b[3] - b[1]
            anns.append(
                {
                    "id": len(anns) + 1,
                    "image_id": img,
                    "category_id": 1,
                    "bbox": [b[0], b[1], w, h],
                    "area": w * h,
                    "iscrowd": 0,
                }
            )
        for b, sc in zip(p, s, strict=True):
            dets.append(
                {
                    "image_id": img,
                    "category_id": 1,
                    "bbox": [b[0], b[1], b[2] - b[0], b[3] - b[1]],
                    "score": float(sc),
                }
            )
    coco = coco_mod.COCO()
    coco.dataset = {"images": images, "annotations": anns, "categories": [{"id": 1, "name": "person"}]}
    with contextlib.redirect_stdout(io.StringIO()):
        coco.createIndex()
        cdt = coco.loadRes(dets) if dets else None
        if cdt is None:
            pytest.skip("no detections")
        ev = cocoeval.COCOeval(coco, cdt, "bbox")
        ev.evaluate()
        ev.accumulate()
        ev.summarize()
    for t, k in ((0.5, 1),):
        mine = box_ap(gts, preds, scores, width=W, iou_threshold=t)
        assert mine.ap == pytest.approx(ev.stats[k], abs=1e-12)
    # AP@0.3 from COCO's precision table is not summarised; check it at 0.75 too (stats[2])
    assert box_ap(gts, preds, scores, width=W, iou_threshold=0.75).ap == pytest.approx(ev.stats[2], abs=1e-12)
