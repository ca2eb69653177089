"""Detection metrics: one-to-one matching per frame within a radius → TP / FP / FN, precision, recall, F1."""

from __future__ import annotations

from collections.abc import Hashable
from dataclasses import dataclass

import numpy as np

from studio.evaluate.base import MetricResult, frame_arrays, safe_div
from studio.evaluate.matching import assign, distance_matrix
from studio.labels.base import LabelFrame

__all__ = ["Detection", "DetectionResult", "FrameMatch", "match_frame"]


@dataclass(frozen=True)
class FrameMatch:
    """The one-to-one matching of one frame.

    Attributes:
        gt_index, pred_index: matched rows of the ground truth / prediction, shape (K,) each.
        distance: distance of each matched pair, shape (K,), metres.
        fn_index: unmatched ground-truth rows (misses), shape (N-K,).
        fp_index: unmatched prediction rows (false positives), shape (M-K,).
    """

    gt_index: np.ndarray
    pred_index: np.ndarray
    distance: np.ndarray
    fn_index: np.ndarray
    fp_index: np.ndarray

    @property
    def tp(self) -> int:
        return len(self.gt_index)

    @property
    def fp(self) -> int:
        return len(self.fp_index)

    @property
    def fn(self) -> int:
        return len(self.fn_index)


def match_frame(gt_xy: np.ndarray, pred_xy: np.ndarray, *, radius: float) -> FrameMatch:
    """Hungarian one-to-one matching of predictions to ground truth within ``radius``.

    The matching has the most pairs possible, then the smallest sum of distances. A pair at exactly
    ``radius`` matches.

    Args:
        gt_xy: shape (N, 2), metres.
        pred_xy: shape (M, 2), metres.
        radius: match radius, metres (> 0).
    """
    d = distance_matrix(gt_xy, pred_xy, radius=radius)
    rows, cols = assign(d)
    n, m = d.shape
    gt_free = np.ones(n, dtype=bool)
    gt_free[rows] = False
    pred_free = np.ones(m, dtype=bool)
    pred_free[cols] = False
    return FrameMatch(
        gt_index=rows,
        pred_index=cols,
        distance=d[rows, cols] if len(rows) else np.zeros(0),
        fn_index=np.flatnonzero(gt_free),
        fp_index=np.flatnonzero(pred_free),
    )


@dataclass(frozen=True)
class DetectionResult(MetricResult):
    """Detection counts and ratios (identities ignored).

    Attributes:
        precision: TP / (TP + FP), NaN with no prediction.
        recall: TP / (TP + FN), NaN with no ground truth.
        f1: 2 TP / (2 TP + FP + FN), NaN when both are empty.
        tp, fp, fn: counts over all frames.
        mean_distance: mean distance of the matched pairs, metres (NaN without matches).
        num_frames: ground-truth frames evaluated.
        radius: match radius, metres.
    """

    precision: float
    recall: float
    f1: float
    tp: int
    fp: int
    fn: int
    mean_distance: float
    num_frames: int
    radius: float


class Detection:
    """Precision / recall / F1 with one-to-one matching per frame (no identities)."""

    def __init__(self, *, radius: float = 0.2) -> None:
        if not radius > 0:
            raise ValueError(f"radius must be positive, got {radius}")
        self.radius = float(radius)
        self.reset()

    def reset(self) -> None:
        self._tp = self._fp = self._fn = self._frames = 0
        self._dist_sum = 0.0

    def update(self, gt: LabelFrame, pred: LabelFrame | None, *, sequence: Hashable = 0) -> FrameMatch:
        """Add one frame; returns its matching (rows index ``gt.people`` / ``pred.people``)."""
        del sequence  # detection counts do not depend on identities or sequences
        _, gxy = frame_arrays(gt)
        _, pxy = frame_arrays(pred)
        fm = match_frame(gxy, pxy, radius=self.radius)
        self._tp += fm.tp
        self._fp += fm.fp
        self._fn += fm.fn
        self._frames += 1
        self._dist_sum += float(fm.distance.sum())
        return fm

    def compute(self) -> DetectionResult:
        tp, fp, fn = self._tp, self._fp, self._fn
        return DetectionResult(
            precision=safe_div(tp, tp + fp),
            recall=safe_div(tp, tp + fn),
            f1=safe_div(2 * tp, 2 * tp + fp + fn),
            tp=tp,
            fp=fp,
            fn=fn,
            mean_distance=safe_div(self._dist_sum, tp),
            num_frames=self._frames,
            radius=self.radius,
        )
