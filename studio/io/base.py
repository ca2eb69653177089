"""Contracts of :mod:`studio.io`: the decoded sensor data and the synchronised frames.

Conventions: time stamps are integer nanoseconds (the message header stamp for data); frame ids have no
leading ``/``; a pose ``T_a_b`` expresses frame *b* in frame *a* (see :mod:`studio.geometry.se`).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from studio.geometry.se import Pose2, Pose3

__all__ = [
    "CloudSlice",
    "Frame",
    "LaserScan",
    "Odometry",
    "Panorama",
    "RawMessage",
    "ScanInBase",
    "TopicInfo",
    "upside_down",
]


def _check_stamp(name: str, stamp_ns: Any) -> int:
    if isinstance(stamp_ns, bool) or not isinstance(stamp_ns, int | np.integer):
        raise TypeError(f"{name}.stamp_ns must be an int (nanoseconds), got {type(stamp_ns).__name__}")
    return int(stamp_ns)


@dataclass(frozen=True)
class CloudSlice:
    """How a 3-D lidar's point cloud (sensor_msgs/PointCloud2) becomes a planar scan for the leg detector.

    The points between ``min_z`` and ``max_z`` (in the cloud's own frame) are projected onto its x–y plane
    and binned by bearing into beams ``step_deg`` apart; each beam keeps the nearest point's range, as
    ``pointcloud_to_laserscan`` does. An empty beam is NaN (no return), unless it is one of at most two
    between returns of one surface (the lidar's columns lie farther apart than the beams): those are
    filled in. For a lidar ``h`` metres above the
    floor, legs are the band ``0.2 - h`` to ``0.6 - h``.

    Attributes:
        min_z, max_z: the height band, metres in the cloud's frame; ``min_z < max_z``.
        step_deg: angle between the virtual scan's beams, degrees, in (0.05, 5]; None: the lidar's column
            spacing, of an organised cloud (360° / its width) or read off the order of an unorganised
            one's returns, else 0.25°.
        range_min: points nearer than this to the lidar's axis are left out (the robot's own body), m.
    """

    min_z: float
    max_z: float
    step_deg: float | None = None
    range_min: float = 0.1

    def __post_init__(self) -> None:
        for name in ("min_z", "max_z", "step_deg", "range_min"):
            v = getattr(self, name)
            if v is None and name == "step_deg":
                continue
            if isinstance(v, bool) or not isinstance(v, int | float | np.floating) or not np.isfinite(v):
                raise ValueError(f"cloud {name} must be a finite number, got {v!r}")
            object.__setattr__(self, name, float(v))
        if not self.min_z < self.max_z:
            raise ValueError(f"cloud min_z must be below max_z, got {self.min_z} and {self.max_z}")
        if self.step_deg is not None and not 0.05 < self.step_deg <= 5.0:
            raise ValueError(f"cloud step_deg must be in (0.05, 5] degrees, got {self.step_deg}")
        if self.range_min < 0:
            raise ValueError(f"cloud range_min must be >= 0, got {self.range_min}")


@dataclass(frozen=True)
class TopicInfo:
    """A topic of a recording.

    Attributes:
        name: topic name as stored in the recording (e.g. ``/scan``; ROS1 bags may have no leading ``/``).
        msgtype: message type, ROS2 style (``sensor_msgs/msg/LaserScan``), or the schema name for plain MCAP
            (e.g. ``foxglove.LaserScan``).
        count: number of messages.
    """

    name: str
    msgtype: str
    count: int


@dataclass(frozen=True)
class RawMessage:
    """One undecoded record of a recording (decode it with ``Recording.decode``).

    Attributes:
        topic: topic name.
        msgtype: message type (see :class:`TopicInfo`).
        log_ns: time the recorder logged it, ns (not the header stamp).
        rawdata: serialized message bytes.
    """

    topic: str
    msgtype: str
    log_ns: int
    rawdata: bytes


@dataclass(frozen=True)
class LaserScan:
    """A planar laser scan (sensor_msgs/LaserScan), beam ``i`` at ``angle_min + i * angle_increment``.

    Attributes:
        stamp_ns: header stamp, ns (time of the first beam).
        frame_id: laser frame (no leading ``/``).
        angle_min: angle of the first beam, rad, counter-clockwise from the frame's +x axis.
        angle_increment: angle between beams, rad (may be negative).
        ranges: float32 (N,), metres; NaN, inf or out of ``[range_min, range_max]`` means no return.
        range_min: smallest valid range, metres.
        range_max: largest valid range, metres.
        intensities: float32 (N,) or None when the scanner gives none.
        time_increment: time between beams, seconds (beam ``i`` at ``stamp_ns + i · time_increment``); 0 when
            the driver does not say (the scan is then taken as instantaneous).
    """

    stamp_ns: int
    frame_id: str
    angle_min: float
    angle_increment: float
    ranges: NDArray[np.float32]
    range_min: float
    range_max: float
    intensities: NDArray[np.float32] | None = None
    time_increment: float = 0.0

    def __post_init__(self) -> None:
        object.__setattr__(self, "stamp_ns", _check_stamp("LaserScan", self.stamp_ns))
        ranges = np.asarray(self.ranges, dtype=np.float32).reshape(-1)
        object.__setattr__(self, "ranges", ranges)
        if self.intensities is not None:
            inten = np.asarray(self.intensities, dtype=np.float32).reshape(-1)
            if inten.size == 0:
                object.__setattr__(self, "intensities", None)
            elif inten.shape != ranges.shape:
                raise ValueError(f"LaserScan intensities {inten.shape} do not match ranges {ranges.shape}")
            else:
                object.__setattr__(self, "intensities", inten)
        for name in ("angle_min", "angle_increment", "range_min", "range_max", "time_increment"):
            v = float(getattr(self, name))
            if not np.isfinite(v):
                raise ValueError(f"LaserScan.{name} must be finite, got {v}")
            object.__setattr__(self, name, v)
        if ranges.size > 0 and self.angle_increment == 0.0:
            raise ValueError("LaserScan.angle_increment must not be 0")

    def __len__(self) -> int:
        return int(self.ranges.shape[0])

    def angles(self) -> NDArray[np.float64]:
        """Beam angles (N,), rad, in the scan frame."""
        return self.angle_min + self.angle_increment * np.arange(len(self), dtype=np.float64)

    def valid(self) -> NDArray[np.bool_]:
        """Mask (N,) of beams with a return: finite, above 0 (low-cost drivers write 0 for "no return",
        with ``range_min`` 0 too) and within ``[range_min, range_max]``."""
        r = self.ranges
        with np.errstate(invalid="ignore"):
            return np.isfinite(r) & (r > 0.0) & (r >= self.range_min) & (r <= self.range_max)

    def open(self) -> NDArray[np.bool_]:
        """Mask (N,) of beams that met nothing within ``range_max``: ``+inf`` (REP 117) or a finite value
        beyond ``range_max``. The space along them is free up to ``range_max``. NaN, ``-inf`` and values
        below ``range_min`` are errors or too close, and say nothing (older drivers also write a small value
        for "no return"; it cannot be told from an error)."""
        r = self.ranges
        with np.errstate(invalid="ignore"):
            return np.isposinf(r) | (np.isfinite(r) & (r > self.range_max))

    def points(self) -> NDArray[np.float64]:
        """Beam end points (N, 2), metres, in the scan frame; NaN rows where the beam is invalid."""
        a = self.angles()
        r = np.where(self.valid(), self.ranges.astype(np.float64), np.nan)
        return np.stack([r * np.cos(a), r * np.sin(a)], axis=-1)


@dataclass(frozen=True)
class Panorama:
    """An equirectangular 360° image.

    Attributes:
        stamp_ns: header stamp of the image message, ns (no latency correction).
        frame_id: camera frame (no leading ``/``).
        image: uint8 (H, W, 3), BGR (OpenCV order).
        encoded: the original compressed bytes of a CompressedImage (JPEG or PNG), so a viewer can log them
            without re-encoding; None for raw images.
        encoding: format of ``encoded`` (``"jpeg"`` or ``"png"``), ``""`` when ``encoded`` is None.
    """

    stamp_ns: int
    frame_id: str
    image: NDArray[np.uint8]
    encoded: bytes | None = None
    encoding: str = ""

    def __post_init__(self) -> None:
        object.__setattr__(self, "stamp_ns", _check_stamp("Panorama", self.stamp_ns))
        img = np.asarray(self.image)
        if img.dtype != np.uint8 or img.ndim != 3 or img.shape[2] != 3:
            raise ValueError(f"Panorama.image must be uint8 (H, W, 3), got {img.dtype} {img.shape}")
        object.__setattr__(self, "image", img)
        if self.encoded is not None and not isinstance(self.encoded, bytes):
            object.__setattr__(self, "encoded", bytes(self.encoded))

    @property
    def width(self) -> int:
        return int(self.image.shape[1])

    @property
    def height(self) -> int:
        return int(self.image.shape[0])


@dataclass(frozen=True)
class Odometry:
    """A planar odometry sample: pose of ``child_frame_id`` (the robot base) in ``frame_id`` (odom).

    Attributes:
        stamp_ns: header stamp, ns.
        frame_id: odometry frame (e.g. ``odom``).
        child_frame_id: robot frame (e.g. ``base_link``); may be ``""`` when the message leaves it empty.
        pose: planar pose T_frame_child (metres, rad).
    """

    stamp_ns: int
    frame_id: str
    child_frame_id: str
    pose: Pose2

    def __post_init__(self) -> None:
        object.__setattr__(self, "stamp_ns", _check_stamp("Odometry", self.stamp_ns))
        if not isinstance(self.pose, Pose2):
            raise TypeError("Odometry.pose must be a Pose2")


def upside_down(sensor_pose: Pose3) -> bool:
    """Whether a scanner with this pose in the base frame is mounted upside down (its z axis points down)."""
    return bool(sensor_pose.R[2, 2] < 0.0)


@dataclass(frozen=True)
class ScanInBase:
    """A scan attached to a frame, with where the laser was relative to the base at the frame stamp.

    Attributes:
        topic: the laser's topic.
        scan: the decoded scan (its own stamp may differ from the frame's by up to ``max_dt_s``).
        sensor_pose: T_base_laser expressed in the base frame *at the frame stamp*, i.e. motion-compensated:
            ``T_odom_base(t_frame)⁻¹ ∘ T_odom_base(t_scan) ∘ T_base_laser``.
        sensor_pose_end: the same at the time of the scan's last beam, when the scan took time
            (``LaserScan.time_increment``) and odometry tells how the robot moved meanwhile; else None.
    """

    topic: str
    scan: LaserScan
    sensor_pose: Pose3
    sensor_pose_end: Pose3 | None = None

    def __post_init__(self) -> None:
        if not isinstance(self.scan, LaserScan) or not isinstance(self.sensor_pose, Pose3):
            raise TypeError("ScanInBase needs a LaserScan and a Pose3")

    def deskewed(
        self, pts: NDArray[np.float64], beams: NDArray[np.int64] | None = None
    ) -> NDArray[np.float64]:
        """Points ``(K, 2)`` of beams ``beams`` (all the scan's when None) in the scanner's frame, as the
        scanner saw them from where it was at the first beam: a scanner that sweeps while the robot turns
        or drives measures each beam from elsewhere (a 10 Hz scanner on a robot turning at 0.5 rad/s: 0.05 rad
        over the sweep, 25 cm at 5 m). The motion between ``sensor_pose`` and ``sensor_pose_end`` is spread
        over the beams in proportion to their time. Without ``sensor_pose_end`` the points are unchanged."""
        n = len(self.scan)
        if self.sensor_pose_end is None or n < 2:
            return pts
        d = self.sensor_pose.inverse().compose(self.sensor_pose_end)  # the sweep's motion, scanner frame
        turn = float(np.arctan2(d.R[1, 0], d.R[0, 0]))
        f = (np.arange(n) if beams is None else np.asarray(beams)) / (n - 1)
        c, s = np.cos(f * turn), np.sin(f * turn)
        x, y = pts[:, 0], pts[:, 1]
        return np.stack([c * x - s * y + f * d.t[0], s * x + c * y + f * d.t[1]], axis=1)

    def upright(self) -> tuple[Pose3, NDArray[np.float64], NDArray[np.bool_]]:
        """The scan as a scanner at the same place, mounted the right way up and turning counter-clockwise,
        would give it.

        A scanner mounted upside down (its z axis pointing down, as many robots carry them) sees the plane
        mirrored: a planar pose of it cannot map its points to the base frame. Turned over about its x axis
        it is upright again, and its points' y changes sign. The beams are then put in counter-clockwise
        order (seen from above), whichever way the scanner turned, so a detector sees the same scan from any
        mounting and any driver (some write a negative ``angle_increment``).

        Returns:
            ``T_base_scanner`` of the upright scanner (its z axis up; ``to_pose2`` maps its points to the
            base plane), the beams' end points ``(N, 2)`` in its frame (NaN where invalid), counter-clockwise,
            and their validity mask ``(N,)``; for an upright scanner with a positive step, ``sensor_pose``
            and the scan's own.
        """
        pose, pts, valid = self.sensor_pose, self.deskewed(self.scan.points()), self.scan.valid()
        if upside_down(pose):
            pose = pose.compose(Pose3(np.diag([1.0, -1.0, -1.0]), np.zeros(3)))
            pts = pts * np.array([1.0, -1.0])
        if self._upright_reversed():
            pts, valid = pts[::-1], valid[::-1]
        return pose, pts, valid

    def _upright_reversed(self) -> bool:
        """Whether :meth:`upright` reverses the beams: the scanner sweeps clockwise seen from above."""
        return (self.scan.angle_increment < 0.0) != upside_down(self.sensor_pose)

    def beam_clock(self, frame_stamp_ns: int) -> tuple[float, float]:
        """When the beams were measured, seconds after ``frame_stamp_ns``: beam ``j`` in :meth:`upright`'s
        order at ``a + b · j`` for the ``(a, b)`` returned (ROS: beam i of the message at the stamp +
        i · ``time_increment``; all at the stamp when that is 0)."""
        t0 = (self.scan.stamp_ns - frame_stamp_ns) * 1e-9
        ti = float(self.scan.time_increment)
        if self._upright_reversed():
            return t0 + ti * max(len(self.scan) - 1, 0), -ti
        return t0, ti

    def points_base(self) -> NDArray[np.float64]:
        """Valid beam end points (M, 3), metres, in the base frame at the frame stamp."""
        pts = self.deskewed(self.scan.points())[self.scan.valid()]
        p3 = np.zeros((pts.shape[0], 3), dtype=np.float64)
        p3[:, :2] = pts
        return self.sensor_pose.apply(p3)


@dataclass(frozen=True)
class Frame:
    """A labeled frame: a panorama (when the rig has a camera) and the nearest scan of every laser.

    Attributes:
        index: 0, 1, … in the order frames are yielded (dropped frames take no index).
        stamp_ns: frame time, ns: the image header stamp minus the rig's camera latency, or the header
            stamp of the first laser's scan for a laser-only rig.
        panorama: the image, or None for a laser-only rig.
        scans: one entry per rig laser that had a scan within ``max_dt_s`` (rig order, missing ones left out).
        robot_pose: planar T_odom_base at ``stamp_ns`` (identity when the rig has no odometry).
    """

    index: int
    stamp_ns: int
    panorama: Panorama | None
    scans: tuple[ScanInBase, ...]
    robot_pose: Pose2

    def __post_init__(self) -> None:
        object.__setattr__(self, "stamp_ns", _check_stamp("Frame", self.stamp_ns))
        object.__setattr__(self, "scans", tuple(self.scans))
        if self.panorama is not None and not isinstance(self.panorama, Panorama):
            raise TypeError("Frame.panorama must be a Panorama or None")
        if not all(isinstance(s, ScanInBase) for s in self.scans):
            raise TypeError("Frame.scans must hold ScanInBase")
        if not isinstance(self.robot_pose, Pose2):
            raise TypeError("Frame.robot_pose must be a Pose2")

    def scan(self, topic: str) -> ScanInBase | None:
        """The scan of the laser on ``topic``, or None when the frame has none."""
        for s in self.scans:
            if s.topic == topic:
                return s
        return None
