"""Synchronise a recording into labeled frames (DESIGN.md §2: a frame is an image, or a scan of the
first laser for a laser-only rig).

Streaming: the odometry topic and the TF tree are read first (a light pass: small messages only); then
images and scans are read in one pass in log-time order. A frame waits in a bounded window until every
laser has sent a scan stamped after ``frame + max_dt`` (so no closer scan can come) or ``window_s`` of log
time has passed; scans are kept only as long as a pending or future frame can use them. Memory therefore
stays flat with bag length: pending images keep their compressed bytes and are decoded when the frame is
yielded; the odometry track is kept whole but compact (32 bytes per sample, ~6 MB per hour at 50 Hz).
Per-topic header stamps are assumed to increase (as recorded by ROS drivers).
"""

from __future__ import annotations

import dataclasses
import math
from array import array
from collections import Counter, deque
from collections.abc import Iterator
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from studio.geometry.equirect import not_equirect
from studio.geometry.se import Pose2, Pose3
from studio.io.base import CloudSlice, Frame, LaserScan, ScanInBase
from studio.io.decode import (
    decode_odometry,
    decode_panorama,
    decode_scan,
    looks_dual_fisheye,
    norm_frame,
    stamp_ns_of,
)
from studio.io.errors import RecordingError, TfError
from studio.io.reader import Recording
from studio.io.rig import LaserConfig, Rig
from studio.io.tf import TfBuffer, tf_topics

__all__ = [
    "LaserSyncStats",
    "SyncReport",
    "count_frames",
    "iter_frames",
    "resolve_sensor_poses",
    "unplaced_reason",
]

DROP_NO_ODOMETRY = "no odometry at the frame stamp"
DROP_BAD_IMAGE = "undecodable image"
DROP_BAD_SCAN = "undecodable scan"
DROP_NOT_AFTER = "a duplicate or out-of-order stamp"
_UPRIGHT_MIN_COS = 0.5  # the base frame's z axis within 60° of the odometry frame's

_IMAGE_TYPES = ("CompressedImage", "Image", "RawImage")
_SCAN_TYPES = ("LaserScan", "MultiEchoLaserScan", "PointCloud2")
_ODOM_TYPES = ("Odometry", "PoseInFrame", "PoseStamped")


@dataclass
class LaserSyncStats:
    """Per-laser sync counts: frames with / without a scan, |scan stamp − frame stamp| (ns), and the first
    and last stamp of the scans read (None: none)."""

    attached: int = 0
    missing: int = 0
    sum_dt_ns: int = 0
    max_dt_ns: int = 0
    span_ns: tuple[int, int] | None = None


@dataclass
class SyncReport:
    """What :func:`iter_frames` yielded, dropped and why.

    Attributes:
        anchor: what makes a frame (``"camera images on /x"`` or ``"scans of /y"``).
        candidates: frames seen (images, or first-laser scans).
        frames: frames yielded.
        dropped: reason → frames dropped for it.
        lasers: laser topic → attached / missing counts and |scan − frame| stamp differences.
        uncompensated_scans: scans attached without motion compensation (no odometry at the scan stamp).
        skipped_scans: reason → scans left out of frames (undecodable, no TF for the laser …).
        warnings: set-up warnings (no odometry, odometry frame mismatch …).
        anchor_span_ns: first and last stamp of the frames seen (None: none).
        odometry_span_ns: first and last stamp of the odometry topic's messages (None: none, or odometry
            from TF).
        first_error: drop reason → the error of the first frame dropped for it, where one was raised (an
            image that does not decode says why: an unsupported encoding, corrupt bytes …).
    """

    anchor: str = ""
    candidates: int = 0
    frames: int = 0
    dropped: Counter[str] = field(default_factory=Counter)
    lasers: dict[str, LaserSyncStats] = field(default_factory=dict)
    uncompensated_scans: int = 0
    skipped_scans: Counter[str] = field(default_factory=Counter)
    warnings: list[str] = field(default_factory=list)
    anchor_span_ns: tuple[int, int] | None = None
    odometry_span_ns: tuple[int, int] | None = None
    first_error: dict[str, str] = field(default_factory=dict)

    def drop(self, reason: str, error: Exception | None = None) -> None:
        """Count a frame dropped for ``reason`` (keeping the first ``error``'s text)."""
        self.dropped[reason] += 1
        if error is not None:
            self.first_error.setdefault(reason, str(error))

    def _why(self) -> str:
        return ", ".join(
            f"{r}: {n}" + (f" (first: {self.first_error[r]})" if r in self.first_error else "")
            for r, n in self.dropped.most_common()
        )

    def unsynced(self) -> list[str]:
        """Per laser that no frame got a scan of (though frames were made): one line on why."""
        out = []
        for topic, st in self.lasers.items():
            if st.attached or not self.frames:
                continue
            if st.span_ns is None or self.anchor_span_ns is None:
                out.append(f"laser {topic}: no scan could be used")
                continue
            (a, b), (c, d) = st.span_ns, self.anchor_span_ns
            out.append(
                f"laser {topic}: no scan within max_dt of any frame: the scans' stamps span "
                f"{a * 1e-9:.3f}–{b * 1e-9:.3f} s, the frames' {c * 1e-9:.3f}–{d * 1e-9:.3f} s "
                "(are they stamped by different clocks?)"
            )
        return out

    def warn(self, text: str) -> None:
        if text not in self.warnings:
            self.warnings.append(text)

    def as_dict(self) -> dict[str, Any]:
        """Plain-JSON form (for run.json)."""
        return {
            "anchor": self.anchor,
            "candidates": self.candidates,
            "frames": self.frames,
            "dropped": dict(self.dropped),
            "first_error": dict(self.first_error),
            "lasers": {
                t: {
                    "attached": s.attached,
                    "missing": s.missing,
                    "mean_dt_ms": s.sum_dt_ns / s.attached / 1e6 if s.attached else None,
                    "max_dt_ms": s.max_dt_ns / 1e6,
                }
                for t, s in self.lasers.items()
            },
            "uncompensated_scans": self.uncompensated_scans,
            "skipped_scans": dict(self.skipped_scans),
            "warnings": list(self.warnings),
        }

    def dropped_note(self) -> str | None:
        """One line on the frames dropped, or None when none was."""
        n_drop = sum(self.dropped.values())
        if not n_drop:
            return None
        return f"{n_drop} of {self.candidates} frames dropped ({self._why()})"

    def why_empty(self) -> str:
        """One line on why no frame was yielded."""
        if self.candidates == 0:
            return f"there are no {self.anchor} in the recording"
        for reason in (DROP_BAD_IMAGE, DROP_BAD_SCAN):
            if self.dropped[reason] == self.candidates and reason in self.first_error:
                return f"none of the {self.candidates} {self.anchor} decodes ({self.first_error[reason]})"
        odo, fr = self.odometry_span_ns, self.anchor_span_ns
        if self.dropped[DROP_NO_ODOMETRY] == self.candidates and odo is not None and fr is not None:
            return (
                f"no odometry at any frame stamp: the odometry's stamps span {odo[0] * 1e-9:.3f}–"
                f"{odo[1] * 1e-9:.3f} s, the frames' {fr[0] * 1e-9:.3f}–{fr[1] * 1e-9:.3f} s "
                "(are they stamped by different clocks?)"
            )
        return "; ".join(self.summary().splitlines())

    def summary(self) -> str:
        """Readable multi-line summary."""
        lines = [f"frames: {self.frames} yielded of {self.candidates} ({self.anchor})"]
        n_drop = sum(self.dropped.values())
        if n_drop:
            lines.append(f"dropped: {n_drop} ({self._why()})")
        for topic, st in self.lasers.items():
            mean = st.sum_dt_ns / st.attached / 1e6 if st.attached else 0.0
            lines.append(
                f"laser {topic}: scan in {st.attached} frames (|dt| mean {mean:.1f} ms, max "
                f"{st.max_dt_ns / 1e6:.1f} ms), none within max_dt in {st.missing}"
            )
        if self.uncompensated_scans:
            lines.append(
                f"scans not motion-compensated (no odometry at scan stamp): {self.uncompensated_scans}"
            )
        for reason, n in self.skipped_scans.most_common():
            lines.append(f"scans left out ({reason}): {n}")
        lines += [f"warning: {w}" for w in self.warnings]
        return "\n".join(lines)


def _check_topic(rec: Recording, name: str, role: str, types: tuple[str, ...]) -> str:
    try:
        topic = rec.resolve_topic(name)
    except RecordingError:
        have = ", ".join(f"{t} ({i.msgtype})" for t, i in rec.topics.items()) or "none"
        raise RecordingError(
            f"{rec.path}: the rig's {role} topic '{name}' is not in the recording (it has: {have})"
        ) from None
    msgtype = rec.topics[topic].msgtype
    if not msgtype.endswith(types):
        raise RecordingError(
            f"{rec.path}: the rig's {role} topic '{name}' carries {msgtype}, expected {' or '.join(types)}"
        )
    return topic


def count_frames(rec: Recording, rig: Rig) -> int:
    """Frame candidates (images, or first-laser scans) from the topic index: a progress bar's total."""
    if rig.camera:
        topic = _check_topic(rec, rig.camera.topic, "camera", _IMAGE_TYPES)
    else:
        topic = check_laser_topic(rec, rig.lasers[0])
    return rec.topics[topic].count


class _OdomTrack:
    """T_odom_base(t) from a nav_msgs/Odometry topic, linear in x, y and (unwrapped) yaw."""

    def __init__(self, stamps: array[int], xyyaw: array[float], tolerance_ns: int) -> None:
        s = np.frombuffer(stamps, dtype=np.int64) if len(stamps) else np.zeros(0, np.int64)
        order = np.argsort(s, kind="stable")
        self.s = s[order]
        a = (np.frombuffer(xyyaw, dtype=np.float64) if len(xyyaw) else np.zeros(0)).reshape(-1, 3)[order]
        self.x, self.y, self.yaw = a[:, 0], a[:, 1], np.unwrap(a[:, 2]) if len(a) else a[:, 2]
        self.tol = tolerance_ns

    def at(self, t: int) -> Pose2 | None:
        s = self.s
        if len(s) == 0 or t < s[0] - self.tol or t > s[-1] + self.tol:
            return None
        if len(s) == 1:
            return Pose2(float(self.x[0]), float(self.y[0]), float(self.yaw[0]))
        i = int(np.clip(np.searchsorted(s, t, side="right"), 1, len(s) - 1))
        s0, s1 = int(s[i - 1]), int(s[i])
        u = 0.0 if s1 == s0 else min(max((t - s0) / (s1 - s0), 0.0), 1.0)
        return Pose2(
            float((1 - u) * self.x[i - 1] + u * self.x[i]),
            float((1 - u) * self.y[i - 1] + u * self.y[i]),
            float(math.remainder((1 - u) * self.yaw[i - 1] + u * self.yaw[i], 2 * math.pi)),
        )


class _Motion:
    """T_odom_base(t) as a Pose3, from the rig's odometry source (or identity for a static robot)."""

    def __init__(self, rec: Recording, rig: Rig, tf: TfBuffer | None, report: SyncReport) -> None:
        self.track: _OdomTrack | None = None
        self.tf = tf
        self.odom_frame: str | None = None
        self.child: str = ""
        self.base = rig.base_frame
        cfg = rig.odometry
        tol = tf.tolerance_ns if tf is not None else 100_000_000
        if cfg is None:
            report.warn(
                "the rig has no odometry: studio label's scan matching estimates the motion from the lasers "
                "(the labels' robot_pose and odom positions are in its frame)"
            )
        elif cfg.topic is not None:
            topic = _check_topic(rec, cfg.topic, "odometry", _ODOM_TYPES)
            stamps = array("q")  # compact: 8 + 24 bytes per sample
            vals = array("d")
            children: set[str] = set()
            bad, why = 0, ""
            for raw in rec.messages([topic]):
                try:
                    od = decode_odometry(rec.decode(raw), raw.log_ns)
                except RecordingError as exc:
                    bad += 1
                    why = why or str(exc)
                    continue
                stamps.append(od.stamp_ns)
                vals.extend((od.pose.x, od.pose.y, od.pose.yaw))
                children.add(od.child_frame_id)
            if bad:
                report.warn(f"{bad} odometry messages on {topic} could not be decoded (the first: {why})")
            if not stamps:
                report.warn(f"odometry topic {topic} has no usable messages")
            else:
                report.odometry_span_ns = (min(stamps), max(stamps))
            self.track = _OdomTrack(stamps, vals, tol)
            child = next(iter(children)) if len(children) == 1 else ""
            if child and child != self.base:
                if tf is not None and tf.can_transform(child, self.base):
                    self.child = child
                else:
                    report.warn(
                        f"odometry child frame '{child}' is not the rig base_frame '{self.base}' and TF does "
                        f"not relate them: the odometry pose is taken as the base pose"
                    )
        else:
            assert cfg.tf is not None
            if tf is None:
                tf = TfBuffer()
            try:
                tf.require(cfg.tf, self.base)
            except TfError as exc:
                raise TfError(
                    f"rig odometry {{tf: {cfg.tf}}} needs TF {cfg.tf} → {self.base}: {exc}"
                ) from None
            self.odom_frame = cfg.tf
            self.tf = tf

    @property
    def known(self) -> bool:
        """Whether odometry or TF gives the robot's motion (else it is taken as static)."""
        return self.track is not None or self.odom_frame is not None

    def at(self, t: int) -> Pose3 | None:
        if self.track is not None:
            p = self.track.at(t)
            if p is None:
                return None
            T = Pose3.from_xyz_rpy(p.x, p.y, 0.0, 0.0, 0.0, p.yaw)
            if self.child:
                assert self.tf is not None
                try:
                    T = T.compose(self.tf.lookup(self.child, self.base, t))
                except TfError:
                    return None
            return T
        if self.odom_frame is not None:
            assert self.tf is not None
            try:
                return self.tf.lookup(self.odom_frame, self.base, t)
            except TfError:
                return None
        return Pose3.identity()


@dataclass
class _Pending:
    stamp: int
    log_ns: int
    image_msg: Any  # decoded image message (pixels decoded when the frame is yielded)
    best: list[tuple[int, LaserScan] | None]


def check_laser_topic(rec: Recording, laser: LaserConfig) -> str:
    """The recording's name of a laser's topic, checked: a LaserScan, or a PointCloud2 with ``cloud``.

    Raises:
        RecordingError: the topic is missing, carries another type, or a cloud without ``cloud`` (or the
            other way round).
    """
    topic = _check_topic(rec, laser.topic, "laser", _SCAN_TYPES)
    is_cloud = rec.topics[topic].msgtype.endswith("PointCloud2")
    if is_cloud and laser.cloud is None:
        raise RecordingError(
            f"{rec.path}: the rig's laser topic '{laser.topic}' carries PointCloud2 (a 3-D lidar): give the "
            "height band to slice into a planar scan, e.g. 'cloud: {min_z: -0.6, max_z: -0.2}' (metres in "
            "the cloud's frame: legs 0.2-0.6 m above the floor for a lidar 0.8 m up)"
        )
    if not is_cloud and laser.cloud is not None:
        raise RecordingError(
            f"{rec.path}: the rig's laser topic '{laser.topic}' carries "
            f"{rec.topics[topic].msgtype}, not PointCloud2: drop its 'cloud' entry"
        )
    return topic


def _first_frame_id(rec: Recording, topic: str, cloud: CloudSlice | None) -> str | None:
    """Frame id of the first decodable scan on ``topic``."""
    for raw in rec.messages([topic]):
        try:
            return decode_scan(rec.decode(raw), raw.log_ns, cloud=cloud).frame_id
        except RecordingError:
            continue
    return None


def _first_frame(rec: Recording, topic: str) -> tuple[str, int] | None:
    """The ``frame_id`` (normalised) and stamp of a topic's first message; None when it has none or does
    not decode."""
    raw = next(iter(rec.messages([rec.resolve_topic(topic)])), None) if rec.has_topic(topic) else None
    if raw is None:
        return None
    try:
        msg = rec.decode(raw)
    except RecordingError:
        return None
    header = getattr(msg, "header", None)
    return norm_frame(getattr(header, "frame_id", getattr(msg, "frame_id", ""))), stamp_ns_of(msg, raw.log_ns)


def resolve_sensor_poses(rec: Recording, rig: Rig, *, tf: TfBuffer | None = None) -> Rig:
    """A copy of ``rig`` where each sensor without a pose gets its static T_base_sensor from the TF tree.

    The sensor's frame is the ``frame_id`` of its first message. A sensor that TF cannot place (or only
    through moving edges) keeps ``pose=None`` (:func:`unplaced_reason` says why); iter_frames then looks
    laser poses up per scan.
    """
    if rig.camera is not None and rig.camera.pose is not None and all(x.pose is not None for x in rig.lasers):
        return rig
    if tf is None:
        tf = TfBuffer.from_recording(rec) if tf_topics(rec) else TfBuffer()

    def static_pose(topic: str) -> Pose3 | None:
        first = _first_frame(rec, topic)
        if first is None:
            return None
        frame, stamp = first
        if (
            not frame
            or not tf.can_transform(rig.base_frame, frame)
            or not tf.is_static_path(rig.base_frame, frame)
        ):
            return None
        return tf.lookup(rig.base_frame, frame, stamp)

    camera = rig.camera
    if camera is not None and camera.pose is None:
        camera = dataclasses.replace(camera, pose=static_pose(camera.topic))
    lasers = tuple(
        x if x.pose is not None else dataclasses.replace(x, pose=static_pose(x.topic)) for x in rig.lasers
    )
    return dataclasses.replace(rig, camera=camera, lasers=lasers)


def unplaced_reason(rec: Recording, rig: Rig, topic: str, *, tf: TfBuffer | None = None) -> tuple[bool, str]:
    """Why :func:`resolve_sensor_poses` left the sensor of ``topic`` without a pose: ``(moving, text)``,
    ``moving`` True when TF places it only through edges that move (a laser is then looked up scan by
    scan; a camera cannot be), ``text`` a clause for a message."""
    if tf is None:
        tf = TfBuffer.from_recording(rec) if tf_topics(rec) else TfBuffer()
    first = _first_frame(rec, topic)
    if first is None:
        return False, f"{topic} has no message that decodes, to read its frame_id from"
    frame = first[0]
    if not frame:
        return False, f"the messages of {topic} have no frame_id"
    if not tf_topics(rec):
        return False, f"its frame '{frame}' is not '{rig.base_frame}' and the recording has no TF"
    if not tf.can_transform(rig.base_frame, frame):
        return (
            False,
            f"its frame '{frame}' is not connected to base_frame '{rig.base_frame}' in the recording's TF",
        )
    return True, f"its frame '{frame}' moves relative to base_frame '{rig.base_frame}' in the recording's TF"


def iter_frames(
    rec: Recording,
    rig: Rig,
    *,
    report: SyncReport | None = None,
    tf: TfBuffer | None = None,
    window_s: float = 2.0,
) -> Iterator[Frame]:
    """Yield the synchronised frames of a recording.

    Args:
        rec: an open recording.
        rig: the sensor set-up.
        report: filled with counts of what was yielded and dropped (see :class:`SyncReport`).
        tf: a TF buffer already built from ``rec`` (else it is read when needed).
        window_s: longest wait (log time, s) for the scans of a frame before it is resolved.

    Raises:
        RecordingError: a topic of the rig is missing from the recording or has the wrong type; a camera
            image is not an equirectangular panorama (2:1) or its size changes within the recording.
        TfError: the rig needs a transform (laser pose, odometry frame) the TF tree cannot give.
    """
    rep = report if report is not None else SyncReport()
    max_dt = rig.sync.max_dt_ns
    latency = rig.sync.camera_latency_ns
    window_ns = int(window_s * 1e9)

    cam_topic = _check_topic(rec, rig.camera.topic, "camera", _IMAGE_TYPES) if rig.camera else None
    laser_topics = [check_laser_topic(rec, x) for x in rig.lasers]
    rep.anchor = f"camera images on {cam_topic}" if cam_topic else f"scans of {laser_topics[0]}"
    for x in rig.lasers:
        rep.lasers.setdefault(x.topic, LaserSyncStats())

    need_tf = any(x.pose is None for x in rig.lasers) or rig.odometry is not None
    if tf is None and need_tf and tf_topics(rec):
        tf = TfBuffer.from_recording(rec)
    if tf is None:
        tf = TfBuffer()
    motion = _Motion(rec, rig, tf, rep)

    # laser poses: from the rig, else TF (checked now on each laser's first scan, for a clear error)
    static_pose: list[Pose3 | None] = [x.pose for x in rig.lasers]
    for k, (cfg, topic) in enumerate(zip(rig.lasers, laser_topics, strict=True)):
        if cfg.pose is not None:
            continue
        frame_id = _first_frame_id(rec, topic, cfg.cloud)
        if frame_id is None:
            continue
        try:
            tf.require(rig.base_frame, frame_id)
        except TfError as exc:
            raise TfError(
                f"laser {cfg.topic} (frame '{frame_id}') has no pose in the rig and TF cannot place it in "
                f"base_frame '{rig.base_frame}': {exc}; give its pose in rig.yaml or fix base_frame"
            ) from None
        if tf.is_static_path(rig.base_frame, frame_id):
            static_pose[k] = tf.lookup(rig.base_frame, frame_id, 0)

    anchor_laser = None if cam_topic else 0
    topic_index = {t: k for k, t in enumerate(laser_topics)}
    buffers: list[deque[LaserScan]] = [deque() for _ in laser_topics]
    last_stamp: list[int | None] = [None] * len(laser_topics)
    pending: deque[_Pending] = deque()
    last_anchor: int | None = None
    n_out = 0
    pano_size: tuple[int, int] | None = None  # (width, height) of the first panorama

    def offer(p: _Pending, k: int, scan: LaserScan) -> None:
        dt = abs(scan.stamp_ns - p.stamp)
        if dt <= max_dt and (p.best[k] is None or dt < p.best[k][0]):  # type: ignore[index]
            p.best[k] = (dt, scan)

    def complete(p: _Pending, now_log: int | None) -> bool:
        if now_log is None or now_log - p.log_ns > window_ns:
            return True
        for k, ls in enumerate(last_stamp):
            if k == anchor_laser:
                continue
            if ls is None or ls <= p.stamp + max_dt:
                return False
        return True

    def laser_pose(k: int, scan: LaserScan) -> Pose3 | None:
        pose = static_pose[k]
        if pose is not None:
            return pose
        try:
            return tf.lookup(rig.base_frame, scan.frame_id, scan.stamp_ns)
        except TfError:
            return None

    def emit(p: _Pending) -> Frame | None:
        nonlocal n_out, pano_size
        T_f = motion.at(p.stamp)
        if T_f is None:
            rep.dropped[DROP_NO_ODOMETRY] += 1
            return None
        if T_f.R[2, 2] < _UPRIGHT_MIN_COS:
            # a 2-D pose of a frame upside down in the odometry frame is a mirror image, not a motion
            tilt = math.degrees(math.acos(max(-1.0, min(1.0, float(T_f.R[2, 2])))))
            raise TfError(
                f"base_frame '{rig.base_frame}' is tilted {tilt:.0f}° from upright in the odometry frame "
                "(mounted upside down?): positions in it would be mirrored; name an upright frame of the "
                "robot (e.g. base_link) as base_frame"
            )
        pano = None
        if p.image_msg is not None:
            try:
                pano = decode_panorama(p.image_msg, p.stamp + latency)
            except RecordingError as exc:
                rep.drop(DROP_BAD_IMAGE, exc)
                return None
            w, h = pano.width, pano.height
            if (wrong := not_equirect(w, h)) is not None:
                raise RecordingError(
                    f"camera topic {cam_topic}: the image at {pano.stamp_ns * 1e-9:.3f} s is {wrong}: is "
                    "this the 360° camera?"
                )
            if pano_size is None:
                if looks_dual_fisheye(pano.image):
                    raise RecordingError(
                        f"camera topic {cam_topic}: the images are two fisheye circles side by side, not an "
                        "equirectangular panorama: record the camera's stitched output (Ricoh Theta: its "
                        "equirectangular live-streaming mode) or stitch the images first"
                    )
                pano_size = (w, h)
            elif (w, h) != pano_size:
                raise RecordingError(
                    f"camera topic {cam_topic}: the image at {pano.stamp_ns * 1e-9:.3f} s is {w}×{h} px, "
                    f"the first one was {pano_size[0]}×{pano_size[1]} px; the panorama size must not change"
                )
        T_f_inv = T_f.inverse()
        scans = []
        for k, cfg in enumerate(rig.lasers):
            st = rep.lasers[cfg.topic]
            best = p.best[k]
            if best is None:
                st.missing += 1
                continue
            dt, scan = best
            T_bl = laser_pose(k, scan)
            if T_bl is None:
                rep.skipped_scans[f"no TF {rig.base_frame} → {scan.frame_id} at the scan stamp"] += 1
                st.missing += 1
                continue
            T_s = motion.at(scan.stamp_ns) if scan.stamp_ns != p.stamp else T_f
            moved = T_s is not None  # the odometry covers the scan's time
            if T_s is None:
                rep.uncompensated_scans += 1
                T_s = T_f
            pose = T_f_inv.compose(T_s).compose(T_bl)
            pose_end = None
            if scan.time_increment != 0.0 and len(scan) > 1 and moved and motion.known:
                # the robot's motion over the sweep (each beam from where the scanner was at its time)
                T_e = motion.at(scan.stamp_ns + round((len(scan) - 1) * scan.time_increment * 1e9))
                if T_e is not None:
                    pose_end = T_f_inv.compose(T_e).compose(T_bl)
            scans.append(ScanInBase(cfg.topic, scan, pose, pose_end))
            st.attached += 1
            st.sum_dt_ns += dt
            st.max_dt_ns = max(st.max_dt_ns, dt)
        frame = Frame(n_out, p.stamp, pano, tuple(scans), T_f.to_pose2())
        n_out += 1
        rep.frames += 1
        return frame

    def prune(k: int) -> None:
        buf = buffers[k]
        ref = pending[0].stamp if pending else last_anchor
        newest = buf[-1].stamp_ns if buf else 0
        while buf and (
            (ref is not None and buf[0].stamp_ns < ref - max_dt)
            or buf[0].stamp_ns < newest - window_ns
            or len(buf) > 4096
        ):
            buf.popleft()

    read_topics = ([cam_topic] if cam_topic else []) + laser_topics
    for raw in rec.messages(read_topics):
        new: _Pending | None = None
        if raw.topic == cam_topic:
            rep.candidates += 1
            try:
                msg = rec.decode(raw)
            except RecordingError as exc:
                rep.drop(DROP_BAD_IMAGE, exc)
                continue
            stamp = stamp_ns_of(msg, raw.log_ns) - latency
            new = _Pending(stamp, raw.log_ns, msg, [None] * len(laser_topics))
        else:
            k = topic_index[raw.topic]
            try:
                scan = decode_scan(rec.decode(raw), raw.log_ns, cloud=rig.lasers[k].cloud)
            except RecordingError as exc:
                if k == anchor_laser:
                    rep.candidates += 1
                    rep.drop(DROP_BAD_SCAN, exc)
                else:
                    rep.skipped_scans["undecodable"] += 1
                continue
            buffers[k].append(scan)
            st = rep.lasers[rig.lasers[k].topic]
            st.span_ns = (
                (scan.stamp_ns, scan.stamp_ns)
                if st.span_ns is None
                else (min(st.span_ns[0], scan.stamp_ns), max(st.span_ns[1], scan.stamp_ns))
            )
            ls = last_stamp[k]
            last_stamp[k] = scan.stamp_ns if ls is None else max(ls, scan.stamp_ns)
            for p in pending:
                offer(p, k, scan)
            if k == anchor_laser:
                rep.candidates += 1
                new = _Pending(scan.stamp_ns, raw.log_ns, None, [None] * len(laser_topics))
                new.best[k] = (0, scan)
        if new is not None and last_anchor is not None and new.stamp <= last_anchor:
            rep.dropped[DROP_NOT_AFTER] += 1  # a frame needs a stamp after the one before it
            new = None
        if new is not None:
            span = rep.anchor_span_ns
            rep.anchor_span_ns = (new.stamp if span is None else span[0], new.stamp)
            for k2, buf in enumerate(buffers):
                if k2 != anchor_laser:
                    for s in buf:
                        offer(new, k2, s)
            pending.append(new)
            last_anchor = new.stamp if last_anchor is None else max(last_anchor, new.stamp)
        while pending and complete(pending[0], raw.log_ns):
            frame = emit(pending.popleft())
            if frame is not None:
                yield frame
        for k2 in range(len(buffers)):
            prune(k2)
    while pending:
        frame = emit(pending.popleft())
        if frame is not None:
            yield frame
