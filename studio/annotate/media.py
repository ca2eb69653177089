"""Panoramas and laser scans of a run's frames, read lazily from the recording the run was labeled from.

A run directory does not hold the sensor data. :class:`RunMedia` opens the recording named in
``RUN/run.json`` and, for one frame, reads only a short time window around the frame's ``stamp_ns``
(``Recording.messages(start_ns=, stop_ns=)``), never the whole recording:

* the panorama is the camera image whose header stamp is the frame stamp (plus the rig's camera latency);
  it is served as a JPEG at most :data:`MAX_WIDTH` px wide (the original size is reported separately so
  boxes keep their pixel coordinates); exported frames (``RUN/frames/NNNNNN.jpg``) are used when present;
* the scan of each laser is the one nearest the frame stamp within the rig's ``max_dt_s``; its valid
  points are put in the base frame with the rig's laser pose (not motion-compensated: the scan is at most
  ``max_dt_s`` away from the frame) and, with a camera, projected into the panorama (``u, v`` in pixels of
  the *original* image).

Results are cached in memory (LRU) and, for panoramas, on disk under ``RUN/annotations/cache/``;
:meth:`RunMedia.prefetch` warms the neighbours of a frame in a background thread.
"""

from __future__ import annotations

import contextlib
import json
import threading
from collections import OrderedDict
from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from studio.atomic import atomic_write_bytes
from studio.errors import StudioError

__all__ = ["MAX_WIDTH", "FrameScan", "MediaError", "RunMedia", "resolve_run_path"]

MAX_WIDTH = 1920  # px: panoramas wider than this are downscaled for the page
_SEEK_BEFORE_NS = 500_000_000  # log time may lead or lag the header stamp: read this window around it
_SEEK_AFTER_NS = 1_500_000_000


class MediaError(StudioError):
    """The recording of a run cannot be found or read, or a frame has no such sensor data."""


@dataclass(frozen=True)
class FrameScan:
    """The laser points of one frame.

    Attributes:
        xy: float (N, 2), metres, valid beam end points in the base frame.
        uv: float (N, 2), px in the original panorama (NaN where not projectable), or None without a camera.
        topics: per point, the index into ``RunMedia.laser_topics`` of the laser it came from, int (N,).
    """

    xy: np.ndarray
    uv: np.ndarray | None
    topics: np.ndarray

    def to_json(self, *, decimals: int = 3) -> dict[str, Any]:
        """``{"xy": [[x, y], ...], "uv": [[u, v], ...] | None, "laser": [k, ...]}`` (rounded)."""
        out: dict[str, Any] = {
            "xy": np.round(self.xy, decimals).tolist(),
            "laser": self.topics.astype(int).tolist(),
            "uv": None,
        }
        if self.uv is not None:
            uv = np.round(self.uv, 1)
            out["uv"] = [None if not np.all(np.isfinite(r)) else r.tolist() for r in uv]
        return out


def resolve_run_path(run_dir: Path, value: str | None) -> Path | None:
    """Find a file named in ``run.json`` (absolute, or relative to the labeling's working directory).

    Tries the path as written, then relative to the run directory and to its parent (a run made with
    ``studio label sim/recording.mcap --out run`` names ``sim/recording.mcap``). None when not found.
    """
    if not value:
        return None
    p = Path(value)
    cands = [p] if p.is_absolute() else [p, run_dir / p, run_dir.parent / p, Path.cwd() / p]
    for c in cands:
        if c.exists():
            return c.resolve()
    return None


class _Lru:
    """A small thread-safe LRU cache."""

    def __init__(self, size: int) -> None:
        self.size = size
        self.data: OrderedDict[Any, Any] = OrderedDict()
        self.lock = threading.Lock()

    def get(self, key: Any) -> Any:
        with self.lock:
            if key in self.data:
                self.data.move_to_end(key)
                return self.data[key]
        return None

    def put(self, key: Any, value: Any) -> None:
        with self.lock:
            self.data[key] = value
            self.data.move_to_end(key)
            while len(self.data) > self.size:
                self.data.popitem(last=False)


class RunMedia:
    """Sensor data of a run's frames (see the module doc).

    Args:
        run_dir: the run directory (with ``run.json``).
        cache_dir: where encoded panoramas are kept on disk (None: memory only).
        max_width: largest width of a served panorama, px.
        cache_frames: frames kept in memory.

    Attributes:
        has_camera: the rig has a camera (panoramas exist).
        image_size: ``(W, H)`` px of the original panoramas, or None.
        laser_topics: the rig's laser topics.
        problem: why sensor data is unavailable (recording or rig not found), else None.
    """

    def __init__(
        self,
        run_dir: str | Path,
        *,
        cache_dir: str | Path | None = None,
        max_width: int = MAX_WIDTH,
        cache_frames: int = 256,
    ) -> None:
        self.run_dir = Path(run_dir)
        self.cache_dir = None if cache_dir is None else Path(cache_dir)
        self.max_width = int(max_width)
        self._jpegs = _Lru(cache_frames)
        self._scans = _Lru(cache_frames)
        self._io_lock = threading.Lock()
        self._pool = ThreadPoolExecutor(max_workers=1, thread_name_prefix="studio-media")
        self._pending: set[tuple[str, int]] = set()
        self._rec: Any = None
        self._rig: Any = None
        self.problem: str | None = None
        self.has_camera = False
        self.image_size: tuple[int, int] | None = None
        self.laser_topics: list[str] = []
        self.recording_path: Path | None = None
        self.rig_path: Path | None = None
        self._load_run_json()

    # ------------------------------------------------------------------ setup
    def _load_run_json(self) -> None:
        try:
            info = json.loads((self.run_dir / "run.json").read_text(encoding="utf-8"))
        except (OSError, ValueError) as exc:
            self.problem = f"run.json unreadable ({exc})"
            info = {}
        size = info.get("image_size") if isinstance(info, dict) else None
        if isinstance(size, list | tuple) and len(size) == 2:
            self.image_size = (int(size[0]), int(size[1]))
        if not isinstance(info, dict):
            return
        self.recording_path = resolve_run_path(self.run_dir, info.get("recording"))
        self.rig_path = resolve_run_path(self.run_dir, info.get("rig"))
        if self.rig_path is None:
            self.problem = self.problem or f"rig file {info.get('rig')!r} of run.json not found"
            self.has_camera = self.image_size is not None and self._exported_frames()
            return
        from studio.io import load_rig

        try:
            self._rig = load_rig(self.rig_path)
        except StudioError as exc:
            self.problem = str(exc)
            return
        self.has_camera = self._rig.camera is not None
        self.laser_topics = [x.topic for x in self._rig.lasers]
        if self.recording_path is None:
            self.problem = f"recording {info.get('recording')!r} of run.json not found"

    def _exported_frames(self) -> bool:
        return (self.run_dir / "frames").is_dir()

    def _recording(self) -> Any:
        """The open recording (opened on first use; sensor poses resolved once). Call under the io lock."""
        if self._rec is None:
            if self.recording_path is None or self._rig is None:
                raise MediaError(f"no sensor data for this run: {self.problem}")
            from studio.io import open_recording, resolve_sensor_poses

            rec = open_recording(self.recording_path)
            self._rig = resolve_sensor_poses(rec, self._rig)
            self._rec = rec
        return self._rec

    def close(self) -> None:
        """Stop the prefetcher and close the recording."""
        self._pool.shutdown(wait=False, cancel_futures=True)
        with self._io_lock:
            if self._rec is not None:
                self._rec.close()
                self._rec = None

    # ------------------------------------------------------------------ panoramas
    def display_size(self) -> tuple[int, int] | None:
        """``(w, h)`` px of the served panorama JPEG, or None without a camera."""
        if not self.has_camera or self.image_size is None:
            return None
        w, h = self.image_size
        if w <= self.max_width:
            return (w, h)
        return (self.max_width, round(h * self.max_width / w))

    def panorama_jpeg(self, frame: int, stamp_ns: int) -> bytes:
        """The frame's panorama as JPEG bytes (downscaled to :attr:`max_width`).

        Raises:
            MediaError: no camera, recording missing, or no image with that stamp.
        """
        key = (int(frame), int(stamp_ns))
        hit = self._jpegs.get(key)
        if hit is not None:
            return bytes(hit)
        disk = self._disk_path(frame, stamp_ns)
        if disk is not None and disk.is_file():
            data = disk.read_bytes()
            self._jpegs.put(key, data)
            return data
        data = self._read_panorama(frame, stamp_ns)
        self._jpegs.put(key, data)
        if disk is not None:
            with contextlib.suppress(OSError):  # the disk cache is optional
                atomic_write_bytes(disk, data, fsync=False)
        return data

    def _disk_path(self, frame: int, stamp_ns: int) -> Path | None:
        if self.cache_dir is None:
            return None
        return self.cache_dir / f"{int(frame):06d}_{int(stamp_ns)}_{self.max_width}.jpg"

    def _read_panorama(self, frame: int, stamp_ns: int) -> bytes:
        if not self.has_camera:
            raise MediaError("this run has no camera (laser-only rig): no panorama")
        exported = self.run_dir / "frames" / f"{int(frame):06d}.jpg"
        if exported.is_file():
            return self._encode(exported.read_bytes(), None)
        from studio.io.decode import image_format, stamp_ns_of

        with self._io_lock:
            rec = self._recording()
            rig = self._rig
            topic = rec.resolve_topic(rig.camera.topic)
            want = int(stamp_ns) + rig.sync.camera_latency_ns
            best: tuple[int, Any] | None = None
            for raw in rec.messages([topic], start_ns=want - _SEEK_BEFORE_NS, stop_ns=want + _SEEK_AFTER_NS):
                msg = rec.decode(raw)
                dt = abs(stamp_ns_of(msg, raw.log_ns) - want)
                if best is None or dt < best[0]:
                    best = (dt, msg)
                if dt == 0:
                    break
        if best is None or best[0] > max(rig.sync.max_dt_ns, 1_000_000):
            raise MediaError(f"frame {frame}: no camera image at stamp {stamp_ns} in the recording")
        msg = best[1]
        if hasattr(msg, "format") and not hasattr(msg, "width"):
            data = bytes(msg.data)
            if image_format(data) == "jpeg":
                return self._encode(data, None)
        from studio.io import decode_panorama

        pano = decode_panorama(msg, want)
        return self._encode(None, pano.image)

    def _encode(self, jpeg: bytes | None, image: np.ndarray | None) -> bytes:
        """JPEG bytes at most ``max_width`` wide (``jpeg`` passed through when already small enough)."""
        import cv2

        if jpeg is not None and self.image_size is not None and self.image_size[0] <= self.max_width:
            return jpeg
        if image is None:
            assert jpeg is not None
            image = cv2.imdecode(np.frombuffer(jpeg, dtype=np.uint8), cv2.IMREAD_COLOR)
            if image is None:
                raise MediaError("a panorama does not decode")
        if self.image_size is None:
            self.image_size = (int(image.shape[1]), int(image.shape[0]))
        h, w = image.shape[:2]
        if w > self.max_width:
            image = cv2.resize(
                image, (self.max_width, round(h * self.max_width / w)), interpolation=cv2.INTER_AREA
            )
        ok, buf = cv2.imencode(".jpg", image, [cv2.IMWRITE_JPEG_QUALITY, 85])
        if not ok:
            raise MediaError("cannot encode a panorama as JPEG")
        return bytes(buf.tobytes())

    # ------------------------------------------------------------------ scans
    def scan(self, frame: int, stamp_ns: int) -> FrameScan:
        """The frame's laser points in the base frame (and in the panorama).

        Raises:
            MediaError: the recording or rig is missing.
        """
        key = (int(frame), int(stamp_ns))
        hit = self._scans.get(key)
        if hit is not None:
            return hit
        out = self._read_scan(int(stamp_ns))
        self._scans.put(key, out)
        return out

    def _read_scan(self, stamp_ns: int) -> FrameScan:
        from studio.io import decode_scan
        from studio.io.errors import RecordingError

        with self._io_lock:
            rec = self._recording()
            rig = self._rig
            max_dt = max(rig.sync.max_dt_ns, 1_000_000)
            topics = [rec.resolve_topic(t) for t in self.laser_topics]
            clouds = {t: x.cloud for t, x in zip(topics, rig.lasers, strict=True)}
            best: dict[str, tuple[int, Any]] = {}
            for raw in rec.messages(
                topics,
                start_ns=stamp_ns - max_dt - _SEEK_BEFORE_NS,
                stop_ns=stamp_ns + max_dt + _SEEK_AFTER_NS,
            ):
                try:
                    sc = decode_scan(rec.decode(raw), raw.log_ns, cloud=clouds.get(raw.topic))
                except RecordingError:
                    continue
                dt = abs(sc.stamp_ns - stamp_ns)
                if dt <= max_dt and (raw.topic not in best or dt < best[raw.topic][0]):
                    best[raw.topic] = (dt, sc)
        xy_parts: list[np.ndarray] = []
        idx_parts: list[np.ndarray] = []
        pts3: list[np.ndarray] = []
        for k, (cfg, topic) in enumerate(zip(rig.lasers, topics, strict=True)):
            if topic not in best or cfg.pose is None:
                continue
            sc = best[topic][1]
            local = sc.points()[sc.valid()]
            p3 = np.zeros((local.shape[0], 3))
            p3[:, :2] = local
            pb = cfg.pose.apply(p3)
            pts3.append(pb)
            xy_parts.append(pb[:, :2])
            idx_parts.append(np.full(local.shape[0], k, dtype=np.int64))
        xy = np.concatenate(xy_parts) if xy_parts else np.zeros((0, 2))
        idx = np.concatenate(idx_parts) if idx_parts else np.zeros(0, dtype=np.int64)
        uv = None
        if rig.camera is not None and rig.camera.pose is not None and self.image_size is not None:
            from studio.geometry import EquirectCamera

            cam = EquirectCamera(*self.image_size[:2], rig.camera.pose, rig.camera.lens_offset)
            p = np.concatenate(pts3) if pts3 else np.zeros((0, 3))
            uv, _ = cam.project(p) if len(p) else (np.zeros((0, 2)), None)
        return FrameScan(xy=xy, uv=uv, topics=idx)

    # ------------------------------------------------------------------ prefetch
    def prefetch(self, frames: list[tuple[int, int]]) -> None:
        """Warm the caches for ``(frame, stamp_ns)`` pairs in the background (errors are ignored)."""
        for frame, stamp in frames:
            if self.has_camera:
                self._submit("pano", frame, stamp, self.panorama_jpeg)
            if self.laser_topics:
                self._submit("scan", frame, stamp, self.scan)

    def _submit(self, kind: str, frame: int, stamp: int, fn: Callable[[int, int], Any]) -> None:
        key = (kind, frame)
        cache = self._jpegs if kind == "pano" else self._scans
        if key in self._pending or cache.get((frame, stamp)) is not None:
            return
        self._pending.add(key)

        def job() -> None:
            try:
                fn(frame, stamp)
            except Exception:
                pass
            finally:
                self._pending.discard(key)

        try:
            self._pool.submit(job)
        except RuntimeError:  # pool shut down
            self._pending.discard(key)
