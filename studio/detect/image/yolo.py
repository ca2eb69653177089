"""Adapter for a user's YOLO ONNX export (``--image-detector PATH.onnx``), run on perspective views.

Recognised output layouts (the first 3-D output of the model, batch 1):

* YOLOv5 / YOLOv7: ``[1, N, 5 + C]`` rows ``(cx, cy, w, h, objectness, class scores…)``;
  person score = objectness × class-0 score;
* YOLOv8 / YOLO11: ``[1, 4 + C, N]`` columns ``(cx, cy, w, h, class scores…)``, no objectness;
  person score = class-0 score.

The layouts are told apart by orientation (N candidates outnumber the 4–5 + C channels); ``layout=``
forces one. Boxes are in input pixels. Input ``[1, 3, H, W]`` RGB scaled to 0–1 (float32 or float16),
letterboxed (aspect kept, grey 114 padding, centred) as Ultralytics does; a dynamic input size is
taken as the view size (default 640). Ultralytics itself is not needed (AGPL; only an optional plugin).
"""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np
from numpy.typing import NDArray

from studio.detect.image.base import ViewDetections
from studio.detect.image.errors import ImageDetectorError
from studio.detect.image.sweep import MergeParams, SweepParams, ViewSweepDetector, load_session, thread_plan
from studio.geometry import ViewRenderer

__all__ = ["Letterbox", "YoloDetector", "letterbox", "nms", "parse_yolo_output", "yolo_postprocess"]

FloatArray = NDArray[np.float64]
PAD_VALUE = 114


def nms(boxes: FloatArray, scores: FloatArray, iou_threshold: float) -> NDArray[np.intp]:
    """Greedy non-maximum suppression of ``(N, 4)`` ``[x1, y1, x2, y2]`` boxes; kept indices by score."""
    order = np.argsort(-np.asarray(scores), kind="stable")
    b = np.asarray(boxes, dtype=np.float64)
    area = np.clip(b[:, 2] - b[:, 0], 0, None) * np.clip(b[:, 3] - b[:, 1], 0, None)
    keep: list[int] = []
    while order.size:
        i = int(order[0])
        keep.append(i)
        rest = order[1:]
        iw = np.clip(np.minimum(b[i, 2], b[rest, 2]) - np.maximum(b[i, 0], b[rest, 0]), 0, None)
        ih = np.clip(np.minimum(b[i, 3], b[rest, 3]) - np.maximum(b[i, 1], b[rest, 1]), 0, None)
        inter = iw * ih
        union = area[i] + area[rest] - inter
        iou = np.where(union > 0, inter / np.where(union > 0, union, 1.0), 0.0)
        order = rest[iou <= iou_threshold]
    return np.asarray(keep, dtype=np.intp)


class Letterbox:
    """How an image was letterboxed: ``input = image · scale + (pad_x, pad_y)`` (px)."""

    __slots__ = ("pad_x", "pad_y", "scale")

    def __init__(self, scale: float, pad_x: float, pad_y: float) -> None:
        self.scale, self.pad_x, self.pad_y = float(scale), float(pad_x), float(pad_y)

    def to_image(self, boxes: FloatArray) -> FloatArray:
        """Boxes ``(N, 4)`` from network-input px back to image px."""
        b = np.asarray(boxes, dtype=np.float64).copy()
        b[:, [0, 2]] = (b[:, [0, 2]] - self.pad_x) / self.scale
        b[:, [1, 3]] = (b[:, [1, 3]] - self.pad_y) / self.scale
        return b


def letterbox(image: NDArray[np.uint8], width: int, height: int) -> tuple[NDArray[np.uint8], Letterbox]:
    """Resize ``image`` to fit ``width × height`` keeping its aspect, centred on grey padding."""
    h, w = image.shape[:2]
    scale = min(width / w, height / h)
    nw, nh = max(1, round(w * scale)), max(1, round(h * scale))
    resized = cv2.resize(image, (nw, nh), interpolation=cv2.INTER_AREA if scale < 1 else cv2.INTER_LINEAR)
    px, py = (width - nw) // 2, (height - nh) // 2
    out = np.full((height, width, 3), PAD_VALUE, dtype=np.uint8)
    out[py : py + nh, px : px + nw] = resized
    return out, Letterbox(scale, px, py)


def parse_yolo_output(
    output: NDArray[np.floating], *, person_class: int = 0, layout: str | None = None
) -> tuple[FloatArray, FloatArray, str]:
    """Raw YOLO output → candidate person boxes ``(N, 4)`` ``[x1, y1, x2, y2]`` input px, scores ``(N,)``.

    Args:
        output: ``[1, N, 5 + C]`` (v5/v7) or ``[1, 4 + C, N]`` (v8/v11).
        person_class: class index of ``person`` (0 in COCO).
        layout: ``"v5"`` or ``"v8"`` to force a layout; None guesses it from the orientation.

    Returns:
        boxes, scores and the layout used.
    """
    a = np.asarray(output, dtype=np.float64)
    if a.ndim == 3 and a.shape[0] == 1:
        a = a[0]
    if a.ndim != 2:
        raise ImageDetectorError(
            f"unsupported YOLO output shape {np.shape(output)} (expected [1, N, 5+C] or [1, 4+C, N])"
        )
    if layout is None:
        layout = "v8" if a.shape[0] < a.shape[1] else "v5"
    if layout == "v8":
        rows = a.T
        if rows.shape[1] < 5 + person_class:
            raise ImageDetectorError(
                f"YOLOv8-style output with {rows.shape[1]} channels has no class {person_class}"
            )
        scores = rows[:, 4 + person_class]
    elif layout == "v5":
        rows = a
        if rows.shape[1] < 6 + person_class:
            raise ImageDetectorError(
                f"YOLOv5-style output with {rows.shape[1]} channels has no class {person_class}"
            )
        scores = rows[:, 4] * rows[:, 5 + person_class]
    else:
        raise ImageDetectorError(f"unknown YOLO layout '{layout}' (use v5 or v8)")
    cx, cy, bw, bh = rows[:, 0], rows[:, 1], rows[:, 2], rows[:, 3]
    boxes = np.stack([cx - bw / 2, cy - bh / 2, cx + bw / 2, cy + bh / 2], axis=-1)
    return boxes, scores, layout


def yolo_postprocess(
    output: NDArray[np.floating],
    lb: Letterbox,
    width: int,
    height: int,
    *,
    score_threshold: float = 0.25,
    iou_threshold: float = 0.45,
    person_class: int = 0,
    layout: str | None = None,
) -> ViewDetections:
    """Raw output → person boxes in the (un-letterboxed) ``width × height`` image px, after NMS."""
    boxes, scores, _ = parse_yolo_output(output, person_class=person_class, layout=layout)
    ok = np.isfinite(scores) & (scores >= score_threshold) & np.all(np.isfinite(boxes), axis=1)
    boxes, scores = boxes[ok], scores[ok]
    if boxes.shape[0] == 0:
        return ViewDetections.empty(keypoints=False)
    boxes = lb.to_image(boxes)
    boxes[:, [0, 2]] = np.clip(boxes[:, [0, 2]], 0.0, width)
    boxes[:, [1, 3]] = np.clip(boxes[:, [1, 3]], 0.0, height)
    boxes[:, 2] = np.maximum(boxes[:, 2], boxes[:, 0])
    boxes[:, 3] = np.maximum(boxes[:, 3], boxes[:, 1])
    keep = nms(boxes, scores, iou_threshold)
    return ViewDetections(boxes[keep], np.clip(scores[keep], 0.0, 1.0), None)


class YoloDetector(ViewSweepDetector):
    """A YOLO ONNX export run over a ring of perspective views (person class only).

    Args:
        model_path: the ``.onnx`` file.
        count: number of views around the horizon.
        fov_deg: horizontal field of view of a view, degrees.
        pitch_deg: elevation of the optical axes, degrees.
        view_size: ``(width, height)`` of the views, px (default: the model's fixed input size, else 640²).
        score_threshold: minimum person score.
        iou_threshold: NMS IoU within a view.
        person_class: class index of ``person``.
        layout: force ``"v5"`` or ``"v8"``.
        merge: how duplicates across views are merged.
        threads: CPU threads for the network (default: every core; see :func:`thread_plan`).
        renderer: a shared view renderer.
    """

    name = "yolo"

    def __init__(
        self,
        model_path: str | Path,
        *,
        count: int = 6,
        fov_deg: float = 90.0,
        pitch_deg: float = -10.0,
        view_size: tuple[int, int] | None = None,
        score_threshold: float = 0.25,
        iou_threshold: float = 0.45,
        person_class: int = 0,
        layout: str | None = None,
        merge: MergeParams | None = None,
        threads: int | None = None,
        renderer: ViewRenderer | None = None,
    ) -> None:
        self.model_path = Path(model_path)
        workers, intra = thread_plan(threads, count)
        self.session = load_session(self.model_path, threads=intra)
        inp = self.session.get_inputs()[0]
        shape = list(inp.shape)
        if len(shape) != 4 or shape[1] not in (3, "3"):
            raise ImageDetectorError(f"{self.model_path}: expected a [1, 3, H, W] image input, got {shape}")
        self._input = inp.name
        self._dtype = np.float16 if inp.type == "tensor(float16)" else np.float32
        fixed = isinstance(shape[2], int) and isinstance(shape[3], int)
        self.input_size = (int(shape[3]), int(shape[2])) if fixed else None  # (W, H)
        outs = self.session.get_outputs()
        three_d = [o.name for o in outs if len(o.shape) == 3]
        self._output = three_d[0] if three_d else outs[0].name
        vw, vh = view_size or self.input_size or (640, 640)
        sweep = SweepParams(count=count, fov_deg=fov_deg, width=int(vw), height=int(vh), pitch_deg=pitch_deg)
        super().__init__(sweep=sweep, merge=merge, renderer=renderer, workers=workers)
        self.score_threshold = float(score_threshold)
        self.iou_threshold = float(iou_threshold)
        self.person_class = int(person_class)
        self.layout = layout
        self.name = f"yolo:{self.model_path.name}"

    def preprocess(self, image: NDArray[np.uint8]) -> tuple[NDArray[np.floating], Letterbox]:
        """BGR uint8 view → ``(1, 3, H, W)`` RGB in 0–1 and the letterbox used."""
        w, h = self.input_size or (image.shape[1], image.shape[0])
        boxed, lb = letterbox(image, w, h)
        x = cv2.cvtColor(boxed, cv2.COLOR_BGR2RGB).transpose(2, 0, 1)[None].astype(np.float32) / 255.0
        return x.astype(self._dtype), lb

    def infer(self, x: NDArray[np.floating]) -> NDArray[np.floating]:
        out: NDArray[np.floating] = self.session.run([self._output], {self._input: x})[0]
        return out

    def detect_view(self, image: NDArray[np.uint8]) -> ViewDetections:
        x, lb = self.preprocess(image)
        return yolo_postprocess(
            self.infer(x),
            lb,
            image.shape[1],
            image.shape[0],
            score_threshold=self.score_threshold,
            iou_threshold=self.iou_threshold,
            person_class=self.person_class,
            layout=self.layout,
        )
