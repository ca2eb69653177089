"""The data half of :mod:`studio.calibrate.people`: image and laser people gathered from a recording.

The image detector gives each person's camera-frame azimuth (and the elevation of the lowest seen ankle);
the laser detector gives people's positions in the odometry frame at every scan stamp, with those on
static structure dropped and single legs left out (a lone leg is up to ~0.3 m from the body and swings
with the gait, so its bearing leads or lags the person's: on a simulated 14 s recording single legs
pulled the latency 0.034 s off, leg pairs and blobs alone 0.009 s). :func:`collect_people` runs both over
a recording (or reads a ``studio label`` run's ``image_detections.jsonl``) into a :class:`PeopleData` for
:func:`studio.calibrate.people.calibrate_people`.
"""

from __future__ import annotations

import dataclasses
import json
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from studio.calibrate.errors import CalibrationError
from studio.detect.laser.base import KIND_LEG
from studio.geometry.equirect import not_equirect

__all__ = [
    "ImageObservation",
    "LaserPeople",
    "PeopleCalibrationError",
    "PeopleData",
    "UnobservableError",
    "collect_people",
    "image_observation",
    "load_image_detections",
]

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]
_ANKLES, _LEGS = (15, 16), (11, 12, 13, 14, 15, 16)  # COCO keypoints: ankles; hips, knees, ankles
_KPT_MIN = 0.3  # keypoint score that counts as seen (as studio.fuse)
_STATIC = 0.7  # static-map occupancy marking structure (as studio label)


class PeopleCalibrationError(CalibrationError):
    """The recording or rig cannot be calibrated from people (no camera, no laser, too few people)."""


class UnobservableError(PeopleCalibrationError):
    """The time offset is not observable in this recording (nothing moves across the view)."""


@dataclass(frozen=True)
class ImageObservation:
    """The N people of one image: header ``stamp_ns`` (ns), camera-frame azimuth ``az`` ``(N,)`` rad (left
    positive) and ankle-row elevation ``el_foot`` ``(N,)`` rad (NaN where no ankle was seen)."""

    stamp_ns: int
    az: FloatArray
    el_foot: FloatArray


@dataclass(frozen=True)
class LaserPeople:
    """Laser people of a whole recording in the odometry frame, K frames, P detections in all.

    Attributes:
        stamp_ns: ``(K,)`` int64 scan stamps, increasing.
        robot: ``(K, 3)`` robot pose ``x, y`` (m), ``yaw`` (rad, unwrapped) in the odometry frame.
        start, count: ``(K,)`` each frame's first index into ``xy`` and its number of people.
        xy: ``(P, 2)`` positions, m.
        xy_next: ``(P, 2)`` the same person in the next frame (mutual nearest within 0.3 m, else ``xy``).
        velocity: ``(P, 2)`` m/s over ≥ 0.5 s (mutual nearest within 0.8 m), NaN when not found again.
    """

    stamp_ns: IntArray
    robot: FloatArray
    start: IntArray
    count: IntArray
    xy: FloatArray
    xy_next: FloatArray
    velocity: FloatArray

    @staticmethod
    def from_frames(stamp_ns: IntArray, robot: FloatArray, frames: Sequence[FloatArray]) -> LaserPeople:
        """Build from per-frame ``(n_k, 2)`` positions (odometry frame, m) and ``(K, 3)`` robot poses."""
        stamp_ns = np.asarray(stamp_ns, dtype=np.int64)
        count = np.array([len(x) for x in frames], dtype=np.int64)
        start = (np.cumsum(count) - count).astype(np.int64)
        xy = np.concatenate(frames).reshape(-1, 2) if len(frames) else np.zeros((0, 2))
        nxt, vel = xy.copy(), np.full(xy.shape, np.nan)
        for k in range(len(frames) - 1):
            later = min(int(np.searchsorted(stamp_ns, stamp_ns[k] + 500_000_000)), len(frames) - 1)
            for k2, gate, out in ((k + 1, 0.3, nxt), (later, 0.8, vel)):
                a, b = frames[k], frames[k2]
                if not (len(a) and len(b)) or k2 == k:
                    continue
                d = np.hypot(*(a[:, None] - b[None]).transpose(2, 0, 1))
                j = d.argmin(1)
                ok = (d[np.arange(len(a)), j] < gate) & (d[:, j].argmin(0) == np.arange(len(a)))
                val = b[j] if out is nxt else (b[j] - a) / ((stamp_ns[k2] - stamp_ns[k]) * 1e-9)
                out[start[k] : start[k] + len(a)][ok] = val[ok]
        rob = np.array(robot, dtype=np.float64).reshape(-1, 3)
        rob[:, 2] = np.unwrap(rob[:, 2]) if len(rob) else rob[:, 2]
        return LaserPeople(stamp_ns, rob, start, count, xy, nxt, vel)


@dataclass(frozen=True)
class PeopleData:
    """What :func:`collect_people` gathered: images, laser people, panorama size (W, H) px, resolved rig."""

    images: tuple[ImageObservation, ...]
    laser: LaserPeople
    image_size: tuple[int, int]
    rig: Any


def _wrap(a: Any) -> FloatArray:
    return np.asarray(np.mod(np.asarray(a) + np.pi, 2 * np.pi) - np.pi, dtype=np.float64)


# ------------------------------------------------------------------------------------------ collection
def image_observation(stamp_ns: int, dets: Any) -> ImageObservation:
    """Azimuths and ankle rows (camera frame) of an :class:`~studio.detect.image.ImageDetections`.

    The azimuth is the circular mean column of the seen hip/knee/ankle keypoints (the lasers see legs),
    else the box centre; the ankle row is the lowest seen ankle.
    """
    W, H = float(dets.width), float(dets.height)
    b = np.asarray(dets.boxes, dtype=np.float64).reshape(-1, 4)
    col, foot = 0.5 * (b[:, 0] + b[:, 2]), np.full(len(b), np.nan)
    if dets.keypoints is not None and len(b):
        k = np.asarray(dets.keypoints, dtype=np.float64)
        seen = k[:, _LEGS, 2] >= _KPT_MIN
        ang = 2 * np.pi * k[:, _LEGS, 0] / W
        s, c = np.where(seen, np.sin(ang), 0).sum(1), np.where(seen, np.cos(ang), 0).sum(1)
        col = np.where(seen.any(1), np.mod(np.arctan2(s, c), 2 * np.pi) * W / (2 * np.pi), col)
        v = np.where(k[:, _ANKLES, 2] >= _KPT_MIN, k[:, _ANKLES, 1], -np.inf).max(1)
        foot = np.where(np.isfinite(v), v, np.nan)
    return ImageObservation(
        int(stamp_ns), _wrap((0.5 - np.mod(col, W) / W) * 2 * np.pi), (0.5 - foot / H) * np.pi
    )


def load_image_detections(path: str | Path) -> tuple[list[ImageObservation], tuple[int, int]]:
    """Read a run's ``image_detections.jsonl``: boxes only, so azimuths from box centres and no ankle rows.

    Returns:
        The observations and the panorama size (W, H) px.

    Raises:
        PeopleCalibrationError: the file is missing, does not parse, or holds no images.
    """
    from studio.detect.image.base import ImageDetections

    p = Path(path)
    out, size = [], (0, 0)
    try:
        lines = p.read_text(encoding="utf-8").splitlines()
    except OSError as exc:
        raise PeopleCalibrationError(f"cannot read {p}: {exc.strerror or exc}") from None
    for n, line in enumerate(lines, 1):
        if not line.strip():
            continue
        try:
            d = json.loads(line)
            boxes = np.asarray([r[:4] for r in d["boxes"]], dtype=np.float64).reshape(-1, 4)
            size = (int(d["width"]), int(d["height"]))
            dets = ImageDetections(boxes, np.ones(len(boxes)), None, *size)
            out.append(image_observation(int(d["stamp_ns"]), dets))
        except (ValueError, KeyError, TypeError, IndexError) as exc:
            raise PeopleCalibrationError(f"{p}:{n}: not an image detection line ({exc})") from None
    if not out:
        raise PeopleCalibrationError(f"{p}: no image detections")
    return out, size


def _images(
    rec: Any, topic: str, detector: Any, period_ns: int, progress: Callable[[int, int], None] | None
) -> tuple[list[ImageObservation], tuple[int, int]]:
    from studio.io.decode import decode_panorama, stamp_ns_of
    from studio.io.errors import RecordingError

    total, last = rec.topics[topic].count, None
    out, size = [], (0, 0)
    for done, raw in enumerate(rec.messages([topic]), 1):
        try:
            msg = rec.decode(raw)
            stamp = stamp_ns_of(msg, raw.log_ns)
            if last is not None and stamp - last < period_ns:
                continue
            pano = decode_panorama(msg, raw.log_ns)
        except RecordingError:
            continue
        if (wrong := not_equirect(pano.width, pano.height)) is not None:
            raise PeopleCalibrationError(f"{rec.path}: the camera's images are {wrong}")
        last, size = stamp, (pano.width, pano.height)
        out.append(image_observation(stamp, detector.detect(pano.image)))
        if progress is not None:
            progress(done, total)
    return out, size


def _laser(rec: Any, rig: Any, detector: Any, period_ns: int) -> LaserPeople:
    """Laser people of every (``period_ns``-spaced) laser frame; those on static structure and single legs
    dropped (see the module docstring)."""
    from studio.detect.laser.static_map import StaticMap
    from studio.io import iter_frames

    stamps, robot, people, segments = [], [], [], []

    def scans() -> Iterator[tuple[FloatArray, FloatArray]]:  # feeds the static map, detects on the way
        last = None
        for fr in iter_frames(rec, dataclasses.replace(rig, camera=None)):
            if last is not None and fr.stamp_ns - last < period_ns:
                continue
            last, rp = fr.stamp_ns, fr.robot_pose
            parts, odom = [], []
            for sib in fr.scans:
                pose, pts, valid = sib.upright()
                m = pose.to_pose2()
                base = m.apply(np.nan_to_num(pts))
                base[~valid] = np.nan
                parts.append((base, valid, m.apply(np.zeros(2))))
                odom.append(rp.apply(base))
                yield odom[-1], rp.apply(m.apply(np.zeros(2)))
            det = detector.detect_scans(parts) if parts else None
            if det is not None:
                det = det.select(det.kind != KIND_LEG)
            pts = np.concatenate(odom) if odom else np.zeros((0, 2))
            stamps.append(fr.stamp_ns)
            robot.append((rp.x, rp.y, rp.yaw))
            people.append(rp.apply(det.xy) if det is not None and len(det) else np.zeros((0, 2)))
            segs = det.segments if det is not None and det.segments is not None else ()
            segments.append([pts[s] for s in segs])

    smap = StaticMap.build(scans())
    kept = []
    for xy, segs in zip(people, segments, strict=True):
        keep = np.ones(len(xy), bool)
        for i, s in enumerate(segs[: len(xy)]):
            s = s[np.all(np.isfinite(s), axis=1)]
            keep[i] = not len(s) or np.mean(smap.structure(s, occupied=_STATIC)) < _STATIC
        kept.append(xy[keep])
    return LaserPeople.from_frames(np.array(stamps, dtype=np.int64), np.array(robot), kept)


def collect_people(
    recording: str | Path,
    rig: Any,
    *,
    run_dir: str | Path | None = None,
    image_period_s: float = 0.2,
    laser_period_s: float = 0.0,
    image_detector: str = "movenet",
    laser_detector: str = "classical",
    progress: Callable[[int, int], None] | None = None,
) -> PeopleData:
    """Gather the image and laser people of a recording for :func:`calibrate_people`.

    Args:
        recording: the bag.
        rig: the rig (:class:`studio.io.rig.Rig`), with a camera and at least one laser.
        run_dir: a ``studio label`` run: its ``image_detections.jsonl`` replaces running the image
            detector (boxes only: no ankle rows, so roll and pitch are not refined).
        image_period_s: run the image detector at most this often (image header time), s.
        laser_period_s: use laser frames at most this often, s (0: every scan of the first laser).
        image_detector: image detector name or YOLO ``.onnx`` path.
        laser_detector: laser detector name.
        progress: called as ``progress(done, total)`` over the images.

    Raises:
        PeopleCalibrationError: the rig has no camera or no laser, the recording no images or laser frames.
        RecordingError, TfError: as :func:`studio.io.iter_frames`.
    """
    from studio.detect.laser import get_laser_detector
    from studio.io import open_recording, resolve_sensor_poses

    if rig.camera is None:
        raise PeopleCalibrationError(
            "the rig has no camera: nothing to calibrate (this aligns camera and lasers)"
        )
    if not rig.lasers:
        raise PeopleCalibrationError("the rig has no laser: people calibration needs camera and lasers")
    with open_recording(recording) as rec:
        topic = rec.resolve_topic(rig.camera.topic) if rec.has_topic(rig.camera.topic) else None
        if topic is None or not rec.topics[topic].count:
            raise PeopleCalibrationError(
                f"{recording}: no images on the camera topic {rig.camera.topic}: nothing to calibrate"
            )
        rig = resolve_sensor_poses(rec, rig)
        if run_dir is not None:
            images, size = load_image_detections(Path(run_dir) / "image_detections.jsonl")
        else:
            from studio.detect.image import get_image_detector

            det = get_image_detector(image_detector)
            images, size = _images(rec, topic, det, round(image_period_s * 1e9) - 1_000_000, progress)
        laser = _laser(rec, rig, get_laser_detector(laser_detector), round(laser_period_s * 1e9) - 1_000_000)
    if not images:
        raise PeopleCalibrationError(f"{recording}: no camera image could be read")
    if len(laser.stamp_ns) < 2:
        raise PeopleCalibrationError(f"{recording}: fewer than two laser frames could be built")
    return PeopleData(tuple(images), laser, size, rig)
