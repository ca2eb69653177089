"""Image people detectors: panorama → people boxes (and keypoints) in panorama pixels.

``get_image_detector("movenet")`` (the default: MoveNet MultiPose Lightning, bundled ONNX, boxes + 17
keypoints), ``"centernet"`` (CenterNet-MobileNetV3, bundled ONNX, boxes), ``"combined"`` (CenterNet boxes
with MoveNet keypoints) or the path of a user's YOLO ``.onnx`` export. Every backend runs onnxruntime on
a ring of perspective views and merges the views' detections on the sphere
(:mod:`studio.detect.image.sweep`). Backends are imported only when asked for.
"""

from __future__ import annotations

from studio.detect.image.base import (
    KEYPOINT_NAMES,
    ImageDetections,
    ImageDetector,
    ViewDetections,
    get_image_detector,
    image_detector_names,
    register_image_detector,
)
from studio.detect.image.errors import ImageDetectorError

__all__ = [
    "KEYPOINT_NAMES",
    "ImageDetections",
    "ImageDetector",
    "ImageDetectorError",
    "ViewDetections",
    "get_image_detector",
    "image_detector_names",
    "register_image_detector",
]
