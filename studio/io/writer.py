"""Write a ROS2 bag (MCAP storage) with rosbags' rosbag2 Writer — used by the simulator and tests.

``RecordingWriter("x/recording.mcap")`` writes one self-contained ``.mcap`` file (ROS2 profile, CDR
messages with their ``ros2msg`` schemas), readable by rosbags' AnyReader, by the ROS2 tools and by Rerun's
MCAP loader. Any other path is written as a rosbag2 directory (``metadata.yaml`` + ``<name>.mcap``).
The output appears only when the writer closes without error (it is built in a temporary sibling).

Messages should be written in roughly increasing log time (readers sort by log time).
"""

from __future__ import annotations

import contextlib
import os
import shutil
import tempfile
from collections.abc import Iterable
from pathlib import Path
from types import TracebackType
from typing import Any

import numpy as np
from numpy.typing import NDArray

from studio.geometry.se import Pose3
from studio.io.base import LaserScan, Odometry
from studio.io.errors import RecordingError

__all__ = ["RecordingWriter"]

_STATIC_QOS_YAML = None  # built lazily (needs rosbags' enums)


def _time(store: Any, stamp_ns: int) -> Any:
    sec, nsec = divmod(int(stamp_ns), 1_000_000_000)
    return store.types["builtin_interfaces/msg/Time"](sec=sec, nanosec=nsec)


def _header(store: Any, stamp_ns: int, frame_id: str) -> Any:
    return store.types["std_msgs/msg/Header"](stamp=_time(store, stamp_ns), frame_id=frame_id)


def _static_qos() -> list[Any]:
    from rosbags.interfaces import Qos, QosDurability, QosHistory, QosLiveliness, QosReliability, QosTime

    zero = QosTime(0, 0)
    return [
        Qos(
            QosHistory.KEEP_LAST, 1, QosReliability.RELIABLE, QosDurability.TRANSIENT_LOCAL,
            zero, zero, QosLiveliness.AUTOMATIC, zero, False,
        )
    ]  # fmt: skip


class RecordingWriter:
    """Writes a ROS2 MCAP recording. Use as a context manager.

    Args:
        path: output ``.mcap`` file, or a rosbag2 directory for any other suffix.
        overwrite: replace an existing output (else :class:`RecordingError`).

    Raises:
        RecordingError: the output exists (without ``overwrite``) or cannot be written.
    """

    def __init__(self, path: str | os.PathLike[str], *, overwrite: bool = False) -> None:
        from rosbags.typesys import Stores, get_typestore

        self.path = Path(path)
        self.overwrite = overwrite
        if self.path.exists() and not overwrite:
            raise RecordingError(f"{self.path} exists already (not overwriting)")
        self._store = get_typestore(Stores.ROS2_HUMBLE)
        self._writer: Any = None
        self._tmp: Path | None = None
        self._conns: dict[str, tuple[str, Any]] = {}
        self._last_log_ns = 0
        self.counts: dict[str, int] = {}

    # -- life cycle -----------------------------------------------------------------------------------
    def open(self) -> RecordingWriter:
        from rosbags.rosbag2 import StoragePlugin, Writer

        if self._writer is not None:
            return self
        self.path.parent.mkdir(parents=True, exist_ok=True)
        self._tmp = Path(tempfile.mkdtemp(prefix=f".{self.path.stem}.", suffix=".tmp", dir=self.path.parent))
        bag_dir = self._tmp / self.path.stem
        try:
            self._writer = Writer(bag_dir, version=9, storage_plugin=StoragePlugin.MCAP)
            self._writer.open()
        except Exception as exc:
            self._cleanup()
            raise RecordingError(f"cannot write {self.path}: {exc}") from exc
        return self

    def __enter__(self) -> RecordingWriter:
        return self.open()

    def __exit__(
        self, exc_type: type[BaseException] | None, exc: BaseException | None, tb: TracebackType | None
    ) -> None:
        if exc_type is None:
            self.close()
        else:
            self.abort()

    def close(self) -> None:
        """Finish the file (index, summary, metadata) and move it into place."""
        if self._writer is None:
            return
        writer, self._writer = self._writer, None
        assert self._tmp is not None
        bag_dir = self._tmp / self.path.stem
        try:
            writer.close()
            src: Path = bag_dir / f"{bag_dir.name}.mcap" if self.path.suffix == ".mcap" else bag_dir
            if self.path.exists():
                if self.path.is_dir():
                    shutil.rmtree(self.path)
                else:
                    self.path.unlink()
            os.replace(src, self.path)
        except Exception as exc:
            raise RecordingError(f"cannot write {self.path}: {exc}") from exc
        finally:
            self._cleanup()

    def abort(self) -> None:
        """Drop everything written so far (no output file)."""
        writer, self._writer = self._writer, None
        if writer is not None:
            with contextlib.suppress(Exception):
                writer.abort()
        self._cleanup()

    def _cleanup(self) -> None:
        tmp, self._tmp = self._tmp, None
        if tmp is not None:
            shutil.rmtree(tmp, ignore_errors=True)

    # -- low level ------------------------------------------------------------------------------------
    def _conn(self, topic: str, msgtype: str, *, static: bool = False) -> Any:
        if self._writer is None:
            raise RecordingError("RecordingWriter is not open (use it as a context manager)")
        have = self._conns.get(topic)
        if have is not None:
            if have[0] != msgtype:
                raise RecordingError(f"topic {topic} was written as {have[0]}, not {msgtype}")
            return have[1]
        qos = _static_qos() if static else ()
        conn = self._writer.add_connection(topic, msgtype, typestore=self._store, offered_qos_profiles=qos)
        self._conns[topic] = (msgtype, conn)
        self.counts[topic] = 0
        return conn

    def write_message(self, topic: str, msgtype: str, msg: Any, *, log_ns: int, static: bool = False) -> None:
        """Write any message of the ROS2 Humble type store (``msgtype`` like ``sensor_msgs/msg/Imu``)."""
        conn = self._conn(topic, msgtype, static=static)
        data = self._store.serialize_cdr(msg, msgtype)
        self._writer.write(conn, int(log_ns), data)
        self.counts[topic] += 1
        self._last_log_ns = max(self._last_log_ns, int(log_ns))

    @property
    def types(self) -> Any:
        """Message classes of the type store, e.g. ``writer.types["sensor_msgs/msg/Imu"]``."""
        return self._store.types

    # -- studio types ---------------------------------------------------------------------------------
    def write_scan(self, topic: str, scan: LaserScan, *, log_ns: int | None = None) -> None:
        """sensor_msgs/LaserScan from a :class:`LaserScan` (log time = header stamp unless given)."""
        n = len(scan)
        msg = self.types["sensor_msgs/msg/LaserScan"](
            header=_header(self._store, scan.stamp_ns, scan.frame_id),
            angle_min=float(scan.angle_min),
            angle_max=float(scan.angle_min + scan.angle_increment * max(n - 1, 0)),
            angle_increment=float(scan.angle_increment),
            time_increment=float(scan.time_increment),
            scan_time=0.0,  # the time between scans: not known here
            range_min=float(scan.range_min),
            range_max=float(scan.range_max),
            ranges=np.ascontiguousarray(scan.ranges, dtype=np.float32),
            intensities=(
                np.zeros(0, np.float32)
                if scan.intensities is None
                else np.ascontiguousarray(scan.intensities, dtype=np.float32)
            ),
        )
        self.write_message(
            topic, "sensor_msgs/msg/LaserScan", msg, log_ns=scan.stamp_ns if log_ns is None else log_ns
        )

    def write_compressed_image(
        self,
        topic: str,
        stamp_ns: int,
        frame_id: str,
        data: bytes,
        format: str = "jpeg",
        *,
        log_ns: int | None = None,
    ) -> None:
        """sensor_msgs/CompressedImage with already encoded bytes (``format`` "jpeg" or "png")."""
        msg = self.types["sensor_msgs/msg/CompressedImage"](
            header=_header(self._store, stamp_ns, frame_id),
            format=format,
            data=np.frombuffer(bytes(data), dtype=np.uint8),
        )
        self.write_message(
            topic, "sensor_msgs/msg/CompressedImage", msg, log_ns=stamp_ns if log_ns is None else log_ns
        )

    def write_image(
        self, topic: str, stamp_ns: int, frame_id: str, image: NDArray[np.uint8], *, log_ns: int | None = None
    ) -> None:
        """sensor_msgs/Image, ``bgr8`` from a uint8 (H, W, 3) BGR image or ``mono8`` from (H, W)."""
        img = np.ascontiguousarray(image, dtype=np.uint8)
        if img.ndim == 2:
            enc, ch = "mono8", 1
        elif img.ndim == 3 and img.shape[2] == 3:
            enc, ch = "bgr8", 3
        else:
            raise ValueError(f"image must be (H, W, 3) or (H, W), got {img.shape}")
        h, w = img.shape[:2]
        msg = self.types["sensor_msgs/msg/Image"](
            header=_header(self._store, stamp_ns, frame_id),
            height=h,
            width=w,
            encoding=enc,
            is_bigendian=0,
            step=w * ch,
            data=img.reshape(-1),
        )
        self.write_message(topic, "sensor_msgs/msg/Image", msg, log_ns=stamp_ns if log_ns is None else log_ns)

    def write_odometry(
        self,
        topic: str,
        odom: Odometry,
        *,
        vx: float = 0.0,
        vy: float = 0.0,
        wz: float = 0.0,
        log_ns: int | None = None,
    ) -> None:
        """nav_msgs/Odometry from a planar :class:`Odometry` and its body-frame twist (m/s, rad/s)."""
        T = self.types
        half = 0.5 * odom.pose.yaw
        pose = T["geometry_msgs/msg/Pose"](
            position=T["geometry_msgs/msg/Point"](x=float(odom.pose.x), y=float(odom.pose.y), z=0.0),
            orientation=T["geometry_msgs/msg/Quaternion"](
                x=0.0, y=0.0, z=float(np.sin(half)), w=float(np.cos(half))
            ),
        )
        twist = T["geometry_msgs/msg/Twist"](
            linear=T["geometry_msgs/msg/Vector3"](x=float(vx), y=float(vy), z=0.0),
            angular=T["geometry_msgs/msg/Vector3"](x=0.0, y=0.0, z=float(wz)),
        )
        msg = T["nav_msgs/msg/Odometry"](
            header=_header(self._store, odom.stamp_ns, odom.frame_id),
            child_frame_id=odom.child_frame_id,
            pose=T["geometry_msgs/msg/PoseWithCovariance"](pose=pose, covariance=np.zeros(36)),
            twist=T["geometry_msgs/msg/TwistWithCovariance"](twist=twist, covariance=np.zeros(36)),
        )
        self.write_message(
            topic, "nav_msgs/msg/Odometry", msg, log_ns=odom.stamp_ns if log_ns is None else log_ns
        )

    def write_tf(
        self,
        transforms: Iterable[tuple[str, str, int, Pose3]],
        *,
        static: bool,
        log_ns: int | None = None,
        topic: str | None = None,
    ) -> None:
        """tf2_msgs/TFMessage on ``/tf`` (or ``/tf_static`` when ``static``) from
        ``(parent, child, stamp_ns, T_parent_child)`` tuples. Log time: the latest stamp unless given."""
        T = self.types
        items = []
        stamps = []
        for parent, child, stamp_ns, pose in transforms:
            x, y, z, w = _quat(pose)
            items.append(
                T["geometry_msgs/msg/TransformStamped"](
                    header=_header(self._store, stamp_ns, parent),
                    child_frame_id=child,
                    transform=T["geometry_msgs/msg/Transform"](
                        translation=T["geometry_msgs/msg/Vector3"](
                            x=float(pose.t[0]), y=float(pose.t[1]), z=float(pose.t[2])
                        ),
                        rotation=T["geometry_msgs/msg/Quaternion"](x=x, y=y, z=z, w=w),
                    ),
                )
            )
            stamps.append(int(stamp_ns))
        if not items:
            return
        if log_ns is None:
            log_ns = max(stamps) if max(stamps) > 0 else self._last_log_ns
        name = topic or ("/tf_static" if static else "/tf")
        self.write_message(name, "tf2_msgs/msg/TFMessage", T["tf2_msgs/msg/TFMessage"](transforms=items),
                           log_ns=log_ns, static=static)  # fmt: skip


def _quat(pose: Pose3) -> tuple[float, float, float, float]:
    from studio.io.tf import quat_from_rot

    q = quat_from_rot(pose.R)
    return float(q[0]), float(q[1]), float(q[2]), float(q[3])
