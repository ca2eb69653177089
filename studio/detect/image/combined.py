"""CenterNet boxes with MoveNet keypoints: both bundled networks on the same views, matched per person.

On real 360° frames CenterNet's boxes were much better than MoveNet's (which miss hidden legs), while only
MoveNet gives keypoints (feet for range). This detector runs both over their view sweeps and pairs them on
the panorama by seam-aware IoU (Hungarian): a paired person gets CenterNet's box and MoveNet's keypoints;
an unpaired CenterNet box keeps zero-score keypoints; an unpaired MoveNet person is kept with its own box
when its score reaches ``movenet_alone_score`` (CenterNet missed it).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray
from scipy.optimize import linear_sum_assignment

from studio.detect.image.base import ImageDetections
from studio.detect.image.centernet import CenterNetDetector
from studio.detect.image.movenet import MoveNetDetector
from studio.detect.image.sweep import SweepParams, check_pano
from studio.geometry import ViewRenderer, pano_box_iou

__all__ = ["CombinedDetector", "combine_detections"]


def combine_detections(
    boxes: ImageDetections,
    poses: ImageDetections,
    *,
    min_iou: float = 0.3,
    movenet_alone_score: float = 0.35,
) -> ImageDetections:
    """Pair box detections (no keypoints) with pose detections (keypoints) of the same panorama.

    Args:
        boxes: detections whose boxes are trusted (CenterNet).
        poses: detections with keypoints (MoveNet).
        min_iou: least seam-aware IoU of a pair.
        movenet_alone_score: an unpaired pose detection is kept from this score up.

    Returns:
        Detections with keypoints (zero-score keypoints where no pose was paired), by decreasing score.
    """
    if (boxes.width, boxes.height) != (poses.width, poses.height):
        raise ValueError("detections of different panoramas")
    w, h = boxes.width, boxes.height
    kp_poses = poses.keypoints if poses.keypoints is not None else np.zeros((len(poses), 17, 3))
    kps = np.zeros((len(boxes), 17, 3))
    if len(boxes):  # unpaired: keypoints at the box's centre with score 0
        kps[:, :, 0] = (0.5 * (boxes.boxes[:, 0] + boxes.boxes[:, 2]) % w)[:, None]
        kps[:, :, 1] = (0.5 * (boxes.boxes[:, 1] + boxes.boxes[:, 3]))[:, None]
    paired_pose = np.zeros(len(poses), dtype=bool)
    if len(boxes) and len(poses):
        iou = pano_box_iou(boxes.boxes, poses.boxes, w)
        rows, cols = linear_sum_assignment(-iou)
        for r, c in zip(rows, cols, strict=True):
            if iou[r, c] >= min_iou:
                kps[r] = kp_poses[c]
                paired_pose[c] = True
    extra = ~paired_pose & (poses.scores >= movenet_alone_score)
    out_b = np.concatenate([boxes.boxes, poses.boxes[extra]])
    out_s = np.concatenate([boxes.scores, poses.scores[extra]])
    out_k = np.concatenate([kps, kp_poses[extra]])
    order = np.argsort(-out_s, kind="stable")
    return ImageDetections(out_b[order], out_s[order], out_k[order], w, h)


class CombinedDetector:
    """CenterNet boxes + MoveNet keypoints (see the module docstring); about the cost of both.

    Args:
        movenet_sweep: MoveNet's views (default as :class:`MoveNetDetector`).
        centernet_count: number of CenterNet views (384 × 384 px, 90°).
        min_iou: least IoU that pairs a box and a pose.
        movenet_alone_score: a MoveNet person CenterNet missed is kept from this score up.
        threads: CPU threads of each network (default: every core).
    """

    name = "combined"
    thread_safe = True
    looks_at_columns = True

    def __init__(
        self,
        *,
        movenet_sweep: SweepParams | None = None,
        centernet_count: int = 6,
        min_iou: float = 0.3,
        movenet_alone_score: float = 0.35,
        threads: int | None = None,
    ) -> None:
        renderer = ViewRenderer()
        self.centernet = CenterNetDetector(count=centernet_count, threads=threads, renderer=renderer)
        self.movenet = MoveNetDetector(sweep=movenet_sweep, threads=threads, renderer=renderer)
        self.min_iou = float(min_iou)
        self.movenet_alone_score = float(movenet_alone_score)

    @property
    def views_run(self) -> int:
        """Views inferred so far by both networks."""
        return self.centernet.views_run + self.movenet.views_run

    @property
    def view_columns_run(self) -> int:
        """Their widths summed, px."""
        return self.centernet.view_columns_run + self.movenet.view_columns_run

    def detect(self, pano: NDArray[np.uint8], *, columns: NDArray[np.bool_] | None = None) -> ImageDetections:
        """People in an equirectangular BGR uint8 panorama ``(H, W, 3)`` (``columns`` as
        :meth:`~studio.detect.image.sweep.ViewSweepDetector.detect`)."""
        check_pano(pano)
        return combine_detections(
            self.centernet.detect(pano, columns=columns),
            self.movenet.detect(pano, columns=columns),
            min_iou=self.min_iou,
            movenet_alone_score=self.movenet_alone_score,
        )
