"""Pass one of ``studio label``: stream the recording once, detect people in images and scans.

Per frame it keeps only what later stages need: image detections with an appearance descriptor per box,
laser detections in the base frame and the frame's scan points. The image detector works on threads of its
own, on at most two frames at a time (memory stays flat in the number of images), while the main thread
reads, decodes, runs the laser detector on the next frames and adds their scans to the static-world map in
the odom frame. :mod:`studio.pipeline.label` runs the second pass.
"""

from __future__ import annotations

import time
from collections import deque
from collections.abc import Callable, Iterator
from concurrent.futures import Future, ThreadPoolExecutor
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from studio.detect.laser.base import LaserDetections, merge_detections
from studio.errors import StudioError
from studio.geometry.se import Pose2, Pose3
from studio.pipeline.base import LabelOptions
from studio.track.sight import ScanView, scan_view

__all__ = [
    "FarLooks",
    "NoLaserDetector",
    "PerceptionFrame",
    "QuietViews",
    "base_scans",
    "beam_clocks",
    "detect_again",
    "laser_in_base",
    "moving_on",
    "odom_scans",
    "off_people",
    "open_beams_in_base",
    "perceive",
    "point_times",
    "remembers_legs",
]

FloatArray = NDArray[np.float64]
_BODY_EVERY = 4  # the map of the robot's body takes every 4th frame's scans


class QuietViews:
    """Which panorama columns each image detection looks at (``LabelOptions.quiet_view_period_s``).

    A detection looks at the whole panorama when the last whole look is ``period_s`` old or more (its
    header time); otherwise only at the columns where an earlier detection found someone within
    ``recent_s`` before it, widened by ``margin_deg`` on each side (people move). Only detections
    ``lag`` or more places earlier count: the ones still running when this one starts may have finished
    or not, and the choice must not depend on that (the output is the same on every run).

    Args:
        period_s: the quiet part of the panorama is looked at this often, s.
        recent_s: a box this recent (relative to the new image) keeps its columns looked at, s.
        margin_deg: the columns of a box widened by this much on each side, degrees.
        lag: detections that may still be running when the next one starts, plus one (a detection
            ``lag`` places back that has not finished is an error: the choice would depend on timing).
    """

    def __init__(self, period_s: float, *, recent_s: float = 1.0, margin_deg: float = 10.0, lag: int = 3):
        self.period_ns = round(period_s * 1e9)
        self.recent_ns = round(recent_s * 1e9)
        self.margin_deg = float(margin_deg)
        self.lag = int(lag)
        self._stamps: list[int] = []  # header time of each detection started
        self._boxes: list[FloatArray] = []  # its boxes, once it finished (in the order started)
        self._last_whole: int | None = None
        self.whole = self.partial = 0

    def start(self, stamp_ns: int, width: int) -> NDArray[np.bool_] | None:
        """The columns the detection of the image at ``stamp_ns`` looks at (``(W,)`` mask; None: all)."""
        n = len(self._stamps)
        self._stamps.append(stamp_ns)
        done = n - self.lag + 1  # detections 0 … done-1 count
        if done > 0 and len(self._boxes) < done:
            raise RuntimeError(f"QuietViews: detection {done - 1} is still running (lag {self.lag})")
        if self._last_whole is None or stamp_ns - self._last_whole >= self.period_ns - 1_000_000 or done <= 0:
            self._last_whole = stamp_ns
            self.whole += 1
            return None
        cols = np.zeros(width, dtype=bool)
        pad = self.margin_deg / 360.0 * width
        for k in range(done - 1, -1, -1):
            if stamp_ns - self._stamps[k] > self.recent_ns:
                break
            for u1, _, u2, _ in self._boxes[k]:
                lo, hi = int(np.floor(u1 - pad)), int(np.ceil(u2 + pad))
                cols[np.arange(lo, hi + 1) % width] = True
        self.partial += 1
        return cols

    def finish(self, boxes: FloatArray) -> None:
        """The boxes (``(N, 4)`` panorama px, seam form) of the next detection in the order started."""
        self._boxes.append(np.asarray(boxes, dtype=np.float64).reshape(-1, 4))


@dataclass
class PerceptionFrame:
    """Pass-one output for one frame (detections only; no images are kept)."""

    index: int
    stamp_ns: int
    robot_pose: Pose2  # T_odom_base; on a rig without odometry scan matching's pose (identity when it is off)
    image: Any | None  # ImageDetections
    appearance: NDArray[np.float32] | None  # (n_boxes, D)
    laser: LaserDetections | None  # base frame, segments index into `points`
    laser_z: FloatArray  # (n_laser,) scan-plane height of each detection in the base frame
    origins: FloatArray  # (S, 2) scanner positions in the base frame
    # the beams of the frame's scans, as :func:`compact_beams` keeps them (labeling holds every beam until
    # fusion ends, then :meth:`without_beams`: a plane per scan instead of a height per beam saves a third):
    # (M, 2) x, y of every beam in the base frame, NaN = no return, scanner by scanner
    points: NDArray[np.float32]
    scan_sizes: NDArray[np.int32]  # (S,) how many of `points` each scanner gave
    scan_planes: FloatArray  # (S, 3) a, b, c per scanner: its beams lie at height z = a + b·x + c·y
    # T_world_base: the odometry pose corrected by scan matching (None: robot_pose, no correction)
    track_pose: Pose2 | None = None
    # far ends (K, 2) in the base frame of the beams that met nothing within range, and their scanners (K,)
    open_ends: NDArray[np.float32] = field(default_factory=lambda: np.zeros((0, 2), np.float32))
    open_owner: NDArray[np.int16] = field(default_factory=lambda: np.zeros(0, np.int16))
    # (S, 2) per scanner: its j-th point measured a + b·j seconds after the frame stamp (:func:`point_times`)
    beam_clocks: FloatArray | None = None
    # what the scanners saw, in the world frame, kept when the beams go (:meth:`scan_view`)
    view: ScanView | None = None

    @property
    def origin_of_point(self) -> NDArray[np.intp]:
        """``(M,)`` which scanner each of ``points`` came from."""
        return np.repeat(np.arange(len(self.scan_sizes)), self.scan_sizes)

    def points_z(self, sel: Any = slice(None)) -> FloatArray:
        """The base-frame height of ``points[sel]`` (all of them by default), from their scan planes."""
        abc = self.scan_planes[self.origin_of_point[sel]]
        xy = self.points[sel].astype(np.float64)
        return abc[:, 0] + abc[:, 1] * xy[:, 0] + abc[:, 2] * xy[:, 1]

    def without_beams(self) -> PerceptionFrame:
        """This frame without its beams (what tracking needs: pass one keeps them until fusion), their
        :meth:`scan_view` kept."""
        n = len(self.scan_sizes)
        return replace(
            self, points=np.zeros((0, 2), np.float32), scan_sizes=np.zeros(n, np.int32), view=self.scan_view()
        )

    def scan_view(self) -> ScanView | None:
        """What the scanners saw in this frame, in the world frame (:mod:`studio.track.sight`): from the
        beams while the frame has them, else as kept when they went; None without scans."""
        if not self.scan_sizes.sum():
            return self.view
        return scan_view((np.vstack([pts, ends]), origin) for pts, origin, ends, _, _ in odom_scans(self))

    @property
    def world_pose(self) -> Pose2:
        """The pose the static map and the tracker use: ``track_pose``, else the odometry's."""
        return self.robot_pose if self.track_pose is None else self.track_pose


def compact_beams(
    points: NDArray[np.float32], owner: NDArray[np.integer], n_scanners: int
) -> tuple[NDArray[np.float32], NDArray[np.int32], FloatArray]:
    """What :class:`PerceptionFrame` keeps of :func:`laser_in_base`'s beams ``(M, 3)`` and their scanners
    ``(M,)`` (scanner by scanner): their x, y ``(M, 2)``, each scanner's count ``(S,)`` and its scan plane
    ``(S, 3)``.

    A 2-D scanner's beams lie in one plane, so their height follows from x, y: exactly for a level scanner
    (one height), to float precision for a tilted one (a least-squares plane through its returns).
    """
    owner = np.asarray(owner, np.intp)
    if (np.diff(owner) < 0).any():
        raise ValueError("compact_beams: the beams must run scanner by scanner")
    sizes = np.bincount(owner, minlength=n_scanners).astype(np.int32)
    planes = np.zeros((n_scanners, 3))
    start = 0
    for k, n in enumerate(sizes):
        p = points[start : start + n].astype(np.float64)
        start += n
        p = p[np.isfinite(p).all(axis=1)]
        if not len(p):
            continue
        if np.ptp(p[:, 2]) == 0:  # level: one height, kept exactly
            planes[k, 0] = p[0, 2]
        else:
            planes[k] = np.linalg.lstsq(np.c_[np.ones(len(p)), p[:, :2]], p[:, 2], rcond=None)[0]
    return np.ascontiguousarray(points[:, :2]), sizes, planes


def laser_frame(
    frame: Any,
    stamp_ns: int,
    beams: tuple[LaserDetections | None, FloatArray, NDArray[np.float32], FloatArray, Any],
) -> PerceptionFrame:
    """The :class:`PerceptionFrame` of ``frame`` (a :class:`studio.io.Frame`) from :func:`laser_in_base`'s
    output ``beams`` (``laser`` None: no laser detector ran), before any image detections."""
    laser, laser_z, points, origins, owner = beams
    return PerceptionFrame(
        frame.index,
        stamp_ns,
        frame.robot_pose,
        None,
        None,
        laser,
        laser_z,
        origins,
        *compact_beams(points, owner, len(origins)),
    )


def remembers_legs(detector: Any) -> bool:
    """Whether ``detector`` pairs legs with the scanner's last scan (the classical one does)."""
    return callable(getattr(detector, "detect_remembering", None))


def _detect_scan(
    detector: Any,
    points: FloatArray,
    valid: NDArray[np.bool_],
    memory: dict[int, Any] | None,
    k: int,
    to_fixed: FloatArray,
) -> LaserDetections:
    """One scan through ``detector``; with ``memory`` (per scanner, updated in place) paired with scanner
    ``k``'s last scan."""
    if memory is None or not remembers_legs(detector):
        return detector.detect(points, valid=valid)
    det, memory[k] = detector.detect_remembering(points, valid=valid, memory=memory.get(k), to_fixed=to_fixed)
    return det


def laser_in_base(
    frame: Any, detector: Any, memory: dict[int, Any] | None = None
) -> tuple[LaserDetections, FloatArray, NDArray[np.float32], FloatArray, NDArray[np.int16]]:
    """Run ``detector`` on each scan of ``frame`` (a :class:`studio.io.Frame`) and bring it all to the base
    frame.

    ``memory`` (per scanner index, updated in place) lets a detector that :func:`remembers_legs` pair
    each scan's legs with the scanner's last scan, in the odometry frame.

    Returns:
        The detections of all scans merged (their segments index the points), each one's scan-plane height
        ``(N,)`` m, every beam ``(M, 3)`` float32 in the base frame (NaN = no return, in beam order per
        scan, counter-clockwise: :meth:`studio.io.ScanInBase.upright`), the scanners' positions ``(S, 2)``
        and which scanner each beam came from ``(M,)``.
    """
    parts, zs, pts_all, origins, owner = [], [], [], [], []
    offset = 0
    offsets = []
    for k, sib in enumerate(frame.scans):
        pose, pts2, valid = sib.upright()  # turned upright if mounted upside down, beams counter-clockwise
        m = pose.to_pose2().matrix()
        det = _detect_scan(detector, pts2, valid, memory, k, frame.robot_pose.matrix() @ m)
        parts.append(det.transformed(m))
        p3 = np.zeros((len(pts2), 3))
        p3[:, :2] = np.nan_to_num(pts2)
        p3 = pose.apply(p3)
        p3[~valid] = np.nan
        pts_all.append(p3.astype(np.float32))
        owner.append(np.full(len(p3), k, np.int16))
        origins.append(pose.t[:2])
        zs.append(np.full(len(det.xy), float(pose.t[2])))
        offsets.append(offset)
        offset += len(p3)
    if not parts:
        return (
            LaserDetections.empty(with_segments=True),
            np.zeros(0),
            np.zeros((0, 3), np.float32),
            np.zeros((0, 2)),
            np.zeros(0, np.int16),
        )
    merged = merge_detections(parts, offsets=offsets)
    z_all = np.concatenate(zs)
    points = np.concatenate(pts_all)
    laser_z = _heights(merged, points[:, 2], float(np.mean(z_all)) if len(z_all) else 0.0)
    return merged, laser_z, points, np.array(origins), np.concatenate(owner)


def moving_on(frame: Any, twist: tuple[float, float, float]) -> Any:
    """``frame`` (a :class:`studio.io.Frame` of a rig without odometry) with its scans placed as a robot
    moving at ``twist`` = ``(vx, vy, ω)`` in its base frame (m/s, rad/s) measured them: a scan taken before or
    after the frame stamp from where the robot was then, and a scan that took time (``time_increment``)
    de-skewed over its sweep (:meth:`studio.io.ScanInBase.deskewed`). Without odometry the synchroniser
    knows no motion; scan matching's motion between the last frames stands in for it (constant velocity)."""
    scans = []
    for sib in frame.scans:
        t0 = (sib.scan.stamp_ns - frame.stamp_ns) * 1e-9
        pose = _moved(twist, t0).compose(sib.sensor_pose)
        end = None
        n, ti = len(sib.scan), float(sib.scan.time_increment)
        if ti != 0.0 and n > 1:
            end = _moved(twist, t0 + (n - 1) * ti).compose(sib.sensor_pose)
        scans.append(replace(sib, sensor_pose=pose, sensor_pose_end=end))
    return replace(frame, scans=tuple(scans))


def _moved(twist: tuple[float, float, float], t: float) -> Pose3:
    """Where the base is after ``t`` seconds at the constant ``twist`` (the planar exponential)."""
    vx, vy, w = twist
    th = w * t
    if abs(th) < 1e-9:
        dx, dy = vx * t, vy * t
    else:
        a, b = np.sin(th) / w, (1.0 - np.cos(th)) / w
        dx, dy = a * vx - b * vy, b * vx + a * vy
    return Pose3.from_xyz_rpy(float(dx), float(dy), 0.0, 0.0, 0.0, float(th))


def _twist(before: tuple[int, Pose2], after: tuple[int, Pose2]) -> tuple[float, float, float]:
    """The constant velocity ``(vx, vy, ω)`` in the base frame that takes the robot from one
    ``(stamp_ns, T_world_base)`` to the next (zero when they are not 0–0.5 s apart)."""
    dt = (after[0] - before[0]) * 1e-9
    if not 0.0 < dt <= 0.5:
        return (0.0, 0.0, 0.0)
    rel = before[1].inverse().compose(after[1])
    w = rel.yaw / dt
    th = rel.yaw
    if abs(th) < 1e-9:
        return (rel.x / dt, rel.y / dt, w)
    # invert the planar exponential of _moved
    a, b = np.sin(th) / th, (1.0 - np.cos(th)) / th
    det = a * a + b * b
    return (float((a * rel.x + b * rel.y) / det / dt), float((-b * rel.x + a * rel.y) / det / dt), float(w))


def beam_clocks(frame: Any) -> FloatArray:
    """When the beams of ``frame``'s scans were measured: ``(S, 2)``, per scan ``(a, b)``, its ``j``-th point
    of :func:`laser_in_base` at ``a + b · j`` seconds after the frame stamp (a scan taken before or after the
    frame, and a beam late in a sweep, saw people where they were then: someone walking 1.4 m/s moves 10 cm
    in a 10 Hz scanner's sweep)."""
    return np.array([sib.beam_clock(frame.stamp_ns) for sib in frame.scans], dtype=np.float64).reshape(-1, 2)


def point_times(f: PerceptionFrame) -> FloatArray | None:
    """When each of ``f.points`` was measured ``(M,)``, seconds after the frame stamp, from
    ``f.beam_clocks``; None when the frame has none (a pass one stored before they were kept)."""
    if f.beam_clocks is None or len(f.beam_clocks) == 0:
        return None
    owner = f.origin_of_point.astype(np.int64)
    first = np.searchsorted(owner, np.arange(len(f.beam_clocks)))  # the points run scanner by scanner
    j = np.arange(len(owner)) - first[owner]
    return f.beam_clocks[owner, 0] + f.beam_clocks[owner, 1] * j


class BeamReturns:
    """Per scanner, how often each beam met something so far: one that never did is blind.

    The robot's body or a mount in a scanner's way reads NaN on some drivers, but ``+inf`` on those that
    follow REP 117 for "no return" (rplidar_ros, pointcloud_to_laserscan with ``use_inf``), and ``+inf``
    means free space up to ``range_max``: the static map then saw through the walls behind the robot, and
    furniture there turned into people (a 360° scanner with its rear sector blocked: 29 → 191 false
    positives on a simulated `moving` recording). A beam counts as open only once it has met something in
    3 scans: a direction that never met anything says nothing until then (a robot facing a hall longer
    than its scanner's reach learns it is open once someone has walked through it).
    """

    def __init__(self) -> None:
        self._hits: dict[str, NDArray[np.int64]] = {}

    def seeing(self, topic: str, scan: Any) -> NDArray[np.bool_]:
        """Count ``scan`` (of ``topic``) and return the mask of its beams that are not blind."""
        valid = scan.valid()
        hits = self._hits.get(topic)
        if hits is None or len(hits) != len(valid):  # a new scanner, or its beam count changed
            hits = self._hits[topic] = np.zeros(len(valid), np.int64)
        hits += valid
        return hits >= 3


def open_beams_in_base(
    frame: Any, returns: BeamReturns | None = None
) -> tuple[NDArray[np.float32], NDArray[np.int16]]:
    """The far ends ``(K, 2)`` in the base frame of ``frame``'s beams that met nothing within their
    scanner's ``range_max`` (:meth:`studio.io.LaserScan.open`), and which scanner each came from ``(K,)``;
    with ``returns`` (updated), only beams that are not blind (:class:`BeamReturns`)."""
    ends, owner = [np.zeros((0, 2), np.float32)], [np.zeros(0, np.int16)]
    for k, sib in enumerate(frame.scans):
        scan = sib.scan
        is_open = scan.open()
        if returns is not None:
            is_open &= returns.seeing(sib.topic, scan)
        if not is_open.any():
            continue
        a = scan.angles()[is_open]
        p3 = np.zeros((len(a), 3))
        far = scan.range_max * np.stack([np.cos(a), np.sin(a)], axis=1)
        p3[:, :2] = sib.deskewed(far, np.flatnonzero(is_open))
        ends.append(sib.sensor_pose.apply(p3)[:, :2].astype(np.float32))
        owner.append(np.full(len(a), k, np.int16))
    return np.concatenate(ends), np.concatenate(owner)


def _heights(merged: LaserDetections, z_all: FloatArray, fallback: float) -> FloatArray:
    """Scan-plane height of each detection: that of the scan whose points (their heights ``z_all``, NaN =
    no return) dominate its segment (``fallback`` without segments or points)."""
    if merged.segments is None or not len(z_all):
        return np.full(len(merged.xy), fallback)
    z = np.array([float(np.nanmedian(z_all[s])) if len(s) else fallback for s in merged.segments])
    return np.nan_to_num(z, nan=fallback)


def detect_again(
    f: PerceptionFrame,
    detector: Any,
    drop: NDArray[np.bool_] | None = None,
    memory: dict[int, Any] | None = None,
) -> tuple[LaserDetections, FloatArray]:
    """Run ``detector`` again on the frame's stored scans, without the points ``drop`` marks.

    Each scan goes to the detector in the base frame's orientation with its scanner at the origin (what
    the classical detector needs; a detector that reads beam order and ranges sees the same scan). With
    ``memory`` (per scanner, updated in place), legs are paired with the previous scans as in
    :func:`perceive` (to run every frame again in order); without, each scan on its own (a frame detected
    again alone, e.g. without structure points: the memory is not kept per frame, it would grow with the
    recording).

    Returns:
        The merged detections (segments index ``f.points``) and each one's scan-plane height, as
        :func:`laser_in_base`.
    """
    parts, offsets = [], []
    for k, origin in enumerate(f.origins):
        sel = np.flatnonzero(f.origin_of_point == k)
        pts = f.points[sel, :2].astype(np.float64) - origin
        valid = np.isfinite(pts[:, 0])
        if drop is not None:
            valid &= ~drop[sel]
        shift = np.array([[1.0, 0.0, origin[0]], [0.0, 1.0, origin[1]], [0, 0, 1]])
        det = _detect_scan(
            detector,
            np.where(valid[:, None], pts, np.nan),
            valid,
            memory,
            k,
            f.robot_pose.matrix() @ shift,
        )
        parts.append(det.transformed(shift))
        offsets.append(int(sel[0]) if len(sel) else 0)
    merged = merge_detections(parts, offsets=offsets) if parts else LaserDetections.empty(with_segments=True)
    z_all = np.where(np.isfinite(f.points[:, 0]), f.points_z(), np.nan)
    mean_z = float(np.nanmean(z_all)) if np.isfinite(z_all).any() else 0.0
    return merged, _heights(merged, z_all, mean_z)


def perceive(
    recording: Path,
    rig: Any,
    options: LabelOptions,
    *,
    progress: Callable[[int, int], None] | None = None,
    on_frame: Callable[[Any, PerceptionFrame], None] | None = None,
) -> tuple[list[PerceptionFrame], dict[str, Any]]:
    """Pass one: stream the recording, detect people in images and scans.

    Args:
        recording: the bag.
        rig: the loaded rig (:class:`studio.io.rig.Rig`).
        options: what to run.
        progress: called as ``progress(done, total)``.
        on_frame: called with ``(frame, perception)`` for every frame while its image is still in memory
            (the viewer and the frame exporter hook in here).

    Returns:
        The frames and a dict of counts/timings/sync report.
    """
    from studio.io import count_frames, iter_frames, open_recording, resolve_sensor_poses
    from studio.io.sync import SyncReport

    use_camera = rig.camera is not None and options.sources in ("both", "camera")
    use_laser = bool(rig.lasers) and options.sources in ("both", "laser")
    if options.sources == "camera" and rig.camera is None:
        raise StudioError("--sources camera needs a camera in the rig")
    if options.sources == "laser" and not rig.lasers:
        raise StudioError("--sources laser needs at least one laser in the rig")
    image_detector = None
    if use_camera:
        from studio.detect.image import get_image_detector

        image_detector = get_image_detector(options.image_detector or "movenet")
    laser_detector = None
    if use_laser:
        from studio.detect.laser import get_laser_detector

        laser_detector = get_laser_detector(options.laser_detector or "classical")

    from studio.detect.laser.static_map import StaticMapBuilder
    from studio.geometry.scan_match import ScanMatchConfig, ScanOdometry
    from studio.track.appearance import clothing_colours

    # the static-world map grows while the recording is read (this thread mostly waits for the images)
    # (where it changed while the scanner stood still only matters to the walk gate of laser-only labels)
    static_map = (
        StaticMapBuilder(steady_scans=0 if use_camera else 3)
        if options.static_filter and options.sources != "camera"
        else None
    )
    beam_returns = BeamReturns()
    # and per scanner a map of its scans in the base frame: what most of them hit is the robot's own body
    body_maps: list[Any] = []
    # odometry drift corrected by matching the scans (the static map and the tracker need a fixed world)
    # (every other frame with odometry: it is exact over a tenth of a second; ~2.5 ms per frame)
    matcher = ScanOdometry(ScanMatchConfig(every=2)) if options.scan_matching and use_laser else None
    has_odometry = rig.odometry is not None
    # per scanner, the legs of its last scan (for a laser detector that pairs legs over time)
    leg_memory: dict[int, Any] | None = {} if remembers_legs(laser_detector) else None

    def detect_image(
        detector: Any, pano: NDArray[np.uint8], columns: NDArray[np.bool_] | None, zoom: list[float]
    ) -> tuple[Any, NDArray[np.float32], float]:
        t = time.perf_counter()
        kw: dict[str, Any] = {} if columns is None else {"columns": columns}
        if zoom:
            kw["zoom"] = zoom
        det = detector.detect(pano, **kw)
        return det, clothing_colours(pano, det.boxes, det.keypoints), time.perf_counter() - t

    # people far away are a few pixels tall in the detector's views: where the laser found one lately, the
    # image detector looks closer (one that takes views of any size, ``windows``; see
    # ViewSweepDetector.detect), on whole and partial looks alike
    far_looks = FarLooks() if getattr(image_detector, "windows", False) and use_laser else None
    camera: Any = None

    # the part of the panorama where nobody was seen lately is looked at less often
    in_flight = 2  # image detections running at most while the next frames are read
    quiet = (
        QuietViews(options.quiet_view_period_s, lag=in_flight + 1)
        if getattr(image_detector, "looks_at_columns", False)
        and options.quiet_view_period_s > options.image_period_s
        else None
    )

    t_img = t_las = t_io = t_wait = t_map = t_match = 0.0
    # without odometry: scan matching's last pose, and the motion since the one before (see moving_on)
    last_matched: tuple[int, Pose2] | None = None
    twist: tuple[float, float, float] | None = None
    beam_deg: dict[str, float] = {}  # per laser topic: its angle between beams, degrees
    sweep_ms: dict[str, float] = {}  # ... and the time from its first beam to its last (0: not said), ms
    last_image_ns: int | None = None
    frames: list[PerceptionFrame] = []
    # frames read but not yet handed on, with their image detection still running (or None)
    pending: deque[tuple[Any, PerceptionFrame, Future[Any] | None]] = deque()
    report = SyncReport()

    def hand_on(*, wait_for: int) -> None:
        """Hand finished frames on in order; wait until at most ``wait_for`` detections are running."""
        nonlocal t_img, t_wait
        while pending:
            frame, pf, job = pending[0]
            if job is not None:
                if not job.done() and sum(j is not None for _, _, j in pending) <= wait_for:
                    return
                t = time.perf_counter()
                pf.image, pf.appearance, dt = job.result()
                if quiet is not None:
                    quiet.finish(pf.image.boxes)
                t_wait += time.perf_counter() - t
                t_img += dt
            pending.popleft()
            frames.append(pf)
            if on_frame is not None:
                on_frame(frame, pf)
            if progress is not None:
                progress(len(frames), total)

    # The image detector runs on two threads of its own (two frames in flight at most, one unless the
    # detector says it is thread-safe; its views on the detector's threads) while this one reads, decodes
    # and runs the laser detector on the next frames. "image_detection" in the timings sums the
    # detections' own durations, so it overlaps the others.
    workers = 2 if getattr(image_detector, "thread_safe", False) else 1
    with (
        open_recording(recording) as rec,
        ThreadPoolExecutor(workers, thread_name_prefix="studio-image") as pool,
    ):
        notes = list(rec.notes)
        if rig.camera is not None and not use_camera and not rec.has_topic(rig.camera.topic):
            # --sources laser on a recording without the rig's camera: label it as a laser-only rig does
            notes.append(
                f"the rig's camera topic {rig.camera.topic} is not in the recording: a frame is a scan of "
                f"{rig.lasers[0].topic}, as on a rig without a camera"
            )
            rig = replace(rig, camera=None)
        rig = resolve_sensor_poses(rec, rig)
        if use_camera:
            require_camera_pose(rec, rig)
        total = count_frames(rec, rig)
        it: Iterator[Any] = iter(iter_frames(rec, rig, report=report))
        t0 = time.perf_counter()
        for frame in it:
            t1 = time.perf_counter()
            t_io += t1 - t0
            job = None
            stamp = frame.stamp_ns
            if frame.panorama is not None:
                stamp = frame.panorama.stamp_ns
            due = last_image_ns is None or stamp - last_image_ns >= options.image_period_s * 1e9 - 1e6
            t2 = time.perf_counter()
            for sib in frame.scans:
                beam_deg.setdefault(sib.topic, abs(float(np.degrees(sib.scan.angle_increment))))
                sweep_ms.setdefault(
                    sib.topic, abs(float(sib.scan.time_increment)) * max(len(sib.scan) - 1, 0) * 1e3
                )
            if twist is not None:
                frame = moving_on(frame, twist)
            if use_laser and laser_detector is not None:
                laser, laser_z, points, origins, owner = laser_in_base(frame, laser_detector, leg_memory)
            else:
                laser, laser_z = None, np.zeros(0)
                # scan points only (the viewer and the export still show the scans)
                _, _, points, origins, owner = laser_in_base(frame, NoLaserDetector())
            t3 = time.perf_counter()
            t_las += t3 - t2
            if use_camera and frame.panorama is not None and image_detector is not None and due:
                last_image_ns = stamp
                pano = frame.panorama.image
                columns = None if quiet is None else quiet.start(stamp, pano.shape[1])
                zoom: list[float] = []
                if far_looks is not None and laser is not None:
                    if camera is None or camera.width != pano.shape[1]:
                        camera = rig_camera(rig, pano.shape[1], pano.shape[0])
                    # the frame's own pose; without odometry scan matching's last one (a frame behind)
                    here = frame.robot_pose if has_odometry or last_matched is None else last_matched[1]
                    zoom = far_looks.bearings(camera, stamp, here, laser.xy, laser_z)
                job = pool.submit(detect_image, image_detector, pano, columns, zoom)
            t3 = time.perf_counter()
            pf = laser_frame(frame, stamp, (laser, laser_z, points, origins, owner))
            pf.beam_clocks = beam_clocks(frame)
            if static_map is not None:
                pf.open_ends, pf.open_owner = open_beams_in_base(frame, beam_returns)
            if matcher is not None and laser is not None:
                pf.track_pose = matcher.step(
                    off_people(points, laser), frame.robot_pose if has_odometry else None
                )
                if not has_odometry:  # the robot's only motion: the outputs' odom frame is scan matching's
                    pf.robot_pose = pf.track_pose
                    if last_matched is not None:
                        twist = _twist(last_matched, (frame.stamp_ns, pf.track_pose))
                    last_matched = (frame.stamp_ns, pf.track_pose)
                t_match += time.perf_counter() - t3
                t3 = time.perf_counter()
            if static_map is not None:
                for scan in odom_scans(pf):
                    static_map.add(*scan)
                if pf.index % _BODY_EVERY == 0:  # the body is judged by a share of the scans: a sample does
                    for k, body_scan in enumerate(base_scans(pf)):
                        if k == len(body_maps):
                            body_maps.append(StaticMapBuilder(max_free_range=0.0, steady_scans=0))
                        body_maps[k].add(*body_scan)
                t_map += time.perf_counter() - t3
            if far_looks is not None and laser is not None:
                far_looks.add(stamp, pf.robot_pose, laser.xy, laser_z)
            pending.append((frame, pf, job))
            hand_on(wait_for=in_flight)
            t0 = time.perf_counter()
        hand_on(wait_for=0)
    info = {
        "timings_s": {
            "read_decode_sync": t_io,
            "image_detection": t_img,
            "laser_detection": t_las,
            "scan_matching": t_match,
            "static_map": t_map,
            "waiting_for_images": t_wait,
        },
        "static_map": static_map.finish() if static_map is not None and static_map.n_scans else None,
        "body_maps": [b.finish() for b in body_maps] if static_map is not None else None,
        "scan_matching": None
        if matcher is None
        else {"matched": matcher.matched, "rejected": matcher.rejected, "skipped": matcher.skipped},
        "sync": report.summary(),
        "sync_report": report,
        "image_looks": None if quiet is None else {"whole": quiet.whole, "partial": quiet.partial},
        "views_run": getattr(image_detector, "views_run", None),
        "view_columns_run": getattr(image_detector, "view_columns_run", None),
        "frames": len(frames),
        "laser_beam_deg": beam_deg,
        "laser_sweep_ms": sweep_ms,
        "use_camera": use_camera,
        "notes": notes,
        "use_laser": use_laser,
        "rig": rig,
    }
    return frames, info


ZOOM_RANGE_M = (4.5, 11.0)  # laser detections this far from the base get a closer look by the camera
ZOOM_MEMORY_S = 0.5  # ... and so do those of the frames this much older


class FarLooks:
    """Where the image detector should look closer: the laser detections :data:`ZOOM_RANGE_M` from the
    base, in this frame and in the frames of the last ``memory_s`` before it.

    The scanners miss most people 7 m away or more in a given scan (a few beams reach their legs), but
    rarely in all the scans of half a second. Those of the earlier frames are kept in the odom frame and
    brought into this frame's base frame; someone walking 1.5 m/s moves about 5° across the bearing in
    0.5 s at 8 m, within a closer look's 18° (:meth:`ViewSweepDetector.zoom_views`).
    """

    def __init__(self, memory_s: float = ZOOM_MEMORY_S) -> None:
        self.memory_ns = round(memory_s * 1e9)
        self._recent: deque[tuple[int, FloatArray, FloatArray]] = deque()  # stamp, odom xy, heights

    def add(self, stamp_ns: int, pose: Pose2, xy: FloatArray, z: FloatArray) -> None:
        """Remember the far ones of a frame's laser detections ``xy`` (base frame at ``pose`` =
        T_odom_base, scan-plane heights ``z``)."""
        far = _far(xy)
        if far.any():
            self._recent.append((stamp_ns, pose.apply(xy[far]), np.asarray(z, dtype=np.float64)[far]))

    def bearings(self, camera: Any, stamp_ns: int, pose: Pose2, xy: FloatArray, z: FloatArray) -> list[float]:
        """Panorama azimuths (rad) to look closer at in the frame at ``stamp_ns`` and ``pose``: those of
        its own far detections ``xy`` first, then those of the remembered ones."""
        while self._recent and self._recent[0][0] < stamp_ns - self.memory_ns:
            self._recent.popleft()
        into_base = pose.inverse()
        pts = np.concatenate(
            [np.asarray(xy, dtype=np.float64).reshape(-1, 2)]
            + [into_base.apply(w) for _, w, _ in self._recent]
        )
        heights = np.concatenate(
            [np.asarray(z, dtype=np.float64).reshape(-1)] + [h for _, _, h in self._recent]
        )
        return far_bearings(camera, pts, heights) if len(pts) else []


def _far(xy: FloatArray) -> NDArray[np.bool_]:
    r = np.hypot(xy[:, 0], xy[:, 1])
    return (r >= ZOOM_RANGE_M[0]) & (r <= ZOOM_RANGE_M[1])


def far_bearings(camera: Any, xy: FloatArray, z: FloatArray) -> list[float]:
    """Panorama azimuths (rad) of the laser detections ``xy`` ``(N, 2)`` (base frame, scan-plane heights
    ``z``) that lie within :data:`ZOOM_RANGE_M` of the base."""
    far = _far(xy)
    if not far.any():
        return []
    uv, _ = camera.project(np.c_[xy[far], np.asarray(z, dtype=np.float64)[far]])
    ok = np.isfinite(uv[:, 0])
    return [float(a) for a in camera.pixel_to_angles(uv[ok, 0], uv[ok, 1])[0]]


def require_camera_pose(rec: Any, rig: Any) -> None:
    """Raise :class:`TfError` when the rig's camera has no pose (neither in the rig nor from the recording's
    TF, after :func:`~studio.io.resolve_sensor_poses`): boxes would be placed from the wrong spot."""
    from studio.io import unplaced_reason
    from studio.io.errors import TfError

    if rig.camera is None or rig.camera.pose is not None:
        return
    if not rec.has_topic(rig.camera.topic) or not rec.topics[rec.resolve_topic(rig.camera.topic)].count:
        return  # iter_frames says what is wrong with the topic itself
    moving, why = unplaced_reason(rec, rig, rig.camera.topic)
    hint = "a camera that moves on the robot is not supported; " if moving else ""
    raise TfError(
        f"the camera ({rig.camera.topic}) cannot be placed: {why}: {hint}give camera.pose in rig.yaml"
    )


def rig_camera(rig: Any, width: int, height: int) -> Any:
    """The rig's spherical camera for ``width × height`` panoramas (identity pose when it has none)."""
    from studio.geometry import EquirectCamera
    from studio.geometry.se import Pose3

    pose = rig.camera.pose if rig.camera.pose is not None else Pose3.identity()
    return EquirectCamera(width, height, pose, rig.camera.lens_offset)


def base_scans(f: PerceptionFrame) -> Iterator[tuple[FloatArray, FloatArray]]:
    """The frame's scans in the base frame, as :func:`odom_scans` (for the map of the robot's body)."""
    for k in range(len(f.origins)):
        yield f.points[f.origin_of_point == k, :2].astype(np.float64), f.origins[k]


def off_people(points: NDArray[np.float32], laser: LaserDetections) -> FloatArray:
    """``(K, 2)`` the frame's points in the base frame without those of the laser detections (people move)."""
    keep = np.isfinite(points[:, 0])
    if laser.segments is not None:
        for seg in laser.segments:
            keep[seg] = False
    return points[keep, :2].astype(np.float64)


class NoLaserDetector:
    """A laser detector that finds nobody (scan points only: the viewer and the export still show them)."""

    def detect(self, points: FloatArray, *, valid: Any = None) -> LaserDetections:
        return LaserDetections.empty(with_segments=True)


def odom_scans(f: PerceptionFrame) -> Iterator[tuple[FloatArray, FloatArray, FloatArray, int, float]]:
    """The frame's scans in the world frame (:attr:`PerceptionFrame.world_pose`): ``(points (M, 2), scanner
    position (2,), open ends (K, 2), scanner index, frame stamp in s)``, beams in order with NaN for no
    return, then the far ends of the beams that met nothing within range (what
    :class:`studio.detect.laser.static_map.StaticMap` accumulates)."""
    pose = f.world_pose
    for k in range(len(f.origins)):
        sel = f.origin_of_point == k
        ends = f.open_ends[f.open_owner == k].astype(np.float64)
        yield (
            pose.apply(f.points[sel, :2].astype(np.float64)),
            pose.apply(f.origins[k]),
            pose.apply(ends) if len(ends) else np.zeros((0, 2)),
            k,
            f.stamp_ns * 1e-9,
        )
