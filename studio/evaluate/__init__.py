"""Evaluate predicted people positions and tracks against ground truth (issue 4, docs/evaluation.md).

Detection (one-to-one Hungarian matching within a radius → P / R / F1), CLEAR MOT with ``motmetrics``
semantics, IDF1 / IDP / IDR, HOTA with TrackEval conventions and a Euclidean similarity, box AP on the
panorama with seam-aware IoU. Each metric is a class with ``update / reset / compute``;
:func:`evaluate` runs them all on two label files.
"""

from studio.evaluate.align import DEFAULT_STAMP_TOLERANCE_NS, Alignment, align_frames
from studio.evaluate.base import Metric, MetricResult
from studio.evaluate.boxes import BoxAP, BoxAPResult, box_ap, box_ap_labels
from studio.evaluate.clear import ClearFrame, ClearMOT, ClearMOTResult
from studio.evaluate.core import (
    JSON_KEYS,
    Evaluation,
    FrameEval,
    SplitResult,
    evaluate,
    evaluate_sequences,
    robot_motion,
)
from studio.evaluate.detection import Detection, DetectionResult, FrameMatch, match_frame
from studio.evaluate.errors import FrameAlignmentError
from studio.evaluate.hota import ALPHAS, HOTA, HOTAResult, similarity_matrix
from studio.evaluate.identity import Identity, IdentityResult
from studio.evaluate.matching import assign, distance_matrix

__all__ = [
    "ALPHAS",
    "DEFAULT_STAMP_TOLERANCE_NS",
    "HOTA",
    "JSON_KEYS",
    "Alignment",
    "BoxAP",
    "BoxAPResult",
    "ClearFrame",
    "ClearMOT",
    "ClearMOTResult",
    "Detection",
    "DetectionResult",
    "Evaluation",
    "FrameAlignmentError",
    "FrameEval",
    "FrameMatch",
    "HOTAResult",
    "Identity",
    "IdentityResult",
    "Metric",
    "MetricResult",
    "SplitResult",
    "align_frames",
    "assign",
    "box_ap",
    "box_ap_labels",
    "distance_matrix",
    "evaluate",
    "evaluate_sequences",
    "match_frame",
    "robot_motion",
    "similarity_matrix",
]
