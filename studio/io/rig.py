"""The sensor set-up of a recording: ``rig.yaml`` (format in DESIGN.md §2), loaded and validated.

Example::

    base_frame: base_link
    odometry: {topic: /odom}          # or {tf: odom}; absent → static robot
    camera:
      topic: /theta_camera/image/compressed
      pose: {x: 0.0, y: 0.0, z: 1.15, roll: 0.0, pitch: 0.0, yaw: 0.0}
      lens_offset: 0.013              # optional, metres: dual-lens parallax (default 0, central camera)
    lasers:
      - topic: /scan_front
        pose: {x: 0.35, y: 0.0, z: 0.30, yaw: 0.0}
      - topic: /velodyne_points       # a 3-D lidar (PointCloud2), 0.8 m up: its points 0.2-0.6 m
        cloud: {min_z: -0.6, max_z: -0.2}  # above the floor make a planar scan
    sync: {max_dt_s: 0.05, camera_latency_s: 0.0}

Poses are metres and radians in ``base_frame``; missing pose keys are 0. A sensor without ``pose`` takes
its pose from the TF tree of the recording. ``camera.lens_offset`` (metres, ``|b| < 0.2``) puts the two
lens centres of a dual-fisheye camera at ``(±b, 0, 0)`` in the camera frame
(:class:`~studio.geometry.equirect.EquirectCamera`); it is written only when non-zero. A laser entry
with ``cloud`` reads a PointCloud2 topic and slices it into a planar scan
(:class:`~studio.io.base.CloudSlice`: ``min_z``/``max_z`` metres in the cloud's frame, ``step_deg``
default the lidar's column spacing, else 0.25, ``range_min`` default 0.1 m).
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import yaml

from studio.atomic import atomic_write_text
from studio.geometry.se import Pose3
from studio.io.base import CloudSlice
from studio.io.errors import RigError
from studio.yamlload import load_yaml

__all__ = [
    "MAX_LENS_OFFSET_M",
    "CameraConfig",
    "LaserConfig",
    "OdometryConfig",
    "Rig",
    "SyncConfig",
    "load_rig",
    "parse_rig",
    "save_rig",
]

_POSE_KEYS = ("x", "y", "z", "roll", "pitch", "yaw")
_CLOUD_KEYS = ("min_z", "max_z", "step_deg", "range_min")
MAX_LENS_OFFSET_M = 0.2  # largest |camera.lens_offset| accepted, metres


def _norm_frame(name: str) -> str:
    return name.strip().lstrip("/")


@dataclass(frozen=True)
class OdometryConfig:
    """Where the robot's motion comes from: exactly one of ``topic`` (nav_msgs/Odometry) or ``tf``.

    Attributes:
        topic: odometry topic, e.g. ``/odom``.
        tf: the odometry frame of the TF tree (e.g. ``odom``); the pose is the TF lookup odom → base_frame.
    """

    topic: str | None = None
    tf: str | None = None

    def __post_init__(self) -> None:
        if (self.topic is None) == (self.tf is None):
            raise ValueError("OdometryConfig needs exactly one of topic or tf")
        if self.tf is not None:
            object.__setattr__(self, "tf", _norm_frame(self.tf))


@dataclass(frozen=True)
class CameraConfig:
    """The 360° camera.

    Attributes:
        topic: image topic (CompressedImage or Image).
        pose: T_base_camera (None → from TF).
        lens_offset: dual-lens parallax ``b``, metres: lens centres at ``(±b, 0, 0)`` in the camera frame
            (0: a central camera); finite, ``|b| < 0.2``.
    """

    topic: str
    pose: Pose3 | None = None
    lens_offset: float = 0.0

    def __post_init__(self) -> None:
        b = self.lens_offset
        if isinstance(b, bool) or not isinstance(b, int | float) or not math.isfinite(b):
            raise ValueError(f"lens_offset must be a finite number (metres), got {b!r}")
        if abs(b) >= MAX_LENS_OFFSET_M:
            raise ValueError(f"lens_offset must be within ±{MAX_LENS_OFFSET_M} m, got {b}")
        object.__setattr__(self, "lens_offset", float(b))


@dataclass(frozen=True)
class LaserConfig:
    """A 2D laser scanner: LaserScan topic and pose T_base_laser (None → from TF); or a 3-D lidar's
    PointCloud2 topic with ``cloud``, the height band sliced into a planar scan (:class:`CloudSlice`)."""

    topic: str
    pose: Pose3 | None = None
    cloud: CloudSlice | None = None


@dataclass(frozen=True)
class SyncConfig:
    """Time synchronisation.

    Attributes:
        max_dt_s: largest |scan stamp − frame stamp| for a scan to join a frame, seconds.
        camera_latency_s: image header stamps are this late; the frame stamp is the image stamp minus it.
    """

    max_dt_s: float = 0.05
    camera_latency_s: float = 0.0

    def __post_init__(self) -> None:
        if not (math.isfinite(self.max_dt_s) and self.max_dt_s >= 0):
            raise ValueError(f"max_dt_s must be a non-negative number, got {self.max_dt_s}")
        if not math.isfinite(self.camera_latency_s):
            raise ValueError(f"camera_latency_s must be finite, got {self.camera_latency_s}")

    @property
    def max_dt_ns(self) -> int:
        return round(self.max_dt_s * 1e9)

    @property
    def camera_latency_ns(self) -> int:
        return round(self.camera_latency_s * 1e9)


@dataclass(frozen=True)
class Rig:
    """The sensor set-up: base frame, odometry source, optional camera, lasers, synchronisation."""

    base_frame: str
    odometry: OdometryConfig | None = None
    camera: CameraConfig | None = None
    lasers: tuple[LaserConfig, ...] = ()
    sync: SyncConfig = field(default_factory=SyncConfig)

    def __post_init__(self) -> None:
        object.__setattr__(self, "base_frame", _norm_frame(self.base_frame))
        object.__setattr__(self, "lasers", tuple(self.lasers))
        if not self.base_frame:
            raise ValueError("base_frame must not be empty")
        if not self.lasers and self.camera is None:
            raise ValueError("a rig needs at least one laser or a camera")
        topics = [x.topic for x in self.lasers]
        if len(set(topics)) != len(topics):
            raise ValueError(f"a laser topic is listed twice: {topics}")

    def topics(self) -> list[str]:
        """Every topic the rig reads (camera, lasers, odometry)."""
        out = [self.camera.topic] if self.camera else []
        out += [x.topic for x in self.lasers]
        if self.odometry and self.odometry.topic:
            out.append(self.odometry.topic)
        return out

    def to_dict(self) -> dict[str, Any]:
        """The rig.yaml mapping (plain Python types)."""
        d: dict[str, Any] = {"base_frame": self.base_frame}
        if self.odometry is not None:
            d["odometry"] = (
                {"topic": self.odometry.topic}
                if self.odometry.topic is not None
                else {"tf": self.odometry.tf}
            )
        if self.camera is not None:
            cam: dict[str, Any] = {"topic": self.camera.topic}
            if self.camera.pose is not None:
                cam["pose"] = _pose_dict(self.camera.pose)
            if self.camera.lens_offset:
                cam["lens_offset"] = round(self.camera.lens_offset, 12) + 0.0
            d["camera"] = cam
        lasers = []
        for laser in self.lasers:
            entry: dict[str, Any] = {"topic": laser.topic}
            if laser.pose is not None:
                entry["pose"] = _pose_dict(laser.pose)
            if laser.cloud is not None:
                entry["cloud"] = {
                    k: float(getattr(laser.cloud, k))
                    for k in _CLOUD_KEYS
                    if getattr(laser.cloud, k) is not None
                }
            lasers.append(entry)
        d["lasers"] = lasers
        d["sync"] = {
            "max_dt_s": float(self.sync.max_dt_s),
            "camera_latency_s": float(self.sync.camera_latency_s),
        }
        return d


def _pose_dict(pose: Pose3) -> dict[str, float]:
    return {k: round(v, 12) + 0.0 for k, v in pose.as_dict().items()}


class _Checker:
    """Validation helpers that name the file and the key in every message."""

    def __init__(self, source: str) -> None:
        self.source = source

    def fail(self, key: str, what: str) -> RigError:
        where = f" key '{key}'" if key else ""
        return RigError(f"{self.source}:{where} {what}")

    def mapping(self, value: Any, key: str, allowed: tuple[str, ...], required: tuple[str, ...] = ()) -> dict:
        if not isinstance(value, dict):
            raise self.fail(key, f"must be a mapping, got {type(value).__name__}")
        unknown = [str(k) for k in value if k not in allowed]
        if unknown:
            prefix = f"{key}." if key else ""
            raise self.fail(
                prefix + unknown[0], f"is not a known key (expected one of: {', '.join(allowed)})"
            )
        for k in required:
            if k not in value:
                raise self.fail(f"{key}.{k}" if key else k, "is required")
        return value

    def string(self, value: Any, key: str) -> str:
        if not isinstance(value, str) or not value.strip():
            raise self.fail(key, f"must be a non-empty string, got {value!r}")
        return value.strip()

    def number(self, value: Any, key: str) -> float:
        if isinstance(value, bool) or not isinstance(value, int | float) or not math.isfinite(value):
            raise self.fail(key, f"must be a finite number, got {value!r}")
        return float(value)

    def pose(self, value: Any, key: str) -> Pose3:
        m = self.mapping(value, key, _POSE_KEYS)
        vals = {k: self.number(m.get(k, 0.0), f"{key}.{k}") for k in _POSE_KEYS}
        return Pose3.from_xyz_rpy(**vals)


def parse_rig(data: Any, *, source: str = "rig") -> Rig:
    """Validate a rig mapping (as loaded from YAML) and build the :class:`Rig`.

    Raises:
        RigError: naming ``source`` and the offending key.
    """
    c = _Checker(source)
    if data is None:
        raise c.fail("", "is empty")
    # `calibration`: the provenance block `studio calibrate` writes; informational, not read here
    keys = ("base_frame", "odometry", "camera", "lasers", "sync", "calibration")
    top = c.mapping(data, "", keys, ("base_frame",))
    base_frame = _norm_frame(c.string(top["base_frame"], "base_frame"))
    if not base_frame:
        raise c.fail("base_frame", "must name a frame")

    odometry = None
    if top.get("odometry") is not None:
        o = c.mapping(top["odometry"], "odometry", ("topic", "tf"))
        if ("topic" in o) == ("tf" in o):
            raise c.fail("odometry", "needs exactly one of 'topic' (nav_msgs/Odometry) or 'tf' (odom frame)")
        if "topic" in o:
            odometry = OdometryConfig(topic=c.string(o["topic"], "odometry.topic"))
        else:
            odometry = OdometryConfig(tf=c.string(o["tf"], "odometry.tf"))

    camera = None
    if top.get("camera") is not None:
        cm = c.mapping(top["camera"], "camera", ("topic", "pose", "lens_offset"), ("topic",))
        pose = c.pose(cm["pose"], "camera.pose") if cm.get("pose") is not None else None
        lens = c.number(cm.get("lens_offset", 0.0), "camera.lens_offset")
        if abs(lens) >= MAX_LENS_OFFSET_M:
            raise c.fail(
                "camera.lens_offset",
                f"must be within ±{MAX_LENS_OFFSET_M} m (the lens centres' offset from the camera "
                f"centre), got {lens}",
            )
        camera = CameraConfig(topic=c.string(cm["topic"], "camera.topic"), pose=pose, lens_offset=lens)

    lasers: list[LaserConfig] = []
    raw_lasers = top.get("lasers")
    if raw_lasers is not None:
        if not isinstance(raw_lasers, list):
            raise c.fail("lasers", f"must be a list of {{topic, pose}}, got {type(raw_lasers).__name__}")
        for i, item in enumerate(raw_lasers):
            key = f"lasers[{i}]"
            lm = c.mapping(item, key, ("topic", "pose", "cloud"), ("topic",))
            lpose = c.pose(lm["pose"], f"{key}.pose") if lm.get("pose") is not None else None
            topic = c.string(lm["topic"], f"{key}.topic")
            if any(x.topic == topic for x in lasers):
                raise c.fail(f"{key}.topic", f"'{topic}' is listed twice")
            cloud = None
            if lm.get("cloud") is not None:
                cm = c.mapping(lm["cloud"], f"{key}.cloud", _CLOUD_KEYS, ("min_z", "max_z"))
                # step_deg: null (or left out) is the lidar's own column spacing
                vals = {
                    k: c.number(v, f"{key}.cloud.{k}")
                    for k, v in cm.items()
                    if not (k == "step_deg" and v is None)
                }
                try:
                    cloud = CloudSlice(**vals)
                except ValueError as exc:
                    raise c.fail(f"{key}.cloud", str(exc)) from None
            lasers.append(LaserConfig(topic=topic, pose=lpose, cloud=cloud))
    if not lasers and camera is None:
        raise c.fail("lasers", "a rig needs at least one laser or a camera (neither is given)")

    sync = SyncConfig()
    if top.get("sync") is not None:
        s = c.mapping(top["sync"], "sync", ("max_dt_s", "camera_latency_s"))
        max_dt = c.number(s.get("max_dt_s", 0.05), "sync.max_dt_s")
        if max_dt < 0:
            raise c.fail("sync.max_dt_s", f"must be >= 0, got {max_dt}")
        sync = SyncConfig(
            max_dt_s=max_dt,
            camera_latency_s=c.number(s.get("camera_latency_s", 0.0), "sync.camera_latency_s"),
        )

    return Rig(base_frame=base_frame, odometry=odometry, camera=camera, lasers=tuple(lasers), sync=sync)


def load_rig(path: str | os.PathLike[str]) -> Rig:
    """Read and validate a rig.yaml file.

    Raises:
        RigError: the file is missing, is not YAML, or is not a valid rig (the message names file and key).
    """
    p = Path(path)
    try:
        text = p.read_text(encoding="utf-8")
    except FileNotFoundError:
        raise RigError(f"rig file not found: {p}") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise RigError(f"cannot read rig file {p}: {exc}") from None
    try:
        data = load_yaml(text)
    except yaml.YAMLError as exc:
        mark = getattr(exc, "problem_mark", None)
        where = f" (line {mark.line + 1}, column {mark.column + 1})" if mark is not None else ""
        problem = getattr(exc, "problem", None) or "invalid YAML"
        raise RigError(f"{p}: not valid YAML{where}: {problem}") from None
    return parse_rig(data, source=str(p))


def save_rig(rig: Rig, path: str | os.PathLike[str]) -> None:
    """Write ``rig`` as rig.yaml (atomically)."""
    text = yaml.safe_dump(rig.to_dict(), sort_keys=False, default_flow_style=None)
    atomic_write_text(path, text)
    # the atomic writer's temporary file is private (0600): give the rig the usual mode for a user file
    umask = os.umask(0)
    os.umask(umask)
    os.chmod(path, 0o666 & ~umask)
