"""MoveNet MultiPose Lightning (bundled ONNX) on a sweep of perspective views: boxes + 17 keypoints.

The network (Google, Apache-2.0; converted from TFJS by ``tools/convert_movenet.py``, see
``studio/models/NOTICE.md``) takes ``[1, H, W, 3]`` int32 RGB with H and W multiples of 32 and returns
``[1, 6, 56]``: for each of at most 6 people, 17 × ``(y, x, score)`` keypoints normalised to the input,
then ``(ymin, xmin, ymax, xmax, score)``. Six people per pass is one reason to run it on several views.
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
from studio.geometry import ViewRenderer

__all__ = ["MODEL_FILE", "MoveNetDetector", "movenet_postprocess", "movenet_preprocess"]

MODEL_FILE = "movenet-multipose-lightning.onnx"


def movenet_preprocess(image: NDArray[np.uint8]) -> NDArray[np.int32]:
    """BGR uint8 ``(h, w, 3)`` (h, w multiples of 32) → the network input ``(1, h, w, 3)`` int32 RGB."""
    if image.ndim != 3 or image.shape[2] != 3:
        raise ImageDetectorError(f"MoveNet needs a 3-channel image, got shape {image.shape}")
    if image.shape[0] % 32 or image.shape[1] % 32:
        raise ImageDetectorError(
            f"MoveNet input sides must be multiples of 32, got {image.shape[1]}×{image.shape[0]}"
        )
    return cv2.cvtColor(image, cv2.COLOR_BGR2RGB).astype(np.int32)[None]


def movenet_postprocess(
    output: NDArray[np.floating],
    width: int,
    height: int,
    *,
    score_threshold: float = 0.2,
    keypoint_score: float = 0.3,
) -> ViewDetections:
    """Network output ``(1, 6, 56)`` → people in input pixels.

    Args:
        output: raw MoveNet MultiPose output.
        width: input width, px.
        height: input height, px.
        score_threshold: minimum person score kept.
        keypoint_score: keypoints at least this confident extend the person's box (the network's box
            often stops short of raised arms or feet).

    Returns:
        Boxes ``[x1, y1, x2, y2]`` px clipped to the image, scores, keypoints ``(x, y, score)`` px.
    """
    out = np.asarray(output, dtype=np.float64).reshape(-1, 56)
    keep = out[:, 55] >= score_threshold
    out = out[keep]
    n = out.shape[0]
    if n == 0:
        return ViewDetections.empty()
    kp = out[:, :51].reshape(n, 17, 3)
    kps = np.stack([kp[..., 1] * width, kp[..., 0] * height, np.clip(kp[..., 2], 0.0, 1.0)], axis=-1)
    box = np.stack(
        [out[:, 52] * width, out[:, 51] * height, out[:, 54] * width, out[:, 53] * height], axis=-1
    )
    conf = kps[..., 2] >= keypoint_score
    kx, ky = kps[..., 0], kps[..., 1]
    box[:, 0] = np.minimum(box[:, 0], np.where(conf, kx, np.inf).min(axis=1))
    box[:, 1] = np.minimum(box[:, 1], np.where(conf, ky, np.inf).min(axis=1))
    box[:, 2] = np.maximum(box[:, 2], np.where(conf, kx, -np.inf).max(axis=1))
    box[:, 3] = np.maximum(box[:, 3], np.where(conf, ky, -np.inf).max(axis=1))
    box[:, [0, 2]] = np.clip(box[:, [0, 2]], 0.0, width)
    box[:, [1, 3]] = np.clip(box[:, [1, 3]], 0.0, height)
    box[:, 2] = np.maximum(box[:, 2], box[:, 0])
    box[:, 3] = np.maximum(box[:, 3], box[:, 1])
    kps[..., 0] = np.clip(kps[..., 0], 0.0, width)
    kps[..., 1] = np.clip(kps[..., 1], 0.0, height)
    return ViewDetections(box, np.clip(out[:, 55], 0.0, 1.0), kps)


class MoveNetDetector(ViewSweepDetector):
    """MoveNet MultiPose Lightning over a ring of perspective views (the default image detector).

    Args:
        sweep: the views (default: 5 views of 90° × 102°, 256 × 320 px, on the horizon; see
            ``bench/bench_image_detector.py``). Sizes must be multiples of 32.
        merge: how duplicates across views are merged.
        score_threshold: minimum person score.
        keypoint_score: keypoint confidence that extends a box.
        model_path: another MoveNet MultiPose ONNX file (default: the bundled one).
        threads: CPU threads for the network (default: every core; see :func:`thread_plan`).
        renderer: a shared view renderer.
    """

    name = "movenet"

    def __init__(
        self,
        *,
        sweep: SweepParams | None = None,
        merge: MergeParams | None = None,
        score_threshold: float = 0.2,
        keypoint_score: float = 0.3,
        model_path: str | Path | None = None,
        threads: int | None = None,
        renderer: ViewRenderer | None = None,
    ) -> None:
        sweep = sweep or SweepParams()
        if sweep.width % 32 or sweep.height % 32:
            raise ImageDetectorError(
                f"MoveNet view sizes must be multiples of 32, got {sweep.width}×{sweep.height}"
            )
        workers, intra = thread_plan(threads, sweep.count)
        super().__init__(sweep=sweep, merge=merge, renderer=renderer, workers=workers)
        self.score_threshold = float(score_threshold)
        self.keypoint_score = float(keypoint_score)
        self.model_path = Path(model_path) if model_path is not None else bundled_model(MODEL_FILE)
        self.session = load_session(self.model_path, threads=intra)
        inp = self.session.get_inputs()[0]
        self._input = inp.name
        # narrow windows need a network that takes any width (the bundled one does; an export may not)
        self.windows = len(inp.shape) == 4 and not isinstance(inp.shape[2], int)

    def infer(self, x: NDArray[np.int32]) -> NDArray[np.float32]:
        """Run the network on one pre-processed input ``(1, h, w, 3)`` → ``(1, 6, 56)``."""
        out: NDArray[np.float32] = self.session.run(None, {self._input: x})[0]
        return out

    def detect_view(self, image: NDArray[np.uint8]) -> ViewDetections:
        h, w = image.shape[:2]
        return movenet_postprocess(
            self.infer(movenet_preprocess(image)),
            w,
            h,
            score_threshold=self.score_threshold,
            keypoint_score=self.keypoint_score,
        )
