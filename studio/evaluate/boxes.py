"""Box detection AP on the panorama (the image detector stage alone), COCO-style, seam-aware IoU.

Per image, predictions are taken by decreasing score; each takes the unmatched ground-truth box of highest
IoU if that IoU is ≥ the threshold (true positive), else it is a false positive. Over all images, the
precision–recall curve of predictions sorted by score is made monotone (precision envelope) and sampled at
the 101 recall points 0, 0.01, …, 1 (precision 0 beyond the largest recall reached); AP is their mean.
Unlike COCO there is no limit on detections per image and no area ranges or crowd regions.

IoU is :func:`studio.geometry.pano_box_iou`: a box near ``u = W`` overlaps one near ``u = 0`` and a box
may be written past the seam (``u2 > W``).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from studio.evaluate.align import DEFAULT_STAMP_TOLERANCE_NS, align_frames
from studio.evaluate.base import MetricResult
from studio.geometry.base import pano_box_iou
from studio.labels.base import LabelFrame, LabelSet

__all__ = ["BoxAP", "BoxAPResult", "box_ap", "box_ap_labels"]

RECALL_POINTS = np.linspace(0.0, 1.0, 101)


@dataclass(frozen=True)
class BoxAPResult(MetricResult):
    """Average precision of boxes at one IoU threshold.

    Attributes:
        ap: COCO 101-point interpolated AP in [0, 1] (NaN without ground-truth boxes).
        iou_threshold: IoU needed for a true positive.
        num_gt, num_pred: boxes counted; num_images: images (frames) evaluated.
        max_recall: recall with every prediction kept (NaN without ground truth).
    """

    ap: float
    iou_threshold: float
    num_gt: int
    num_pred: int
    num_images: int
    max_recall: float


def _boxes(b: ArrayLike | None) -> np.ndarray:
    if b is None:
        return np.zeros((0, 4))
    a = np.asarray(b, dtype=np.float64)
    if a.size == 0:
        return np.zeros((0, 4))
    if a.ndim != 2 or a.shape[1] != 4:
        raise ValueError(f"boxes must have shape (N, 4), got {a.shape}")
    return a


class BoxAP:
    """Box AP accumulated image by image (seam-aware IoU on a panorama of ``width`` pixels)."""

    def __init__(self, *, width: float, iou_threshold: float = 0.5) -> None:
        if not width > 0:
            raise ValueError(f"width must be positive, got {width}")
        if not 0.0 < iou_threshold <= 1.0:
            raise ValueError(f"iou_threshold must be in (0, 1], got {iou_threshold}")
        self.width = float(width)
        self.iou_threshold = float(iou_threshold)
        self.reset()

    def reset(self) -> None:
        self._scores: list[np.ndarray] = []
        self._tp: list[np.ndarray] = []
        self._num_gt = 0
        self._images = 0

    def update(
        self, gt_boxes: ArrayLike | None, pred_boxes: ArrayLike | None, scores: ArrayLike | None
    ) -> None:
        """Add one image.

        Args:
            gt_boxes: ground-truth boxes ``[u1, v1, u2, v2]``, shape (N, 4), px.
            pred_boxes: predicted boxes, shape (M, 4), px.
            scores: confidence of each predicted box, shape (M,).
        """
        g, p = _boxes(gt_boxes), _boxes(pred_boxes)
        s = np.zeros(0) if scores is None else np.asarray(scores, dtype=np.float64).reshape(-1)
        if len(s) != len(p):
            raise ValueError(f"{len(p)} boxes but {len(s)} scores")
        self._images += 1
        self._num_gt += len(g)
        if not len(p):
            return
        order = np.argsort(-s, kind="mergesort")
        tp = np.zeros(len(p), dtype=bool)
        if len(g):
            iou = pano_box_iou(p[order], g, self.width)
            taken = np.zeros(len(g), dtype=bool)
            for k in range(len(order)):
                cand = np.where(taken, -1.0, iou[k])
                best = int(np.argmax(cand))
                if cand[best] >= self.iou_threshold:
                    taken[best] = True
                    tp[k] = True
        self._scores.append(s[order])
        self._tp.append(tp)

    def compute(self) -> BoxAPResult:
        scores = np.concatenate(self._scores) if self._scores else np.zeros(0)
        tp = np.concatenate(self._tp) if self._tp else np.zeros(0, dtype=bool)
        n_gt = self._num_gt
        if n_gt == 0:
            return BoxAPResult(np.nan, self.iou_threshold, 0, len(scores), self._images, np.nan)
        order = np.argsort(-scores, kind="mergesort")
        tp = tp[order]
        tpc = np.cumsum(tp)
        fpc = np.cumsum(~tp)
        recall = tpc / n_gt
        precision = tpc / np.maximum(tpc + fpc, np.finfo(float).eps)
        envelope = np.maximum.accumulate(precision[::-1])[::-1] if len(precision) else precision
        sampled = np.zeros_like(RECALL_POINTS)
        if len(envelope):
            idx = np.searchsorted(recall, RECALL_POINTS, side="left")
            sampled = np.where(idx < len(envelope), envelope[np.minimum(idx, len(envelope) - 1)], 0.0)
        return BoxAPResult(
            ap=float(sampled.mean()),
            iou_threshold=self.iou_threshold,
            num_gt=n_gt,
            num_pred=len(scores),
            num_images=self._images,
            max_recall=float(recall[-1]) if len(recall) else 0.0,
        )


def box_ap(
    gt_boxes: Sequence[ArrayLike],
    pred_boxes: Sequence[ArrayLike],
    scores: Sequence[ArrayLike],
    *,
    width: float,
    iou_threshold: float = 0.5,
) -> BoxAPResult:
    """AP of predicted panorama boxes over a list of images (one entry per image in each sequence)."""
    if not len(gt_boxes) == len(pred_boxes) == len(scores):
        raise ValueError("gt_boxes, pred_boxes and scores need one entry per image")
    m = BoxAP(width=width, iou_threshold=iou_threshold)
    for g, p, s in zip(gt_boxes, pred_boxes, scores, strict=True):
        m.update(g, p, s)
    return m.compute()


def _frame_boxes(f: LabelFrame | None) -> tuple[np.ndarray, np.ndarray]:
    if f is None:
        return np.zeros((0, 4)), np.zeros(0)
    people = [p for p in f.people if p.box is not None]
    if not people:
        return np.zeros((0, 4)), np.zeros(0)
    boxes = np.array([p.box for p in people], dtype=np.float64)
    scores = np.array([1.0 if p.score is None else p.score for p in people])
    return boxes, scores


def box_ap_labels(
    pred: LabelSet,
    gt: LabelSet,
    *,
    width: float,
    iou_thresholds: Sequence[float] = (0.5, 0.3),
    stamp_tolerance_ns: int = DEFAULT_STAMP_TOLERANCE_NS,
) -> dict[float, BoxAPResult]:
    """Box AP between the ``box`` fields of two label sets, frames aligned as in :func:`align_frames`
    (without interpolation: a box belongs to one image).

    People without a box are left out on both sides; a predicted person without a score counts as 1.

    Returns:
        ``{iou_threshold: BoxAPResult}``.
    """
    al = align_frames(pred, gt, stamp_tolerance_ns=stamp_tolerance_ns, interpolate_gap_ns=0)
    out = {}
    for t in iou_thresholds:
        m = BoxAP(width=width, iou_threshold=t)
        for g, p in al.pairs:
            gb, _ = _frame_boxes(g)
            pb, ps = _frame_boxes(p)
            m.update(gb, pb, ps)
        out[float(t)] = m.compute()
    return out
