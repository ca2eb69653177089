"""Run a per-image network over a sweep of perspective views around the horizon, back to the panorama.

A panorama is a poor input for detectors trained on perspective photos (people near the robot are bent,
and a single pass returns only a few people), so each backend sees pinhole views rendered from it
(:class:`studio.geometry.ViewRenderer`); its boxes and keypoints are mapped back to panorama pixels with
the exact view ↔ sphere mapping, and the duplicates that neighbouring views (or the 0/360° seam) produce
are merged on the sphere:

* two detections from the same view are never merged (the network already told them apart);
* detections from different views are one person when their seam-aware IoU exceeds ``iou_threshold`` or
  one box lies mostly inside the other (intersection / smaller area above ``containment``), unless their
  confident keypoints disagree (mean distance above ``keypoint_distance`` box heights: two people, one
  behind the other);
* a detection whose box touches its view's left or right border is a partial view of the person: a
  whole one from another view wins; two partial ones are united; two partial ones that overlap at all and
  share most of their rows (``partial_rows``) are one person cut by both views' borders (someone close
  to the robot, wider than the views' overlap).
"""

from __future__ import annotations

import math
import os
import threading
from collections.abc import Sequence
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from importlib import resources
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from studio.detect.image.base import ImageDetections, ViewDetections
from studio.detect.image.errors import ImageDetectorError
from studio.geometry import (
    PerspectiveView,
    ViewRenderer,
    angles_to_pixel,
    horizon_views,
    merge_pano_boxes,
    pano_box_iou,
    pixel_to_angles,
)

__all__ = [
    "MergeParams",
    "SweepParams",
    "ViewSweepDetector",
    "bundled_model",
    "check_pano",
    "load_session",
    "merge_on_sphere",
    "thread_plan",
    "views_to_pano",
]

FloatArray = NDArray[np.float64]


@dataclass(frozen=True)
class SweepParams:
    """A ring of ``count`` pinhole views around the horizon.

    Attributes:
        count: number of views, evenly spaced in azimuth (the first looks forward).
        fov_deg: horizontal field of view of each view, degrees (> 360/count so neighbours overlap).
        width: view width, px (the network input width).
        height: view height, px (the network input height).
        pitch_deg: elevation of the optical axes, degrees (negative looks down, towards the feet).
    """

    count: int = 5
    fov_deg: float = 90.0
    width: int = 256
    height: int = 320
    pitch_deg: float = 0.0

    def views(self) -> list[PerspectiveView]:
        return horizon_views(
            count=self.count,
            fov=math.radians(self.fov_deg),
            width=self.width,
            height=self.height,
            pitch=math.radians(self.pitch_deg),
        )


@dataclass(frozen=True)
class MergeParams:
    """Thresholds of :func:`merge_on_sphere` (see the module docstring)."""

    iou_threshold: float = 0.4
    containment: float = 0.7
    keypoint_distance: float = 0.25
    keypoint_score: float = 0.3
    border_px: float = 2.0
    partial_rows: float = 0.6


def bundled_model(file_name: str) -> Path:
    """Path of a model file shipped in ``studio/models``."""
    path = Path(str(resources.files("studio") / "models" / file_name))
    if not path.is_file():
        raise ImageDetectorError(f"bundled model {file_name} is missing from {path.parent} (broken install?)")
    return path


def thread_plan(threads: int | None, views: int) -> tuple[int, int]:
    """``(views run at once, onnxruntime intra-op threads per run)`` for a budget of ``threads`` CPU threads.

    A small network on one view uses two or more cores poorly (MoveNet at 256 × 320 px on 2 cores: 37 ms
    per view with 2 intra-op threads, 32 ms per view with two single-threaded views at once; see
    ``bench/bench_image_detector.py``), so the budget goes to running views side by side first; what is
    left over (more cores than views) goes to each run.

    Args:
        threads: CPU threads for the network (default: every core this process may run on).
        views: views per panorama.
    """
    if threads is None:
        total = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else (os.cpu_count() or 1)
    else:
        total = int(threads)
    if total < 1:
        raise ImageDetectorError(f"threads must be at least 1, got {threads}")
    workers = max(1, min(int(views), total))
    return workers, max(1, total // workers)


def load_session(path: str | Path, *, threads: int | None = None) -> Any:
    """An onnxruntime CPU session of ``path``; errors become :class:`ImageDetectorError`."""
    import onnxruntime as ort

    opts = ort.SessionOptions()
    if threads is not None:
        opts.intra_op_num_threads = int(threads)
        opts.inter_op_num_threads = 1
    opts.log_severity_level = 3
    try:
        return ort.InferenceSession(str(path), sess_options=opts, providers=["CPUExecutionProvider"])
    except Exception as exc:  # onnxruntime raises its own exception types for unreadable models
        first = str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__
        raise ImageDetectorError(f"cannot load ONNX model {path}: {first}") from None


def check_pano(pano: Any) -> tuple[int, int]:
    """``(W, H)`` of a BGR uint8 panorama ``(H, W, 3)``; ImageDetectorError otherwise."""
    if not isinstance(pano, np.ndarray) or pano.ndim != 3 or pano.shape[2] != 3 or pano.dtype != np.uint8:
        raise ImageDetectorError(
            "expected a BGR uint8 panorama of shape (H, W, 3), got "
            f"{getattr(pano, 'shape', type(pano).__name__)} {getattr(pano, 'dtype', '')}"
        )
    h, w = pano.shape[:2]
    if w < 8 or h < 4:
        raise ImageDetectorError(f"panorama too small: {w}×{h} px")
    return int(w), int(h)


def views_to_pano(
    views: list[PerspectiveView], per_view: list[ViewDetections], pano_w: int, pano_h: int
) -> tuple[FloatArray, FloatArray, FloatArray | None, FloatArray, NDArray[np.int64]]:
    """Map every view's detections to the panorama.

    Returns:
        boxes ``(N, 4)`` seam-form panorama px, scores ``(N,)``, keypoints ``(N, 17, 3)`` (u wrapped into
        ``[0, W)``) or None when a view has none, border margin ``(N,)`` (the box's distance to its view's
        left or right edge, whichever is nearer, px; 0 when it touches one), and the view index ``(N,)``.
    """
    boxes, scores, kps, margin, view_idx = [], [], [], [], []
    has_kp = all(d.keypoints is not None for d in per_view)
    for i, (view, det) in enumerate(zip(views, per_view, strict=True)):
        if len(det) == 0:
            continue
        b = det.boxes
        boxes.append(view.box_to_pano(b, pano_w, pano_h))
        scores.append(det.scores)
        m = np.minimum(b[:, 0], view.width - b[:, 2])  # left/right only: rows are cut alike in all views
        margin.append(np.maximum(m, 0.0))
        view_idx.append(np.full(len(det), i, dtype=np.int64))
        if has_kp and det.keypoints is not None:
            k = det.keypoints
            uv = view.view_to_pano(k[..., :2].reshape(-1, 2), pano_w, pano_h).reshape(len(det), 17, 2)
            kps.append(np.concatenate([uv, k[..., 2:3]], axis=-1))
    if not boxes:
        return (
            np.zeros((0, 4)),
            np.zeros(0),
            np.zeros((0, 17, 3)) if has_kp else None,
            np.zeros(0),
            np.zeros(0, dtype=np.int64),
        )
    kp_all = np.concatenate(kps) if has_kp else None
    return (
        np.concatenate(boxes),
        np.concatenate(scores),
        kp_all,
        np.concatenate(margin),
        np.concatenate(view_idx),
    )


def _keypoints_disagree(ka: FloatArray, kb: FloatArray, box_h: float, width: int, p: MergeParams) -> bool:
    both = (ka[:, 2] >= p.keypoint_score) & (kb[:, 2] >= p.keypoint_score)
    if both.sum() < 3:
        return False
    du = np.abs(ka[both, 0] - kb[both, 0])
    du = np.minimum(du, width - du)
    dv = ka[both, 1] - kb[both, 1]
    dist = float(np.mean(np.hypot(du, dv)))
    return dist > p.keypoint_distance * max(box_h, 1.0)


def merge_on_sphere(
    boxes: FloatArray,
    scores: FloatArray,
    keypoints: FloatArray | None,
    margin: FloatArray,
    view_idx: NDArray[np.int64],
    pano_w: int,
    pano_h: int,
    *,
    params: MergeParams | None = None,
) -> ImageDetections:
    """Merge detections of one person seen in several views (or across the seam) into one.

    Args:
        boxes: ``(N, 4)`` panorama px (seam form); scores ``(N,)``; keypoints ``(N, 17, 3)`` or None;
            margin ``(N,)`` px to the view border; view_idx ``(N,)`` (all as :func:`views_to_pano`).
        pano_w: panorama width W, px.
        pano_h: panorama height H, px.
        params: merge thresholds.

    Returns:
        The merged detections, by decreasing score. A merged person keeps the highest score of its group,
        the box of its best whole view (or the union of partial ones) and per keypoint the most
        confident estimate.
    """
    p = params or MergeParams()
    n = boxes.shape[0]
    if n == 0:
        return ImageDetections.empty(pano_w, pano_h, keypoints=keypoints is not None)
    whole = margin >= p.border_px
    order = np.lexsort((-scores, ~whole))  # whole views first, then by score
    iou = pano_box_iou(boxes, boxes, pano_w)
    area = (boxes[:, 2] - boxes[:, 0]) * (boxes[:, 3] - boxes[:, 1])
    inter = iou * (area[:, None] + area[None, :]) / (1.0 + iou)
    with np.errstate(invalid="ignore", divide="ignore"):
        contain = np.where(
            np.minimum(area[:, None], area[None, :]) > 0,
            inter / np.minimum(area[:, None], area[None, :]),
            0.0,
        )
    v_inter = np.clip(
        np.minimum(boxes[:, None, 3], boxes[None, :, 3]) - np.maximum(boxes[:, None, 1], boxes[None, :, 1]),
        0,
        None,
    )
    heights = boxes[:, 3] - boxes[:, 1]
    with np.errstate(invalid="ignore", divide="ignore"):
        v_ratio = np.where(
            np.minimum(heights[:, None], heights[None, :]) > 0,
            v_inter / np.minimum(heights[:, None], heights[None, :]),
            0.0,
        )

    def same_person(i: int, j: int) -> bool:
        if view_idx[i] == view_idx[j]:
            return False
        overlap = iou[i, j] > p.iou_threshold or contain[i, j] > p.containment
        # a person cut by two views' borders: two partial boxes that overlap and span the same rows
        cut = not whole[i] and not whole[j] and inter[i, j] > 0 and v_ratio[i, j] > p.partial_rows
        if not (overlap or cut):
            return False
        return keypoints is None or not _keypoints_disagree(
            keypoints[i], keypoints[j], max(heights[i], heights[j]), pano_w, p
        )

    groups: list[list[int]] = []
    for i in order:
        target = -1
        for g, members in enumerate(groups):
            if any(view_idx[m] == view_idx[i] for m in members):
                continue
            if any(same_person(int(i), m) for m in members):
                target = g
                break
        if target < 0:
            groups.append([int(i)])
        else:
            groups[target].append(int(i))

    out_b = np.zeros((len(groups), 4))
    out_s = np.zeros(len(groups))
    out_k = None if keypoints is None else np.zeros((len(groups), 17, 3))
    for g, members in enumerate(groups):
        idx = np.asarray(members)
        lead = members[0]
        out_s[g] = scores[idx].max()
        if whole[lead]:
            out_b[g] = boxes[lead]
        else:  # only partial views of this person: their union
            out_b[g] = merge_pano_boxes(boxes[idx], pano_w)
            out_b[g, 0] = min(out_b[g, 0], pano_w - 1e-6)
        if out_k is not None and keypoints is not None:
            best = idx[np.argmax(keypoints[idx, :, 2], axis=0)]  # (17,) member with the best estimate
            out_k[g] = keypoints[best, np.arange(17)]
    sort = np.argsort(-out_s, kind="stable")
    return ImageDetections(out_b[sort], out_s[sort], None if out_k is None else out_k[sort], pano_w, pano_h)


def column_runs(columns: NDArray[np.bool_], *, gap: int = 0) -> list[tuple[int, int]]:
    """Runs of set flags in a circular ``(W,)`` column mask, as ``(start, length)`` by ``start`` (in
    [0, W); a run across the 0/W seam is one); runs separated by ``gap`` or fewer clear columns are one."""
    cols = np.asarray(columns, dtype=bool).reshape(-1)
    w = len(cols)
    if not cols.any():
        return []
    if cols.all():
        return [(0, w)]
    first_clear = int(np.argmin(cols))
    rolled = np.roll(cols, -first_clear)  # starts with a clear column: no run crosses the ends
    edges = np.flatnonzero(np.diff(rolled.astype(np.int8)))
    starts, ends = edges[0::2] + 1, edges[1::2] + 1  # [start, end) in rolled indices
    if len(ends) < len(starts):
        ends = np.append(ends, w)
    runs: list[list[int]] = []
    for a, b in zip(starts.tolist(), ends.tolist(), strict=True):
        if runs and a - runs[-1][1] <= gap:
            runs[-1][1] = b
        else:
            runs.append([a, b])
    if len(runs) > 1 and runs[0][0] + w - runs[-1][1] <= gap:  # across the seam
        runs[0][0] = runs[-1][0] - w
        runs.pop()
    return sorted(((a + first_clear) % w, b - a) for a, b in runs)


class ViewSweepDetector:
    """Base of the detectors that run a network on perspective views: subclasses give ``detect_view``.

    Args:
        sweep: the ring of views.
        merge: merge thresholds.
        renderer: a shared :class:`ViewRenderer` (its LUT cache); a new one when None.
        workers: views inferred at once (threads; onnxruntime releases the GIL). ``detect_view`` must be
            safe to call from several threads (onnxruntime sessions are).
    """

    name = "sweep"
    thread_safe = True  # ``detect`` may run on several panoramas at once (see ``ImageDetector``)
    looks_at_columns = True  # ``detect`` takes ``columns`` (see ``ImageDetector``)
    windows = False  # ``detect_view`` takes views of any width that is a multiple of 32 (:meth:`windows_for`)
    window_min_px = 96  # narrowest window
    window_gap_deg = 10.0  # runs of columns closer than this share a window
    zoom_fov_deg = (18.0, 35.0)  # a zoom view's horizontal and vertical field of view (:meth:`zoom_views`)
    zoom_pitch_deg = -5.0  # and the elevation of its axis
    zoom_factor = 2.5  # its focal length: at most this many times the sweep's, at most the panorama's own

    def __init__(
        self,
        *,
        sweep: SweepParams,
        merge: MergeParams | None = None,
        renderer: ViewRenderer | None = None,
        workers: int = 1,
    ) -> None:
        self.sweep = sweep
        self.merge = merge or MergeParams()
        self.views = sweep.views()
        self.renderer = renderer or ViewRenderer()
        self.workers = max(1, int(workers))
        self.views_run = 0  # views inferred so far (``detect`` with ``columns`` may skip some)
        self.view_columns_run = 0  # and their widths summed, px (windows are narrower than the sweep's)
        self._count_lock = threading.Lock()
        self._footprints: dict[int, NDArray[np.bool_]] = {}  # panorama width → (views, W) column masks
        # threads start on first use; made here so two threads' first detections share one pool
        self._pool = (
            ThreadPoolExecutor(self.workers, thread_name_prefix="studio-views") if self.workers > 1 else None
        )

    def detect_view(self, image: NDArray[np.uint8]) -> ViewDetections:
        """People in one BGR uint8 view ``(h, w, 3)`` (pre-process → infer → post-process)."""
        raise NotImplementedError

    def render_views(
        self, pano: NDArray[np.uint8], views: list[PerspectiveView] | None = None
    ) -> list[NDArray[np.uint8]]:
        """``views`` (default: the sweep's) of ``pano`` (BGR uint8), in order."""
        check_pano(pano)
        if views is None or list(views) == self.views:
            return self.renderer.render_many(pano, self.views)
        # one by one: each subset's stacked look-up tables would be cached on their own
        return [self.renderer.render(pano, v) for v in views]

    def views_seeing(self, columns: NDArray[np.bool_]) -> list[int]:
        """Indices of the views that see at least one of ``columns``, a ``(W,)`` mask of panorama columns
        (a view's columns: those its whole image spans, :meth:`PerspectiveView.box_to_pano`; a pitched
        view reaches wider at its bottom corners)."""
        cols = np.asarray(columns, dtype=bool).reshape(-1)
        w = len(cols)
        if w not in self._footprints:
            u = np.arange(w) + 0.5
            feet = []
            for v in self.views:
                u1, _, u2, _ = v.box_to_pano(np.array([0.0, 0.0, v.width, v.height]), w, w // 2)[0]
                feet.append((u - u1) % w <= u2 - u1)  # seam form: u2 may exceed W
            self._footprints[w] = np.array(feet)
        return [int(i) for i in np.flatnonzero((self._footprints[w] & cols).any(axis=1))]

    def windows_for(self, columns: NDArray[np.bool_]) -> list[PerspectiveView] | None:
        """Narrow views ("windows") that look at ``columns`` for fewer network pixels than the sweep's views.

        Each run of adjacent columns (runs closer than ``window_gap_deg`` are one) gets a pinhole view
        centred on it, as wide as the run needs (a multiple of 32 px, at least ``window_min_px``) at the
        focal length, height and pitch of the sweep's views: a person is drawn at the same scale as in the
        sweep, only less of the panorama around them is. None when the detector takes only its sweep's
        width (``windows = False``), when a run is wider than a sweep view, or when the windows together are
        no narrower than the sweep views that see the columns (:meth:`views_seeing`).
        """
        if not self.windows:
            return None
        cols = np.asarray(columns, dtype=bool).reshape(-1)
        w = len(cols)
        runs = column_runs(cols, gap=round(self.window_gap_deg / 360.0 * w))
        if not runs:
            return []
        ref = self.views[0]
        f = ref.focal
        out = []
        for start, length in runs:
            half = math.pi * (length + 1) / w  # half the run's azimuth span, with half a column each side
            if half >= ref.fov / 2.0:
                return None
            px = max(self.window_min_px, 32 * math.ceil(2.0 * f * math.tan(half) / 32.0))
            if px > ref.width:
                return None
            # centred on a whole column: its look-up table is the yaw-0 window's, shifted (ViewRenderer.lut)
            centre = round(start + length / 2.0) % w
            yaw = float(pixel_to_angles(centre, 0.0, w, 1.0)[0])
            fov = 2.0 * math.atan(px / 2.0 / f)
            out.append(PerspectiveView(yaw, ref.pitch, fov, px, ref.height, name=f"w{centre}"))
        if sum(v.width for v in out) >= sum(self.views[i].width for i in self.views_seeing(cols)):
            return None
        return out

    def zoom_views(self, bearings: Sequence[float], boxes: FloatArray, pano_w: int) -> list[PerspectiveView]:
        """Views at a higher focal length centred on ``bearings`` (azimuths, rad) where none of ``boxes``
        (seam-form panorama px) lies: someone far away, a few pixels tall in the sweep's views, whom another
        sensor (the laser) has found there. Bearings within a quarter of a zoom view of one already chosen
        share it. Empty when the detector takes only its sweep's size (``windows = False``)."""
        if not self.windows or not len(bearings):
            return []
        ref = self.views[0]
        f = min(pano_w / (2.0 * math.pi), self.zoom_factor * ref.focal)
        hfov, vfov = (math.radians(a) for a in self.zoom_fov_deg)
        width = 32 * max(1, round(2.0 * f * math.tan(hfov / 2.0) / 32.0))
        height = 32 * max(1, round(2.0 * f * math.tan(vfov / 2.0) / 32.0))
        fov = 2.0 * math.atan(width / 2.0 / f)
        pitch = math.radians(self.zoom_pitch_deg)
        b = np.asarray(boxes, dtype=np.float64).reshape(-1, 4)
        out: list[PerspectiveView] = []
        for az in bearings:
            u = float(angles_to_pixel(az, 0.0, pano_w, 1.0)[0])
            if len(b) and np.any((u - b[:, 0]) % pano_w <= b[:, 2] - b[:, 0]):
                continue
            centre = round(u) % pano_w  # a whole column: the yaw-0 zoom view's look-up table, shifted
            yaw = float(pixel_to_angles(centre, 0.0, pano_w, 1.0)[0])
            if any(abs((yaw - v.yaw + math.pi) % (2.0 * math.pi) - math.pi) < fov / 4.0 for v in out):
                continue
            out.append(PerspectiveView(yaw, pitch, fov, width, height, name=f"z{centre}"))
        return out

    def _drop_cut(
        self, chosen: list[PerspectiveView], per_view: list[ViewDetections]
    ) -> list[ViewDetections]:
        """Without the boxes that touch a view's left or right border where no chosen view continues it: the
        person is cut there, and the view that would see them whole did not run."""
        out = []
        for i, (v, det) in enumerate(zip(chosen, per_view, strict=True)):
            others = [o for j, o in enumerate(chosen) if j != i]
            keep = np.ones(len(det), bool)
            for side, az in ((0, v.yaw + v.fov / 2.0 + 1e-3), (1, v.yaw - v.fov / 2.0 - 1e-3)):
                if any(abs((az - o.yaw + math.pi) % (2.0 * math.pi) - math.pi) < o.fov / 2.0 for o in others):
                    continue
                edge = det.boxes[:, 0] if side == 0 else v.width - det.boxes[:, 2]
                keep &= edge >= self.merge.border_px
            kp = None if det.keypoints is None else det.keypoints[keep]
            out.append(det if keep.all() else ViewDetections(det.boxes[keep], det.scores[keep], kp))
        return out

    def detect_views(self, images: list[NDArray[np.uint8]]) -> list[ViewDetections]:
        """``detect_view`` of every image, ``workers`` at a time, in order (a single one on the pool's
        threads too: a network run on yet another thread keeps memory of its own, ~40 MB more at peak)."""
        if self._pool is None or not images:
            return [self.detect_view(img) for img in images]
        return list(self._pool.map(self.detect_view, images))

    def detect(
        self,
        pano: NDArray[np.uint8],
        *,
        columns: NDArray[np.bool_] | None = None,
        zoom: Sequence[float] = (),
    ) -> ImageDetections:
        """People in an equirectangular BGR uint8 panorama ``(H, W, 3)``.

        Args:
            pano: the panorama.
            columns: ``(W,)`` mask of the panorama columns to look at: narrow windows on them
                (:meth:`windows_for`), else the sweep views that see one of them (:meth:`views_seeing`);
                a box cut by a view's border is dropped where no other view that ran continues it. None:
                every view of the sweep.
            zoom: azimuths (rad, panorama convention) where someone far away may stand: where the views
                found nobody there, a closer look (:meth:`zoom_views`) runs too.
        """
        w, h = check_pano(pano)
        if columns is not None and len(columns) != w:
            raise ValueError(f"columns: need one flag per panorama column ({w}), got {len(columns)}")
        if columns is None:
            views = self.views
        else:
            windows = self.windows_for(columns)
            views = [self.views[i] for i in self.views_seeing(columns)] if windows is None else windows
        per_view = self.detect_views(self.render_views(pano, views))
        closer = self.zoom_views(zoom, views_to_pano(views, per_view, w, h)[0], w) if len(zoom) else []
        if closer:
            per_view += self.detect_views(self.render_views(pano, closer))
            views = [*views, *closer]
        with self._count_lock:
            self.views_run += len(views)
            self.view_columns_run += sum(v.width for v in views)
        if views is not self.views:
            per_view = self._drop_cut(views, per_view)
        b, s, k, m, vi = views_to_pano(views, per_view, w, h)
        return merge_on_sphere(b, s, k, m, vi, w, h, params=self.merge)
