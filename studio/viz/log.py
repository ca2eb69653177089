"""Log a labeling run to a Rerun recording (``RUN/recording.rrd``).

:class:`RunLogger` hooks into ``studio label``: :meth:`RunLogger.on_frame` logs what exists only while a
frame is in memory (the panorama, image and laser detections, scans and their projections, cube faces);
:meth:`RunLogger.finish` logs whole series with ``send_columns`` after tracking (robot poses, fused people
with covariance, tracks and trails, ground truth, metrics, disagreement events). The entity tree and the
timelines are documented in :mod:`studio.viz.paths`.

It always logs to its own explicit :class:`rerun.RecordingStream` (application id ``studio``), never to
the global one, and the algorithms never log: they hand their results to this class.
"""

from __future__ import annotations

import time
from pathlib import Path
from typing import Any

import cv2
import numpy as np
import rerun as rr
from numpy.typing import NDArray

from studio.geometry import EquirectCamera, PerspectiveView, ViewRenderer, cube_faces
from studio.geometry.se import Pose3
from studio.viz import paths as ep
from studio.viz.colors import SOURCE_COLORS, range_colors
from studio.viz.draw import skeleton_strips, split_seam_boxes, vertical_strips

__all__ = ["RunLogger"]

FloatArray = NDArray[np.float64]

_PERSON_HEIGHT = 1.8  # m, height of the vertical markers drawn on the panorama
_LASER_COLORS = ((255, 210, 60), (60, 220, 255), (255, 120, 220), (150, 255, 120))


def _ns(stamp_ns: int) -> np.datetime64:
    return np.datetime64(int(stamp_ns), "ns")


def _run_name(rrd: Path) -> str:
    """The run directory's name (``studio label`` writes into ``.RUN.xxxx.tmp`` first, see studio.atomic)."""
    d = rrd.parent.name
    if d.startswith(".") and d.endswith(".tmp") and d.count(".") >= 3:
        d = d[1:].rsplit(".", 2)[0]
    return d or rrd.stem


def _segments(strips: list[FloatArray]) -> Any:
    """Two-point strips as one ``(S, 2, 2)`` array (rerun's fast path), or an empty list."""
    return np.asarray(strips, dtype=np.float32).reshape(-1, 2, 2) if strips else []


class RunLogger:
    """Writes a run's Rerun recording while ``studio label`` runs.

    Args:
        rrd_path: the ``.rrd`` file to write.
        rig: the loaded rig (:class:`studio.io.rig.Rig`); its sensors are logged as static data.
        faces_every: log the four side cube faces every this many frames (0: never); they cost ~10 KB each.
        face_size: cube face size, px.
        image_width: panoramas wider than this are logged downscaled to this width, px (None: full size).
            The panorama overlays (boxes, keypoints, projected scans, tracks) are drawn in the logged
            image's pixels. Keeps recordings small: 30 MB per minute at 10 Hz is 50 KB per frame, and a
            1920×960 camera JPEG is 250–500 KB.
        jpeg_quality: quality used when a panorama must be (re-)encoded.
        max_jpeg_bytes: a panorama that arrives as JPEG at the logged size is logged as is when its bytes
            are at most this, else re-encoded at ``jpeg_quality``.
        scan_step: log every this many beams of a scan in 3D (2 keeps ~14 beams on a leg at 2 m and halves
            the ~12 KB per 1081-beam scan and frame).
        pano_scan_step: draw every this many beams of a scan on the panorama.
        trail_s: length of the track trails, seconds.
        recording_name: shown in the viewer (default: the run directory's name).

    Attributes:
        seconds: time spent in :meth:`on_frame`, s (``finish`` is timed by the caller).
        rec: the recording stream.
    """

    def __init__(
        self,
        rrd_path: Path,
        *,
        rig: Any,
        faces_every: int = 10,
        face_size: int = 256,
        image_width: int | None = 960,
        jpeg_quality: int = 65,
        max_jpeg_bytes: int = 40_000,
        scan_step: int = 2,
        pano_scan_step: int = 3,
        trail_s: float = 5.0,
        recording_name: str | None = None,
    ) -> None:
        self.path = Path(rrd_path)
        self.rig = rig
        self.faces_every = int(faces_every)
        self.face_size = int(face_size)
        self.image_width = None if image_width is None else int(image_width)
        self.jpeg_quality = int(jpeg_quality)
        self.max_jpeg_bytes = int(max_jpeg_bytes)
        self.trail_s = float(trail_s)
        self.pano_scan_step = max(1, int(pano_scan_step))
        self.scan_step = max(1, int(scan_step))
        self.seconds = 0.0
        # batch rows for a few seconds: fewer, larger chunks (each chunk carries ~0.4 KB of metadata)
        batcher = rr.ChunkBatcherConfig(flush_tick=5.0, flush_num_bytes=8 * 2**20)
        self.rec = rr.RecordingStream(ep.APP_ID, batcher_config=batcher)
        self.rec.save(self.path)
        self.rec.set_log_time_enabled(False)
        self.rec.set_log_tick_enabled(False)
        self.rec.send_recording_name(recording_name or _run_name(self.path))
        self._renderer = ViewRenderer(max_entries=8)
        self._faces: list[PerspectiveView] = []
        self._camera: EquirectCamera | None = None
        self._laser_topics = [laser.topic for laser in rig.lasers]
        self._sensors_logged: set[str] = set()
        self._closed = False
        self._log_static()

    # ------------------------------------------------------------------ static data
    def _log_static(self) -> None:
        rec = self.rec
        rec.log(ep.WORLD, rr.ViewCoordinates.RIGHT_HAND_Z_UP, static=True)
        # the footprint: bounding box of the sensors, at least 0.5 × 0.4 m, around the base origin
        xy = [np.zeros(2)]
        for laser in self.rig.lasers:
            if laser.pose is not None:
                xy.append(laser.pose.t[:2])
        if self.rig.camera is not None and self.rig.camera.pose is not None:
            xy.append(self.rig.camera.pose.t[:2])
        pts = np.array(xy)
        lo = np.minimum(pts.min(axis=0) - 0.1, [-0.25, -0.2])
        hi = np.maximum(pts.max(axis=0) + 0.1, [0.25, 0.2])
        outline = np.array([[lo[0], lo[1]], [hi[0], lo[1]], [hi[0], hi[1]], [lo[0], hi[1]], [lo[0], lo[1]]])
        nose = np.array([[hi[0], 0.0], [hi[0] - 0.15, 0.1], [hi[0] - 0.15, -0.1], [hi[0], 0.0]])
        rec.log(
            f"{ep.ROBOT}/footprint",
            rr.LineStrips3D(
                [np.c_[outline, np.zeros(5)], np.c_[nose, np.zeros(4)]],
                colors=[(220, 220, 220)],
                radii=[0.01],
            ),
            static=True,
        )
        if self.rig.camera is not None and self.rig.camera.pose is not None:
            self._log_sensor("camera", self.rig.camera.pose)
        for laser in self.rig.lasers:
            if laser.pose is not None:
                self._log_sensor(ep.entity_name(laser.topic), laser.pose)
        for k, topic in enumerate(self._laser_topics):
            rec.log(
                f"{ep.ROBOT}/scan/{ep.entity_name(topic)}",
                rr.Points3D.from_fields(colors=[_LASER_COLORS[k % 4]], radii=[0.015]),
                static=True,
            )
        rec.log(
            f"{ep.ROBOT}/laser_people", rr.Points3D.from_fields(colors=[SOURCE_COLORS["laser"]]), static=True
        )

    def _log_sensor(self, name: str, pose: Pose3) -> None:
        if name in self._sensors_logged:
            return
        self._sensors_logged.add(name)
        self.rec.log(
            f"{ep.ROBOT}/sensors/{name}",
            rr.Transform3D(translation=pose.t, mat3x3=pose.R),
            rr.TransformAxes3D(axis_length=0.2),
            static=True,
        )

    # ------------------------------------------------------------------ per frame
    def on_frame(self, frame: Any, perception: Any) -> None:
        """Log one frame of pass one (``frame``: :class:`studio.io.Frame`; ``perception``: PerceptionFrame).

        Called while the frame's image is in memory; time spent here is added to :attr:`seconds`.
        """
        t0 = time.perf_counter()
        try:
            self._on_frame(frame, perception)
        finally:
            self.seconds += time.perf_counter() - t0

    def _on_frame(self, frame: Any, pf: Any) -> None:
        rec = self.rec
        rec.set_time(ep.TIMELINE_FRAME, sequence=int(pf.index))
        rec.set_time(ep.TIMELINE_TIME, timestamp=_ns(pf.stamp_ns))
        for sib in frame.scans:
            self._log_sensor(ep.entity_name(sib.topic), sib.sensor_pose)

        points = np.c_[pf.points, pf.points_z()].astype(np.float32)
        owner = pf.origin_of_point
        valid = np.isfinite(points[:, 0])
        scan_topics = [s.topic for s in frame.scans]
        per_topic: dict[str, NDArray[np.float32]] = {}
        for topic in self._laser_topics:
            k = scan_topics.index(topic) if topic in scan_topics else -1
            sel = valid & (owner == k) if k >= 0 else np.zeros(len(points), bool)
            per_topic[topic] = points[sel]
            rec.log(f"{ep.ROBOT}/scan/{ep.entity_name(topic)}", rr.Points3D(points[sel][:: self.scan_step]))

        laser = pf.laser
        if laser is not None and len(laser.xy):
            lz = np.asarray(pf.laser_z, dtype=np.float64).reshape(-1)
            lxyz = np.c_[laser.xy, lz if len(lz) == len(laser.xy) else np.zeros(len(laser.xy))]
            rec.log(f"{ep.ROBOT}/laser_people", rr.Points3D(lxyz, radii=np.clip(laser.radius, 0.08, 0.4)))
        else:
            lxyz = np.zeros((0, 3))
            rec.log(f"{ep.ROBOT}/laser_people", rr.Points3D(np.zeros((0, 3))))

        pano = frame.panorama
        if pano is None:
            return
        H0, W0 = pano.image.shape[:2]
        scale = 1.0
        if self.image_width is not None and self.image_width < W0:
            scale = self.image_width / W0
        W, H = round(W0 * scale), round(H0 * scale)
        cam = self._camera_for(W, H)
        rec.log(ep.PANORAMA, rr.EncodedImage(contents=self._jpeg(pano, (W, H)), media_type="image/jpeg"))

        det = pf.image
        boxes = (
            np.zeros((0, 4))
            if det is None
            else np.asarray(det.boxes, dtype=np.float64).reshape(-1, 4) * scale
        )
        scores = np.zeros(len(boxes)) if det is None else np.asarray(det.scores, dtype=np.float64).reshape(-1)
        split, src = split_seam_boxes(boxes, W)
        rec.log(
            f"{ep.PANORAMA}/boxes",
            rr.Boxes2D(
                array=split, array_format=rr.Box2DFormat.XYXY, labels=[f"{scores[i]:.2f}" for i in src]
            ),
        )
        kp = None if det is None else getattr(det, "keypoints", None)
        if kp is not None and len(kp):
            kpa: FloatArray = np.asarray(kp, dtype=np.float64).copy()
            kpa[..., :2] *= scale
            ok = kpa[..., 2] >= 0.3
            uv = kpa[ok][:, :2].copy()
            uv[:, 0] = np.mod(uv[:, 0], W)
            strips, _ = skeleton_strips(kpa, W)
        else:
            uv, strips = np.zeros((0, 2)), []
        rec.log(f"{ep.PANORAMA}/keypoints", rr.Points2D(uv))
        rec.log(f"{ep.PANORAMA}/skeletons", rr.LineStrips2D(_segments(strips)))

        for topic, pts in per_topic.items():
            puv, depth = cam.project(pts[:: self.pano_scan_step].astype(np.float64))
            rec.log(
                f"{ep.PANORAMA}/scan/{ep.entity_name(topic)}", rr.Points2D(puv, colors=range_colors(depth))
            )
        lo, _ = cam.project(np.c_[lxyz[:, :2], np.zeros(len(lxyz))])
        hi, _ = cam.project(np.c_[lxyz[:, :2], np.full(len(lxyz), _PERSON_HEIGHT)])
        vs, _ = vertical_strips(lo, hi, W)
        rec.log(f"{ep.PANORAMA}/laser_people", rr.LineStrips2D(_segments(vs)))

        if self.faces_every > 0 and pf.index % self.faces_every == 0:
            self._log_faces(
                pano.image, cam, np.concatenate([*per_topic.values(), np.zeros((0, 3), np.float32)])
            )

    def _camera_for(self, W: int, H: int) -> EquirectCamera:
        if self._camera is None or (self._camera.width, self._camera.height) != (W, H):
            cam_cfg = self.rig.camera
            pose = cam_cfg.pose if cam_cfg is not None and cam_cfg.pose is not None else Pose3.identity()
            self._camera = EquirectCamera(W, H, pose, cam_cfg.lens_offset if cam_cfg is not None else 0.0)
            all_faces = cube_faces(self.face_size)
            self._faces = [all_faces[n] for n in ep.FACE_NAMES]
            self._log_panorama_style(W)
        return self._camera

    def _log_panorama_style(self, W: int) -> None:
        """Static colours and sizes of the panorama overlays (line widths scale with the image width)."""
        rec = self.rec
        s = max(W / 1920.0, 0.25)
        for topic in self._laser_topics:
            rec.log(
                f"{ep.PANORAMA}/scan/{ep.entity_name(topic)}",
                rr.Points2D.from_fields(radii=[2.0 * s]),
                static=True,
            )
        rec.log(
            f"{ep.PANORAMA}/laser_people",
            rr.LineStrips2D.from_fields(colors=[SOURCE_COLORS["laser"]], radii=[2.0 * s]),
            static=True,
        )
        rec.log(
            f"{ep.PANORAMA}/boxes",
            rr.Boxes2D.from_fields(colors=[SOURCE_COLORS["image"]], radii=[1.5 * s], show_labels=True),
            static=True,
        )
        rec.log(
            f"{ep.PANORAMA}/keypoints",
            rr.Points2D.from_fields(colors=[(255, 255, 255)], radii=[3.0 * s]),
            static=True,
        )
        rec.log(
            f"{ep.PANORAMA}/skeletons",
            rr.LineStrips2D.from_fields(colors=[(120, 200, 255)], radii=[1.2 * s]),
            static=True,
        )
        for name in ep.FACE_NAMES:
            rec.log(
                f"{ep.FACES}/{name}/scan",
                rr.Points2D.from_fields(radii=[1.5 * self.face_size / 256]),
                static=True,
            )

    def _jpeg(self, pano: Any, size: tuple[int, int]) -> bytes:
        img = pano.image
        if (img.shape[1], img.shape[0]) != size:
            img = cv2.resize(img, size, interpolation=cv2.INTER_AREA)
        else:
            enc = getattr(pano, "encoded", None)
            if (
                enc is not None
                and getattr(pano, "encoding", "") == "jpeg"
                and len(enc) <= self.max_jpeg_bytes
            ):
                return bytes(enc)
        ok, buf = cv2.imencode(".jpg", img, [cv2.IMWRITE_JPEG_QUALITY, self.jpeg_quality])
        if not ok:  # pragma: no cover - OpenCV encodes any uint8 BGR image
            raise RuntimeError("JPEG encoding failed")
        return buf.tobytes()

    def _log_faces(self, image: NDArray[np.uint8], cam: EquirectCamera, pts: NDArray[np.float32]) -> None:
        imgs = self._renderer.render_many(image, self._faces)
        p_cam = cam.pose.inverse().apply(pts.astype(np.float64)) if len(pts) else np.zeros((0, 3))
        depth = np.linalg.norm(p_cam, axis=1)
        for face, img in zip(self._faces, imgs, strict=True):
            ok, buf = cv2.imencode(".jpg", img, [cv2.IMWRITE_JPEG_QUALITY, self.jpeg_quality])
            path = f"{ep.FACES}/{face.name}"
            if ok:
                self.rec.log(path, rr.EncodedImage(contents=buf.tobytes(), media_type="image/jpeg"))
            uv = face.pixel_of_rays(p_cam) if len(p_cam) else np.zeros((0, 2))
            inside = np.all(np.isfinite(uv), axis=1) & (uv[:, 0] >= 0) & (uv[:, 0] < face.width)
            inside &= (uv[:, 1] >= 0) & (uv[:, 1] < face.height)
            self.rec.log(f"{path}/scan", rr.Points2D(uv[inside], colors=range_colors(depth[inside])))

    # ------------------------------------------------------------------ after tracking
    def finish(self, result: Any, *, ground_truth: Path | None = None) -> None:
        """Log the whole-run series (see the module docstring), then flush and close the file.

        Args:
            result: the :class:`studio.pipeline.label.LabelRun`.
            ground_truth: a labels file (``.yaml`` / ``.jsonl``) to compare with, or None.

        Raises:
            LabelError: ``ground_truth`` is missing or malformed.
        """
        from studio.viz.series import log_run_series

        try:
            log_run_series(
                self.rec, result, ground_truth=ground_truth, trail_s=self.trail_s, pano_camera=self._camera
            )
        finally:
            self.close()

    def close(self) -> None:
        """Flush and finalise the ``.rrd`` (safe to call twice)."""
        if self._closed:
            return
        self._closed = True
        self.rec.flush()
        self.rec.disconnect()
