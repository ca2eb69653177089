"""Contract of the image people detectors, and the registry that picks one by name or model file.

A detector takes one equirectangular panorama (BGR uint8, as OpenCV decodes it) and returns the people in
it as :class:`ImageDetections` in panorama pixels. Each backend is pre-process → infer → post-process,
each step a function testable alone. Backends import lazily: ``studio.detect.image`` costs nothing until
a detector is asked for.

Boxes follow the seam convention of :mod:`studio.geometry`: ``[u1, v1, u2, v2]`` px from the left/top
edge, ``u1`` in ``[0, W)``, ``u2 >= u1``; a box across the 0/360° seam has ``u2 > W``.
"""

from __future__ import annotations

import importlib
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Protocol, runtime_checkable

import numpy as np
from numpy.typing import ArrayLike, NDArray

from studio.detect.image.errors import ImageDetectorError

__all__ = [
    "KEYPOINT_NAMES",
    "ImageDetections",
    "ImageDetector",
    "ViewDetections",
    "get_image_detector",
    "image_detector_names",
    "register_image_detector",
]

FloatArray = NDArray[np.float64]

KEYPOINT_NAMES = (
    "nose",
    "left_eye",
    "right_eye",
    "left_ear",
    "right_ear",
    "left_shoulder",
    "right_shoulder",
    "left_elbow",
    "right_elbow",
    "left_wrist",
    "right_wrist",
    "left_hip",
    "right_hip",
    "left_knee",
    "right_knee",
    "left_ankle",
    "right_ankle",
)
"""The 17 COCO body keypoints, in the order of the ``keypoints`` arrays."""


def _boxes(a: ArrayLike, what: str) -> FloatArray:
    b = np.asarray(a, dtype=np.float64)
    if b.size == 0:
        b = b.reshape(0, 4)
    if b.ndim != 2 or b.shape[1] != 4:
        raise ValueError(f"{what}.boxes must have shape (N, 4), got {b.shape}")
    if not np.all(np.isfinite(b)):
        raise ValueError(f"{what}.boxes must be finite")
    if np.any(b[:, 2] < b[:, 0]) or np.any(b[:, 3] < b[:, 1]):
        raise ValueError(f"{what}.boxes must have u2 >= u1 and v2 >= v1")
    return b


def _scores_keypoints(
    scores: ArrayLike, keypoints: ArrayLike | None, n: int, what: str
) -> tuple[FloatArray, FloatArray | None]:
    s = np.asarray(scores, dtype=np.float64).reshape(-1)
    if s.shape != (n,):
        raise ValueError(f"{what}.scores must have shape ({n},), got {s.shape}")
    if n and (not np.all(np.isfinite(s)) or s.min() < 0.0 or s.max() > 1.0):
        raise ValueError(f"{what}.scores must lie in [0, 1]")
    if keypoints is None:
        return s, None
    k = np.asarray(keypoints, dtype=np.float64)
    if k.size == 0 and n == 0:
        k = k.reshape(0, 17, 3)
    if k.shape != (n, 17, 3):
        raise ValueError(f"{what}.keypoints must have shape ({n}, 17, 3), got {k.shape}")
    return s, k


@dataclass(frozen=True)
class ImageDetections:
    """People found in one panorama, N of them.

    Attributes:
        boxes: ``(N, 4)`` float64 ``[u1, v1, u2, v2]`` panorama px; ``u1`` in ``[0, W)``, ``u2`` may exceed
            ``width`` for a box across the 0/360° seam.
        scores: ``(N,)`` float64 in [0, 1].
        keypoints: ``(N, 17, 3)`` float64 ``(u, v, score)`` per :data:`KEYPOINT_NAMES`, panorama px with
            ``u`` wrapped into ``[0, W)``, score in [0, 1]; None when the detector has no keypoints.
        width: panorama width W, px.
        height: panorama height H, px.
    """

    boxes: FloatArray
    scores: FloatArray
    keypoints: FloatArray | None
    width: int
    height: int

    def __post_init__(self) -> None:
        b = _boxes(self.boxes, "ImageDetections")
        s, k = _scores_keypoints(self.scores, self.keypoints, b.shape[0], "ImageDetections")
        w, h = int(self.width), int(self.height)
        if w <= 0 or h <= 0:
            raise ValueError(f"ImageDetections size must be positive, got {w}×{h}")
        if b.shape[0] and (b[:, 0].min() < 0.0 or b[:, 0].max() >= w or np.any(b[:, 2] - b[:, 0] > w)):
            raise ValueError("ImageDetections.boxes must have u1 in [0, W) and a width of at most W")
        object.__setattr__(self, "boxes", b)
        object.__setattr__(self, "scores", s)
        object.__setattr__(self, "keypoints", k)
        object.__setattr__(self, "width", w)
        object.__setattr__(self, "height", h)

    def __len__(self) -> int:
        return int(self.boxes.shape[0])

    @staticmethod
    def empty(width: int, height: int, *, keypoints: bool = True) -> ImageDetections:
        """No detections in a ``width × height`` panorama (with an empty keypoint array unless told not)."""
        return ImageDetections(
            np.zeros((0, 4)), np.zeros(0), np.zeros((0, 17, 3)) if keypoints else None, width, height
        )

    def select(self, index: ArrayLike) -> ImageDetections:
        """The detections at ``index`` (integer indices or a boolean mask), in that order."""
        i = np.asarray(index)
        kp = None if self.keypoints is None else self.keypoints[i]
        return ImageDetections(self.boxes[i], self.scores[i], kp, self.width, self.height)


@dataclass(frozen=True)
class ViewDetections:
    """People found in one (perspective or letterboxed) image by a single network pass, N of them.

    Attributes:
        boxes: ``(N, 4)`` float64 ``[x1, y1, x2, y2]`` px in that image (pixel ``(i, j)`` covers
            ``[i, i+1) × [j, j+1)``).
        scores: ``(N,)`` float64 in [0, 1].
        keypoints: ``(N, 17, 3)`` float64 ``(x, y, score)`` px, or None.
    """

    boxes: FloatArray
    scores: FloatArray
    keypoints: FloatArray | None = None

    def __post_init__(self) -> None:
        b = _boxes(self.boxes, "ViewDetections")
        s, k = _scores_keypoints(self.scores, self.keypoints, b.shape[0], "ViewDetections")
        object.__setattr__(self, "boxes", b)
        object.__setattr__(self, "scores", s)
        object.__setattr__(self, "keypoints", k)

    def __len__(self) -> int:
        return int(self.boxes.shape[0])

    @staticmethod
    def empty(*, keypoints: bool = True) -> ViewDetections:
        return ViewDetections(np.zeros((0, 4)), np.zeros(0), np.zeros((0, 17, 3)) if keypoints else None)


@runtime_checkable
class ImageDetector(Protocol):
    """Finds people in equirectangular panoramas.

    A detector may also set ``thread_safe = True`` when ``detect`` may run on several panoramas at once from
    different threads (the bundled ones do); ``studio label`` then keeps two panoramas in flight. Without it
    one detection runs at a time (still beside reading and the laser detector).

    A detector that can look at part of the panorama only sets ``looks_at_columns = True`` and accepts
    ``detect(pano, columns=mask)``, ``mask`` a ``(W,)`` boolean array of the panorama columns where someone
    may be (MoveNet runs narrow views centred on them; CenterNet and YOLO exports run the
    views of their sweep that see them); ``studio label`` then looks at the quiet part of the panorama less
    often (``LabelOptions.quiet_view_period_s``). One that also sets ``windows = True`` (MoveNet) accepts
    ``zoom=bearings`` too, azimuths where the laser found someone 4.5–11 m away
    (:func:`studio.pipeline.perceive.far_bearings`); where its views found nobody there, it looks closer.
    """

    name: str

    def detect(self, pano: NDArray[np.uint8]) -> ImageDetections:
        """People in ``pano``, an ``(H, W, 3)`` BGR uint8 equirectangular image."""
        ...


# ----------------------------------------------------------------------------------------------- registry
# name → "module:factory"; the factory takes keyword options and returns an ImageDetector
_REGISTRY: dict[str, str] = {
    "movenet": "studio.detect.image.movenet:MoveNetDetector",
    "centernet": "studio.detect.image.centernet:CenterNetDetector",
    "combined": "studio.detect.image.combined:CombinedDetector",
}
DEFAULT_DETECTOR = "movenet"


def register_image_detector(name: str, target: str) -> None:
    """Register a backend under ``name``; ``target`` is ``"module:callable"`` returning an ImageDetector."""
    if ":" not in target:
        raise ValueError(f"target must be 'module:callable', got {target!r}")
    _REGISTRY[name] = target


def image_detector_names() -> list[str]:
    """Registered detector names (a path to a YOLO ``.onnx`` file is accepted too)."""
    return sorted(_REGISTRY)


def _load(target: str) -> Callable[..., Any]:
    module_name, attr = target.split(":", 1)
    factory: Callable[..., Any] = getattr(importlib.import_module(module_name), attr)
    return factory


def get_image_detector(name_or_path: str | None = None, **options: Any) -> ImageDetector:
    """The image people detector called ``name_or_path`` (default ``"movenet"``).

    Args:
        name_or_path: a registered name (:func:`image_detector_names`) or the path of a YOLO ONNX export
            (``*.onnx``: YOLOv5/v7/v8/v11 output layouts, class 0 = person).
        **options: keyword options of the backend (e.g. ``views``, ``score_threshold``).

    Raises:
        ImageDetectorError: unknown name, missing or unusable model file.
    """
    key = DEFAULT_DETECTOR if name_or_path is None else str(name_or_path)
    if key.lower().endswith(".onnx"):
        if not Path(key).is_file():
            raise ImageDetectorError(f"image detector model file not found: {key}")
        detector: ImageDetector = _load("studio.detect.image.yolo:YoloDetector")(key, **options)
        return detector
    if key not in _REGISTRY:
        raise ImageDetectorError(
            f"unknown image detector '{key}' (choose one of {', '.join(image_detector_names())}, "
            "or give the path of a YOLO .onnx export)"
        )
    detector = _load(_REGISTRY[key])(**options)
    return detector
