"""Decode deserialized messages into studio's types (:mod:`studio.io.base`).

Messages are the objects of :meth:`Recording.decode`: ROS messages (ROS1 and ROS2 field names) or, from a
plain MCAP with JSON encoding, attribute trees shaped like the ROS message or like the Foxglove schemas
(``foxglove.LaserScan``, ``CompressedImage``, ``RawImage``, ``FrameTransform(s)``, ``PoseInFrame``).
A 3-D lidar's sensor_msgs/PointCloud2 is sliced into a planar scan (:class:`~studio.io.base.CloudSlice`).
The data stamp is the message header stamp; frame ids lose any leading ``/``.
"""

from __future__ import annotations

import base64
import math
from typing import Any

import numpy as np
from numpy.typing import NDArray

from studio.geometry.se import Pose2, Pose3
from studio.io.base import CloudSlice, LaserScan, Odometry, Panorama
from studio.io.errors import RecordingError

__all__ = [
    "decode_odometry",
    "decode_panorama",
    "decode_scan",
    "decode_tf",
    "image_format",
    "looks_dual_fisheye",
    "norm_frame",
    "stamp_ns_of",
    "yaw_from_quat",
]

FloatArray = NDArray[np.float64]


def norm_frame(frame_id: Any) -> str:
    """Frame id without surrounding blanks and leading ``/`` (old ROS1 bags write ``/base_link``)."""
    return str(frame_id or "").strip().lstrip("/")


def _time_ns(t: Any) -> int:
    sec = int(getattr(t, "sec", getattr(t, "secs", 0)) or 0)
    nsec = getattr(t, "nanosec", None)
    if nsec is None:
        nsec = getattr(t, "nsec", getattr(t, "nsecs", 0))
    return sec * 1_000_000_000 + int(nsec or 0)


def stamp_ns_of(msg: Any, fallback_ns: int | None = None) -> int:
    """Header stamp of ``msg`` in ns (``header.stamp`` or Foxglove ``timestamp``).

    A zero (unset) stamp is replaced by ``fallback_ns`` when given (e.g. the record's log time).
    """
    header = getattr(msg, "header", None)
    if header is not None and hasattr(header, "stamp"):
        t = _time_ns(header.stamp)
    elif hasattr(msg, "timestamp"):
        t = _time_ns(msg.timestamp)
    else:
        t = 0
    if t == 0 and fallback_ns is not None:
        return int(fallback_ns)
    return t


def _frame_of(msg: Any) -> str:
    header = getattr(msg, "header", None)
    if header is not None and hasattr(header, "frame_id"):
        return norm_frame(header.frame_id)
    return norm_frame(getattr(msg, "frame_id", ""))


def _bytes_of(data: Any) -> bytes:
    """Message payload as bytes (numpy uint8 array from rosbags, list, or base64 text from JSON)."""
    if isinstance(data, bytes | bytearray | memoryview):
        return bytes(data)
    if isinstance(data, np.ndarray):
        return data.astype(np.uint8, copy=False).tobytes()
    if isinstance(data, str):
        return base64.b64decode(data)
    return bytes(np.asarray(data, dtype=np.uint8).tobytes())


def yaw_from_quat(x: float, y: float, z: float, w: float) -> float:
    """Heading (rad) of the x axis rotated by quaternion ``(x, y, z, w)``, projected onto the plane."""
    return math.atan2(2.0 * (w * z + x * y), 1.0 - 2.0 * (y * y + z * z))


def decode_scan(msg: Any, stamp_ns: int | None = None, *, cloud: CloudSlice | None = None) -> LaserScan:
    """sensor_msgs/LaserScan (or foxglove.LaserScan; or sensor_msgs/MultiEchoLaserScan, of which each beam's
    first echo) → :class:`LaserScan`; a sensor_msgs/PointCloud2 is sliced into one as ``cloud`` says.

    Args:
        msg: the deserialized message.
        stamp_ns: used when the header stamp is zero (unset), ns; typically the log time.
        cloud: how to slice a point cloud (the rig's ``cloud`` of that laser); a cloud without it is an
            error.

    Raises:
        RecordingError: the message is not a laser scan (or a point cloud with ``cloud``).
    """
    if hasattr(msg, "point_step") and hasattr(msg, "fields"):
        if cloud is None:
            raise RecordingError(
                "a PointCloud2 (3-D lidar) needs 'cloud: {min_z, max_z}' in the rig's laser entry: the "
                "height band, metres in the cloud's frame, to slice into a planar scan"
            )
        return _slice_cloud(msg, stamp_ns, cloud)
    try:
        stamp = stamp_ns_of(msg, stamp_ns)
        frame = _frame_of(msg)
        ranges = _first_echoes(msg.ranges)
        inten_raw = getattr(msg, "intensities", None)
        inten = None if inten_raw is None else _first_echoes(inten_raw)
        if inten is not None and inten.shape != ranges.shape:
            inten = None
        if hasattr(msg, "angle_min"):
            a0, da = float(msg.angle_min), float(msg.angle_increment)
            rmin, rmax = float(msg.range_min), float(msg.range_max)
        else:  # foxglove.LaserScan: start/end angle, no range limits
            a0, a1 = float(msg.start_angle), float(msg.end_angle)
            da = (a1 - a0) / (ranges.size - 1) if ranges.size > 1 else 1.0
            rmin, rmax = 0.0, float("inf")
        if not math.isfinite(rmax) or rmax <= max(rmin, 0.0):  # no limit, or none that can hold: unknown
            rmax = float(np.finfo(np.float32).max)
        if ranges.size and da == 0.0:
            raise ValueError("angle_increment is 0")
        _check_span(msg, a0, da, ranges.size)
        # the time between beams (ROS: beam i at the header stamp + i · time_increment); a sweep said to last
        # over a second is a driver's placeholder, not a time
        ti = float(getattr(msg, "time_increment", 0.0) or 0.0)
        if not math.isfinite(ti) or abs(ti) * max(ranges.size - 1, 0) > 1.0:
            ti = 0.0
        return LaserScan(stamp, frame, a0, da, ranges, rmin, rmax, inten, ti)
    except (AttributeError, TypeError, ValueError) as exc:
        raise RecordingError(f"not a decodable laser scan: {exc}") from None


def _check_span(msg: Any, a0: float, da: float, n: int) -> None:
    """Raise ValueError where a LaserScan's ranges at its increment span more than a full turn (a driver
    or a recording tool that wrote too many: no bearing would be right). ``angle_max`` is not checked
    against them: ROS's own tools take beam i at angle_min + i · angle_increment and never read it, so
    a driver's wrong angle_max goes unnoticed and must not make its recording unreadable here."""
    span = abs(da) * (n - 1)
    if span > 2.0 * math.pi + abs(da) + 1e-9:
        said = getattr(msg, "angle_max", None)
        told = f" (angle_min to angle_max: {math.degrees(float(said) - a0):.1f}°)" if said is not None else ""
        raise ValueError(
            f"{n} ranges {math.degrees(abs(da)):.3g}° apart span {math.degrees(span):.1f}°, more than a "
            f"full turn{told}"
        )


def _first_echoes(values: Any) -> np.ndarray:
    """A scan's ranges (or intensities) as float32: as they are, or of a sensor_msgs/MultiEchoLaserScan (a
    ``LaserEcho`` per beam) each beam's first echo, the nearest return (NaN where a beam has none): a
    person in front of a wall is the first thing a beam hits."""
    if len(values) and hasattr(values[0], "echoes"):
        return np.array([e.echoes[0] if len(e.echoes) else np.nan for e in values], dtype=np.float32)
    return np.asarray(values, dtype=np.float32).reshape(-1)


# sensor_msgs/PointField datatypes
_POINT_TYPES = {1: "i1", 2: "u1", 3: "i2", 4: "u2", 5: "i4", 6: "u4", 7: "f4", 8: "f8"}


_TIME_FIELDS = ("t", "time", "timestamp", "offset_time", "time_offset")
"""Per-point time fields of common 3-D lidar drivers (Ouster ``t``, Velodyne ``time``, Hesai ``timestamp``,
Livox ``offset_time``): integer types are nanoseconds, floating ones seconds, after the stamp or (when over
10⁶ s) since the epoch."""


def _slice_cloud(msg: Any, stamp_ns: int | None, cloud: CloudSlice) -> LaserScan:
    """A PointCloud2 → the planar scan of its points in ``cloud``'s height band (see :class:`CloudSlice`).

    NaN points and (0, 0, 0) ones (many drivers' "no return") are left out. With a per-point time field
    (:data:`_TIME_FIELDS`) of a spinning lidar, the scan starts at the bearing measured first and turns
    the way the lidar turned, each beam timed by the rotation (``time_increment``), so a moving robot's
    sweep is undone as a 2-D scanner's is; a full turn's last returns, half a beam short of its start, make
    one beam more at the start's bearing (a turn later). Otherwise (no usable time field, or times that do
    not follow the bearing, as a non-repetitive scan pattern's) the beams start at -180° and are taken at
    the header stamp.
    """
    stamp = stamp_ns_of(msg, stamp_ns)
    x, y, z, raw_t, t_type, width, height = _cloud_points(msg)
    r = np.hypot(x, y)
    seen = np.isfinite(r) & np.isfinite(z) & (r >= cloud.range_min) & (r > 0)
    xs, ys, zs, rs = x[seen], y[seen], z[seen], r[seen]
    band = (zs >= cloud.min_z) & (zs <= cloud.max_z)
    az, r = np.arctan2(ys[band], xs[band]), rs[band]
    n = max(round(360.0 / _cloud_step_deg(cloud, width, height, xs, ys)), 1)
    da = 2.0 * math.pi / n
    # beam k is centred on ``start + turn·k·da`` and measured ``t0_s + k·beam_s`` after the stamp; the
    # sweep is read off all the cloud's returns (its start does not hang on which are in the band): it
    # starts at the bearing of the first return; the returns half a beam short of it a full turn later make
    # one beam more, ``n``, at the start's bearing again
    start, turn, t0_s, beam_s = -math.pi + 0.5 * da, 1.0, 0.0, 0.0
    t_band = None
    t = _point_times(raw_t[seen], t_type, stamp) if raw_t is not None and len(xs) >= 8 else None
    if t is not None:
        # a few thousand returns tell the rotation; the sweep starts at the first of all
        pick = np.arange(0, len(t), max(len(t) // _SWEEP_POINTS, 1))
        sweep = _sweep(np.arctan2(ys[pick], xs[pick]), t[pick])
        if sweep is not None:
            turn, rate = sweep
            i0 = int(np.argmin(t))
            t0_s, start, beam_s = float(t[i0]), math.atan2(ys[i0], xs[i0]), da / rate
            t_band = t[band]
    rel = np.mod(turn * (az - start) + 0.5 * da, 2.0 * math.pi)
    beam = np.minimum(np.floor(rel / da).astype(np.int64), n - 1)
    size = n
    if t_band is not None:  # the end of the turn, just short of its start
        size = n + 1
        beam[(rel < 0.5 * da) & (t_band - t0_s > 0.5 * n * beam_s)] = n
    ranges = np.full(size, np.inf)
    np.minimum.at(ranges, beam, r)
    ranges[~np.isfinite(ranges)] = np.nan
    _fill_holes(ranges)
    rmax = float(np.finfo(np.float32).max)
    first = stamp + round(t0_s * 1e9)
    return LaserScan(
        first,
        _frame_of(msg),
        start,
        turn * da,
        ranges.astype(np.float32),
        cloud.range_min,
        rmax,
        None,
        beam_s,
    )


def _cloud_points(
    msg: Any,
) -> tuple[FloatArray, FloatArray, FloatArray, NDArray[Any] | None, int, int, int]:
    """A PointCloud2's ``x, y, z`` (float64), its first usable time field's raw values and datatype (None,
    0 without one: a time field of unknown type or place is left out), width and height. Unorganised and
    organised clouds (rows padded to ``row_step``), either byte order.

    Raises:
        RecordingError: the message is not a decodable point cloud.
    """
    try:
        fields = {str(f.name): (int(f.offset), int(f.datatype)) for f in msg.fields}
        missing = [c for c in "xyz" if c not in fields]
        if missing:
            raise ValueError(f"no {'/'.join(missing)} field (it has: {', '.join(fields) or 'none'})")
        step, width, height = int(msg.point_step), int(msg.width), int(msg.height)

        def fits(name: str) -> bool:
            off, dt = fields[name]
            return dt in _POINT_TYPES and 0 <= off <= step - np.dtype(_POINT_TYPES[dt]).itemsize

        for c in "xyz":
            if fields[c][1] not in _POINT_TYPES:
                raise ValueError(f"field {c} has the unknown datatype {fields[c][1]}")
            if not fits(c):
                raise ValueError(f"field {c} (offset {fields[c][0]}) does not fit a {step}-byte point")
        names = [*"xyz", *[t for t in _TIME_FIELDS if t in fields and fits(t)][:1]]
        row_step = int(getattr(msg, "row_step", 0) or width * step)
        if width < 0 or height < 0 or row_step < width * step:
            raise ValueError(f"bad layout: {width}×{height} points of {step} bytes, rows of {row_step}")
        data = _bytes_of(msg.data)
        if len(data) < height * row_step:
            raise ValueError(
                f"data holds {len(data)} bytes, {width}×{height} points need {height * row_step}"
            )
        big = bool(getattr(msg, "is_bigendian", False))
        formats = [np.dtype(_POINT_TYPES[fields[c][1]]).newbyteorder(">" if big else "<") for c in names]
        offsets = [fields[c][0] for c in names]
        dtype = np.dtype({"names": names, "formats": formats, "offsets": offsets, "itemsize": step})
        if not height or not width:
            pts = np.zeros(0, dtype)
        elif row_step == width * step:  # rows not padded: one view
            pts = np.frombuffer(data, dtype=dtype, count=width * height)
        else:
            pts = np.concatenate(
                [np.frombuffer(data, dtype=dtype, count=width, offset=r * row_step) for r in range(height)]
            )
    except (AttributeError, TypeError, ValueError, OverflowError) as exc:
        raise RecordingError(f"not a decodable point cloud: {exc}") from None
    x, y, z = (pts[c].astype(np.float64) for c in "xyz")
    if len(names) == 4:
        return x, y, z, pts[names[3]], fields[names[3]][1], width, height
    return x, y, z, None, 0, width, height


def _cloud_step_deg(cloud: CloudSlice, width: int, height: int, x: FloatArray, y: FloatArray) -> float:
    """The virtual scan's beam step: ``cloud.step_deg``; else an organised cloud's column spacing (its rows
    are rings of ``width`` returns around the lidar); else an unorganised cloud's, read off the bearings
    of its returns ``x, y`` in the order the driver wrote them: the bearing they sweep from one return
    to the next, over the number of steps that change it by more than :data:`_SAME_COLUMN_DEG` (a spinning
    lidar writes its returns column by column, the rings of one column at almost one bearing), when that is
    between 0.1° and 1°; else 0.25°."""
    if cloud.step_deg is not None:
        return cloud.step_deg
    if height > 1 and width >= 72:
        return float(np.clip(360.0 / width, 0.05, 5.0))
    d = np.abs(np.degrees(np.diff(np.arctan2(y, x))))
    near = d < 2.0  # consecutive returns of the sweep (not a jump to the next ring or sweep)
    d = d[near]
    columns = int(np.count_nonzero(d > _SAME_COLUMN_DEG))
    if columns >= 100 and np.count_nonzero(near) >= 0.5 * len(near):  # in order, not shuffled
        step = float(d.sum()) / columns  # the bearing swept, over the columns it took
        if 0.1 <= step <= 1.0:
            return step
    return _DEFAULT_CLOUD_STEP_DEG


_SAME_COLUMN_DEG = 0.02  # returns whose bearings differ by less are one column's


_DEFAULT_CLOUD_STEP_DEG = 0.25
_HOLE_BEAMS = 2  # empty beams between two returns of one surface that are filled in
_HOLE_JUMP_M, _HOLE_JUMP_REL = 0.05, 0.03  # ... when the two ranges differ by at most this + share of range


def _fill_holes(ranges: FloatArray) -> None:
    """Fill in place runs of up to :data:`_HOLE_BEAMS` empty beams whose neighbours lie on one surface
    (ranges within :data:`_HOLE_JUMP_M` + :data:`_HOLE_JUMP_REL` of the range), linearly: a lidar whose
    columns lie farther apart than the scan's beams leaves such holes in every surface, and the leg detector
    reads missing returns as dark or thin objects."""
    n = len(ranges)
    idx = np.flatnonzero(np.isfinite(ranges))
    if len(idx) < 2:
        return
    ends = np.r_[idx[1:], idx[0] + n]  # the beams go all around: the last one's neighbour is the first
    for i, j in zip(idx, ends, strict=True):
        if not 1 < j - i <= _HOLE_BEAMS + 1:
            continue
        a, b = float(ranges[i]), float(ranges[j % n])
        if abs(a - b) <= _HOLE_JUMP_M + _HOLE_JUMP_REL * min(a, b):
            ranges[np.arange(i + 1, j) % n] = a + (b - a) * np.arange(1, j - i) / (j - i)


def _point_times(raw: NDArray[Any], datatype: int, stamp_ns: int) -> FloatArray | None:
    """Per-point times, seconds after the header stamp (see :data:`_TIME_FIELDS`; times since the epoch
    are told by their size), or None where they are not finite or not within a second of the stamp."""
    t = raw.astype(np.float64) * (1.0 if datatype in (7, 8) else 1e-9)
    if not len(t) or not np.isfinite(t).all():
        return None
    if float(np.median(np.abs(t))) > 1e15:  # floating nanoseconds since the epoch (livox_ros_driver2)
        t = t * 1e-9
    if float(np.median(np.abs(t))) > 1e6:  # since the epoch
        t = t - stamp_ns * 1e-9
    return t if float(np.abs(t).max()) <= _MAX_TIME_OFF_S else None


_MAX_TIME_OFF_S = 2.0  # per-point times farther from the stamp are another clock's: the beams go untimed
_SWEEP_POINTS = 4096  # the rotation is read off about this many of a cloud's returns
_MIN_TURN_HZ, _MAX_TURN_HZ = 1.0, 50.0  # a spinning lidar turns at these rates
_TURN_FIT_RAD = 0.05  # ... and its bearings follow the time to within this (rms, radians)


def _sweep(az: FloatArray, t: FloatArray) -> tuple[float, float] | None:
    """How a spinning lidar swept its bearings ``az`` at times ``t`` (s after the stamp): its direction (+1
    counter-clockwise) and rate (rad/s); None unless the bearings follow the time as a rotation between
    :data:`_MIN_TURN_HZ` and :data:`_MAX_TURN_HZ` does."""
    order = np.argsort(t, kind="stable")
    ts, unwrapped = t[order], np.unwrap(az[order])
    span = float(ts[-1] - ts[0])
    if span <= 0:
        return None
    slope, icpt = np.polyfit(ts - ts[0], unwrapped, 1)
    rate = abs(float(slope))
    if not 2 * math.pi * _MIN_TURN_HZ <= rate <= 2 * math.pi * _MAX_TURN_HZ:
        return None
    resid = unwrapped - (icpt + slope * (ts - ts[0]))
    if float(np.sqrt(np.mean(resid**2))) > _TURN_FIT_RAD:
        return None
    return 1.0 if slope > 0 else -1.0, rate


def image_format(data: bytes) -> str:
    """``"jpeg"``, ``"png"`` or ``""`` from the first bytes of an encoded image."""
    if data[:3] == b"\xff\xd8\xff":
        return "jpeg"
    if data[:8] == b"\x89PNG\r\n\x1a\n":
        return "png"
    return ""


def _raw_to_bgr(
    data: bytes, height: int, width: int, encoding: str, step: int, bigendian: bool
) -> NDArray[np.uint8]:
    import cv2

    enc = encoding.lower().strip()
    if height <= 0 or width <= 0:
        raise ValueError(f"empty image {width}×{height}")
    channels, dtype = {
        "rgb8": (3, np.uint8), "bgr8": (3, np.uint8), "8uc3": (3, np.uint8),
        "rgba8": (4, np.uint8), "bgra8": (4, np.uint8), "8uc4": (4, np.uint8),
        "mono8": (1, np.uint8), "8uc1": (1, np.uint8),
        "mono16": (1, np.uint16), "16uc1": (1, np.uint16),
        "uyvy": (2, np.uint8), "yuv422": (2, np.uint8), "yuyv": (2, np.uint8), "yuv422_yuy2": (2, np.uint8),
        "bayer_rggb8": (1, np.uint8), "bayer_bggr8": (1, np.uint8),
        "bayer_gbrg8": (1, np.uint8), "bayer_grbg8": (1, np.uint8),
    }.get(enc, (0, np.uint8))  # fmt: skip
    if channels == 0:
        raise ValueError(f"unsupported raw image encoding '{encoding}'")
    itemsize = np.dtype(dtype).itemsize
    row = width * channels * itemsize
    step = step or row
    if step < row or len(data) < step * (height - 1) + row:
        raise ValueError(
            f"image data too short for {width}×{height} {encoding} (step {step}, {len(data)} bytes)"
        )
    buf = np.frombuffer(data, dtype=np.uint8, count=min(len(data), step * height))
    if buf.size < step * height:
        buf = np.concatenate([buf, np.zeros(step * height - buf.size, np.uint8)])
    rows = buf.reshape(height, step)[:, :row]
    if itemsize == 2:
        arr16 = rows.copy().view(">u2" if bigendian else "<u2").reshape(height, width)
        gray = (arr16 >> 8).astype(np.uint8)
        return np.ascontiguousarray(cv2.cvtColor(gray, cv2.COLOR_GRAY2BGR), dtype=np.uint8)
    img = np.ascontiguousarray(rows).reshape(height, width, channels) if channels > 1 else rows.copy()
    conv = {
        "rgb8": cv2.COLOR_RGB2BGR, "rgba8": cv2.COLOR_RGBA2BGR, "bgra8": cv2.COLOR_BGRA2BGR,
        "8uc4": cv2.COLOR_BGRA2BGR, "mono8": cv2.COLOR_GRAY2BGR, "8uc1": cv2.COLOR_GRAY2BGR,
        "uyvy": cv2.COLOR_YUV2BGR_UYVY, "yuv422": cv2.COLOR_YUV2BGR_UYVY,
        "yuyv": cv2.COLOR_YUV2BGR_YUY2, "yuv422_yuy2": cv2.COLOR_YUV2BGR_YUY2,
        # ROS names the Bayer pattern from the top-left 2×2; OpenCV from the second row
        "bayer_rggb8": cv2.COLOR_BayerBG2BGR, "bayer_bggr8": cv2.COLOR_BayerRG2BGR,
        "bayer_gbrg8": cv2.COLOR_BayerGR2BGR, "bayer_grbg8": cv2.COLOR_BayerGB2BGR,
    }.get(enc)  # fmt: skip
    out = img if conv is None else cv2.cvtColor(img, conv)
    return np.ascontiguousarray(out, dtype=np.uint8)


def decode_panorama(msg: Any, stamp_ns: int | None = None) -> Panorama:
    """sensor_msgs/CompressedImage (JPEG/PNG) or Image (rgb8, bgr8, rgba8, bgra8, mono8, mono16, yuv422,
    bayer_*) → :class:`Panorama` with a BGR image. Compressed bytes are kept in ``Panorama.encoded``.

    Args:
        msg: the deserialized message (ROS or Foxglove CompressedImage / RawImage).
        stamp_ns: used when the header stamp is zero (unset), ns.

    Raises:
        RecordingError: the message is not an image, or its pixels cannot be decoded.
    """
    import cv2

    try:
        stamp = stamp_ns_of(msg, stamp_ns)
        frame = _frame_of(msg)
        if hasattr(msg, "format") and not hasattr(msg, "width"):
            data = _bytes_of(msg.data)
            if not data:
                raise ValueError(f"compressed image ({msg.format or 'unknown format'}) with no data")
            img = cv2.imdecode(np.frombuffer(data, dtype=np.uint8), cv2.IMREAD_COLOR)
            if img is None or img.ndim != 3:
                raise ValueError(
                    f"compressed image ({msg.format or 'unknown format'}, {len(data)} bytes) does not decode"
                )
            fmt = image_format(data)
            return Panorama(stamp, frame, np.asarray(img, dtype=np.uint8), data if fmt else None, fmt)
        img = _raw_to_bgr(
            _bytes_of(msg.data),
            int(msg.height),
            int(msg.width),
            str(msg.encoding),
            int(getattr(msg, "step", 0) or 0),
            bool(getattr(msg, "is_bigendian", False)),
        )
        return Panorama(stamp, frame, img)
    except (AttributeError, TypeError, ValueError, cv2.error) as exc:
        raise RecordingError(f"cannot decode image: {' '.join(str(exc).split())[:200]}") from None


def _xyz(v: Any) -> tuple[float, float, float]:
    return float(v.x), float(v.y), float(v.z)


def _xyzw(q: Any) -> tuple[float, float, float, float]:
    return float(q.x), float(q.y), float(q.z), float(q.w)


def decode_odometry(msg: Any, stamp_ns: int | None = None) -> Odometry:
    """nav_msgs/Odometry (or foxglove.PoseInFrame, geometry_msgs/PoseStamped) → planar :class:`Odometry`.

    Raises:
        RecordingError: the message has no pose or an invalid orientation.
    """
    try:
        pose = msg.pose
        pose = getattr(pose, "pose", pose)  # PoseWithCovariance → Pose
        x, y, _ = _xyz(pose.position)
        q = _xyzw(pose.orientation)
        if not all(math.isfinite(v) for v in (x, y, *q)) or sum(v * v for v in q) < 1e-12:
            raise ValueError("non-finite position or zero quaternion")
        return Odometry(
            stamp_ns_of(msg, stamp_ns),
            _frame_of(msg),
            norm_frame(getattr(msg, "child_frame_id", "")),
            Pose2(x, y, yaw_from_quat(*q)),
        )
    except (AttributeError, TypeError, ValueError) as exc:
        raise RecordingError(f"not a decodable odometry message: {exc}") from None


def decode_tf(msg: Any) -> list[tuple[str, str, int, Pose3]]:
    """tf2_msgs/TFMessage (or a single TransformStamped, foxglove.FrameTransform(s)) → transforms.

    Returns:
        ``(parent, child, stamp_ns, T_parent_child)`` per transform; transforms with a non-finite value
        or a zero quaternion are left out.
    """
    items = msg.transforms if hasattr(msg, "transforms") else [msg]
    out: list[tuple[str, str, int, Pose3]] = []
    for tr in items:
        try:
            if hasattr(tr, "transform"):  # geometry_msgs/TransformStamped
                parent, child = _frame_of(tr), norm_frame(tr.child_frame_id)
                t, q = _xyz(tr.transform.translation), _xyzw(tr.transform.rotation)
            else:  # foxglove.FrameTransform
                parent, child = norm_frame(tr.parent_frame_id), norm_frame(tr.child_frame_id)
                t, q = _xyz(tr.translation), _xyzw(tr.rotation)
            if not all(math.isfinite(v) for v in (*t, *q)) or sum(v * v for v in q) < 1e-12:
                continue
            if not parent or not child or parent == child:
                continue
            out.append((parent, child, stamp_ns_of(tr), Pose3.from_quat(t, q)))
        except (AttributeError, TypeError, ValueError):
            continue
    return out


def looks_dual_fisheye(image: NDArray[Any]) -> bool:
    """Whether a 2:1 image looks like a 360° camera's two unstitched fisheye circles, side by side on black
    (a Ricoh Theta streams these unless it stitches), rather than an equirectangular panorama.

    Three things must hold: the image's corners and the gaps between the circles at the top and bottom
    middle are flat black (in a panorama they are the zenith and nadir rows: ceiling, sky or the robot); the
    circles' middles are not dark; and on most of 24 rays from the circles' centres (30–55° off the
    horizontal, up and down, both sides) the brightness falls to black within 4 % of half the height, at
    the same distance from the centre on all of them: a rim. A panorama whose top and bottom rows were
    blacked out has a black band instead, whose edge lies farther along the flatter rays.
    """
    img = np.asarray(image)
    gray = img.mean(axis=2) if img.ndim == 3 else img.astype(np.float64)
    h, w = gray.shape[:2]
    if w != 2 * h or h < 32:
        return False
    k = max(2, h // 20)

    def patch(cy: float, cx: float) -> NDArray[np.float64]:
        y0 = int(np.clip(cy - k / 2, 0, h - k))
        x0 = int(np.clip(cx - k / 2, 0, w - k))
        return np.asarray(gray[y0 : y0 + k, x0 : x0 + k], dtype=np.float64)

    gaps = [patch(y, x) for y in (0, h - 1) for x in (0, w / 2, w - 1)]
    if not all(float(p.mean()) <= 10.0 and float(p.std()) <= 5.0 for p in gaps):
        return False
    r = h / 2
    centres = [(r, w / 4), (r, 3 * w / 4)]
    if min(float(patch(cy, cx).mean()) for cy, cx in centres) < 25.0:
        return False
    radii = np.linspace(0.75, 1.15, 41) * r  # steps of 1 % of the radius
    rims = []
    for cy, cx in centres:
        for up in (30.0, 45.0, 55.0):
            for a in np.deg2rad([up, 180.0 - up, 180.0 + up, 360.0 - up]):
                ys = np.clip(np.round(cy - radii * np.sin(a)).astype(int), 0, h - 1)
                xs = np.clip(np.round(cx + radii * np.cos(a)).astype(int), 0, w - 1)
                prof = np.asarray(gray[ys, xs], dtype=np.float64)
                fall = [
                    i
                    for i in range(5, 31)  # the rim between 0.8 and 1.05 of half the height
                    if prof[i] >= 30.0 and prof[i + 4] <= 10.0 and np.all(prof[i + 4 :] <= 12.0)
                ]
                if fall:
                    rims.append(radii[fall[0]] / r)
    if len(rims) < 20:
        return False
    rim = np.asarray(rims)
    return bool(np.median(np.abs(rim - np.median(rim))) <= 0.02)
