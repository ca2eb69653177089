"""``studio inspect RECORDING [--rig RIG]``: topics, types, counts, rates, time span, TF tree, sync stats;
without a rig, a rig.yaml to start from (:func:`draft_rig`)."""

from __future__ import annotations

import argparse
import json
import os
import re
import sys
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

import numpy as np

from studio.io import (
    RecordingError,
    SyncReport,
    TfBuffer,
    count_frames,
    decode_odometry,
    decode_panorama,
    decode_scan,
    iter_frames,
    load_rig,
    open_recording,
)
from studio.io.base import RawMessage
from studio.io.decode import norm_frame, stamp_ns_of
from studio.io.reader import Recording

__all__ = ["describe_recording", "draft_rig", "run"]


def _utc(ns: int) -> str:
    return datetime.fromtimestamp(ns / 1e9, tz=UTC).strftime("%Y-%m-%d %H:%M:%S.%f")[:-3] + " UTC"


def _size(files: tuple[Path, ...]) -> str:
    n = sum(_size_bytes(f) for f in files)
    for unit in ("B", "KB", "MB", "GB"):
        if n < 1024 or unit == "GB":
            return f"{n:.0f} {unit}" if unit == "B" else f"{n:.1f} {unit}"
        n /= 1024  # type: ignore[assignment]
    return f"{n} B"


def _metres(v: float) -> str:
    return "∞" if v >= 1e30 else f"{v:g}"


_SENSOR_KINDS = (
    "LaserScan",
    "MultiEchoLaserScan",
    "PointCloud2",
    "CompressedImage",
    "Image",
    "RawImage",
    "Odometry",
)


def _kind(msgtype: str) -> str:
    return msgtype.rsplit("/", 1)[-1].rsplit(".", 1)[-1]


def _sensor_detail(rec: Recording, first: RawMessage, last: RawMessage | None, count: int) -> list[str]:
    """Lines describing a sensor topic from its first (and last) message: frame, size, header stamps."""
    kind = _kind(first.msgtype)
    try:
        msg = rec.decode(first)
        if kind in ("LaserScan", "MultiEchoLaserScan"):
            s = decode_scan(msg, first.log_ns)
            fov = abs(s.angle_increment) * max(len(s) - 1, 0)
            text = (
                f"frame '{s.frame_id}', {len(s)} beams over {np.degrees(fov):.1f}°, "
                f"range {s.range_min:g}–{_metres(s.range_max)} m, "
                + (
                    f"swept in {abs(s.time_increment) * max(len(s) - 1, 0) * 1e3:.1f} ms (time_increment)"
                    if s.time_increment
                    else "no time_increment (beams taken as measured at the header stamp)"
                )
                + ("; multi-echo: each beam's first echo is used" if kind == "MultiEchoLaserScan" else "")
            )
        elif kind == "PointCloud2":
            names = ", ".join(str(f.name) for f in msg.fields)
            w, h = int(msg.width), int(msg.height)
            text = (
                f"frame '{norm_frame(msg.header.frame_id)}', {w * h} points ({w}×{h}), fields {names}: "
                "a 3-D lidar; label it with a height band, "
                "'cloud: {min_z, max_z}' in the rig's laser entry"
            )
        elif kind == "Odometry":
            o = decode_odometry(msg, first.log_ns)
            text = f"frame '{o.frame_id}' → '{o.child_frame_id}'"
        else:
            p = decode_panorama(msg, first.log_ns)
            fmt = f", {p.encoding}" if p.encoding else ""
            text = f"frame '{p.frame_id}', {p.width}×{p.height}{fmt}"
            if p.width != 2 * p.height:
                text += " (not 2:1: studio needs an equirectangular panorama, twice as wide as high)"
    except RecordingError as exc:
        return [f"first message not decodable: {exc}"]
    lines = [text]
    if stamp_ns_of(msg) == 0:  # labelling then takes the log time
        lines.append("header stamps: unset (0): the log time stands in for them")
        return lines
    h0 = stamp_ns_of(msg, first.log_ns)
    stamps = f"header stamps: first − log time {(h0 - first.log_ns) / 1e9:+.3f} s"
    if last is not None and count > 1:
        try:
            h1 = stamp_ns_of(rec.decode(last), last.log_ns)
        except RecordingError:
            h1 = None
        if h1 is not None and h1 > h0:
            stamps += f", span {(h1 - h0) / 1e9:.3f} s, {(count - 1) / ((h1 - h0) / 1e9):.2f} Hz"
    lines.append(stamps)
    return lines


def _first_last(rec: Recording) -> dict[str, tuple[RawMessage, RawMessage]]:
    """First and last raw record of every topic, from one pass (no decoding)."""
    from tqdm import tqdm

    out: dict[str, tuple[RawMessage, RawMessage]] = {}
    total = sum(t.count for t in rec.topics.values())
    for raw in tqdm(rec.messages(), total=total, desc="reading", unit="msg", file=sys.stderr, disable=None,
                    leave=False):  # fmt: skip
        have = out.get(raw.topic)
        out[raw.topic] = (raw, raw) if have is None else (have[0], raw)
    return out


def _tf_lines(tf: TfBuffer) -> list[str]:
    edges = tf.edges()
    if not edges:
        return ["TF: none (the recording has no /tf or /tf_static)"]
    children: dict[str, list[Any]] = {}
    for e in edges:
        children.setdefault(e.parent, []).append(e)
    child_names = {e.child for e in edges}
    roots = sorted(p for p in children if p not in child_names)
    lines = [f"TF frames ({len(tf.frames())}; parent → child):"]

    def walk(frame: str, indent: str, seen: set[str]) -> None:
        for e in children.get(frame, []):
            if e.child in seen:
                continue
            if e.static:
                how = "static"
            else:
                span = (e.last_ns - e.first_ns) / 1e9
                rate = (e.count - 1) / span if span > 0 else 0.0
                how = f"dynamic, {e.count} samples, {rate:.1f} Hz"
            lines.append(f"{indent}{e.parent} → {e.child} ({how})")
            walk(e.child, indent + "  ", seen | {e.child})

    for root in roots or sorted(children):
        walk(root, "  ", {root})
    return lines


_SCAN_ALL_BELOW = 2 * 2**30  # bytes: smaller recordings are read once for exact per-topic rates


def _size_bytes(path: Path) -> int:
    if path.is_dir():
        return sum(f.stat().st_size for f in path.rglob("*") if f.is_file())
    return path.stat().st_size


def describe_recording(rec: Recording, *, exact_rates: bool | None = None) -> list[str]:
    """The report lines of ``studio inspect`` for an open recording (without sync statistics).

    Args:
        rec: the open recording.
        exact_rates: read every record once for per-topic rates (count − 1 over the topic's own log-time
            span); default: when the recording is under 2 GiB, else the rates use the whole recording's span.
    """
    kinds = {"ros1": "ROS1 bag", "ros2": "ROS2 bag", "mcap": "plain MCAP"}
    kind = kinds[rec.kind] if len(rec.files) == 1 else f"{len(rec.files)} ROS1 bags merged"
    lines = [f"recording: {rec.path} ({kind}, {_size(rec.files)})"]
    if len(rec.files) > 1:
        lines += [f"  {f.name}" for f in rec.files]
    lines += [f"note: {n}" for n in rec.notes]
    span = rec.duration_ns / 1e9
    if rec.topics and any(t.count for t in rec.topics.values()):
        lines.append(f"time span: {_utc(rec.start_ns)} → {_utc(rec.end_ns)} ({span:.3f} s, log time)")
    else:
        lines.append("time span: empty recording")
    if exact_rates is None:
        exact_rates = sum(_size_bytes(f) for f in rec.files) < _SCAN_ALL_BELOW
    ends = _first_last(rec) if exact_rates else {}
    how = "rate over the topic's own span" if exact_rates else "≈ rate over the recording's span"
    lines.append(f"topics ({len(rec.topics)}; type, messages, {how}, log time):")
    w_name = max((len(t) for t in rec.topics), default=5)
    w_type = max((len(i.msgtype) for i in rec.topics.values()), default=4)
    for name, info in rec.topics.items():
        pair = ends.get(name)
        if pair is None and not exact_rates and _kind(info.msgtype) in _SENSOR_KINDS:
            first_raw = next(iter(rec.messages([name])), None)
            pair = None if first_raw is None else (first_raw, first_raw)
        t0, t1 = (pair[0].log_ns, pair[1].log_ns) if pair and exact_rates else (rec.start_ns, rec.end_ns)
        tspan = (t1 - t0) / 1e9
        rate = f"{(info.count - 1) / tspan:8.2f} Hz" if tspan > 0 and info.count > 1 else "        - Hz"
        lines.append(f"  {name:<{w_name}}  {info.msgtype:<{w_type}}  {info.count:7d} msgs  {rate}")
        if pair is not None and _kind(info.msgtype) in _SENSOR_KINDS:
            last = pair[1] if exact_rates else None
            lines += [f"  {'':<{w_name}}  {d}" for d in _sensor_detail(rec, pair[0], last, info.count)]
    lines += _tf_lines(TfBuffer.from_recording(rec))
    return lines


def _report(args: argparse.Namespace) -> None:
    rig = load_rig(args.rig) if args.rig else None
    with open_recording(args.recording) as rec:
        for line in describe_recording(rec):
            print(line, flush=True)
        if rig is None:
            print()
            for line in draft_rig(rec):
                print(line)
        if rig is not None:
            from tqdm import tqdm

            report = SyncReport()
            total = count_frames(rec, rig)
            frames = iter_frames(rec, rig, report=report)
            for _ in tqdm(
                frames, total=total, desc="sync", unit="frame", file=sys.stderr, disable=None, leave=False
            ):
                pass
            ms = rig.sync.max_dt_s * 1e3
            print(f"sync (rig {args.rig}, base_frame '{rig.base_frame}', max_dt {ms:g} ms):")
            for line in report.summary().splitlines():
                print(f"  {line}")
            print(f"sensor poses in '{rig.base_frame}' (x y z m, roll pitch yaw °):")
            for line in _pose_lines(rec, rig):
                print(f"  {line}")


def _first_decoded(rec: Recording, topic: str, decode: Any, tries: int = 20) -> Any:
    """The first of the first ``tries`` messages of ``topic`` that ``decode(msg, log_ns)`` reads (None: none;
    a driver's first messages can be bad, e.g. an odometry quaternion of zeros at start-up)."""
    for k, raw in enumerate(rec.messages([topic])):
        if k >= tries:
            break
        try:
            return decode(rec.decode(raw), raw.log_ns)
        except (RecordingError, ValueError):
            continue
    return None


_YAML_WORDS = {"null", "true", "false", "yes", "no", "on", "off", "y", "n", "~"}


def _scalar(name: str) -> str:
    """``name`` as a YAML scalar: as it is when YAML reads it back as that string, else quoted."""
    if re.fullmatch(r"[A-Za-z_/][A-Za-z0-9_/.\-]*", name) and name.lower() not in _YAML_WORDS:
        return name
    return json.dumps(name)  # JSON strings are YAML


def draft_rig(rec: Recording, tf: TfBuffer | None = None) -> list[str]:
    """A ``rig.yaml`` to start from, as YAML lines: the recording's scanners, odometry and panorama, a
    ``base_frame`` that places them, and what it could not place as comments.

    The base frame is the odometry's robot frame, else ``base_link`` or ``base_footprint`` of the TF tree,
    else the first scanner's own frame. A sensor the TF tree (or being the base frame) places needs no pose;
    one it cannot place is left commented out, with the pose to measure (a wrong pose labels wrong people),
    unless nothing else is placed: then the first scanner is written with a zero pose marked to measure, so
    the draft loads.
    """
    tf = TfBuffer.from_recording(rec) if tf is None else tf
    by_kind: dict[str, list[str]] = {}
    for name, info in rec.topics.items():
        by_kind.setdefault(_kind(info.msgtype), []).append(name)
    scans: list[tuple[str, str]] = []  # (topic, frame)
    for topic in by_kind.get("LaserScan", []) + by_kind.get("MultiEchoLaserScan", []):
        scan = _first_decoded(rec, topic, decode_scan)
        if scan is not None:
            scans.append((topic, scan.frame_id))
    odom_topic, odom_child = None, ""
    odom_topics = [t for kind in ("Odometry", "PoseInFrame", "PoseStamped") for t in by_kind.get(kind, [])]
    for topic in sorted(odom_topics, key=lambda t: t.strip("/") != "odom"):
        odom = _first_decoded(rec, topic, decode_odometry)
        if odom is not None:
            odom_topic, odom_child = topic, odom.child_frame_id
            break
    pano_topic, pano_frame = None, ""
    for topic in [t for kind in ("CompressedImage", "Image", "RawImage") for t in by_kind.get(kind, [])]:
        pano = _first_decoded(rec, topic, decode_panorama)
        if pano is not None and pano.image.shape[1] == 2 * pano.image.shape[0]:  # equirectangular
            pano_topic, pano_frame = topic, pano.frame_id
            break
    frames = set(tf.frames())
    neighbours: dict[str, set[str]] = {}
    for e in tf.edges():
        neighbours.setdefault(e.parent, set()).add(e.child)
        neighbours.setdefault(e.child, set()).add(e.parent)

    def tree_of(frame: str) -> set[str]:
        seen, todo = {frame}, [frame]
        while todo:
            for n in neighbours.get(todo.pop(), ()):
                if n not in seen:
                    seen.add(n)
                    todo.append(n)
        return seen

    if odom_child and (not frames or odom_child in frames):
        base = odom_child
    else:
        first_frame = next((f for _, f in scans if f), "")
        base = next((f for f in ("base_link", "base_footprint") if f in frames), first_frame)
    placed = tree_of(base) - {""} if base else set()
    lines = [
        "# a rig.yaml to start from: check it (README, 'Your own robot'), then",
        "# studio inspect REC --rig it",
    ]
    lines.append(
        f"base_frame: {_scalar(base)}" if base else "base_frame: base_link  # no frame names one: name it"
    )
    if odom_topic is not None:
        lines.append(f"odometry: {{topic: {_scalar(odom_topic)}}}")
    elif "odom" in placed and base != "odom":
        lines.append("odometry: {tf: odom}")
    else:
        lines.append("# no odometry: scan matching gives the motion")
    zero = "{x: 0.0, y: 0.0, z: 0.0, roll: 0.0, pitch: 0.0, yaw: 0.0}"
    where = f"in the TF tree of '{base}'" if base else "named"
    if pano_topic is not None:
        if pano_frame in placed:
            lines += ["camera:", f"  topic: {_scalar(pano_topic)}"]
        else:
            lines += [
                f"# camera: its frame '{pano_frame}' is not {where}: measure its pose (or studio",
                "# calibrate), then",
                "# camera:",
                f"#   topic: {_scalar(pano_topic)}",
                f"#   pose: {zero}",
            ]
    placed_scans = [t for t, frame in scans if frame in placed]
    guess = None if placed_scans or pano_frame in placed or not scans else scans[0][0]
    lines.append("lasers:" if placed_scans or guess else "lasers: []  # none could be placed")
    for topic, frame in scans:
        if frame in placed:
            lines.append(f"  - topic: {_scalar(topic)}")
        elif topic == guess:
            lines += [
                f"  # MEASURE the pose of its frame '{frame}' in the base frame: it is not {where}",
                f"  - topic: {_scalar(topic)}",
                f"    pose: {zero}",
            ]
        else:
            lines += [
                f"  # its frame '{frame}' is not {where}: measure its pose, then",
                f"  # - topic: {_scalar(topic)}",
                f"  #   pose: {zero}",
            ]
    for topic in by_kind.get("PointCloud2", []):
        lines.append(
            f"  # - topic: {_scalar(topic)}    # a 3-D lidar: slice it, cloud: {{min_z, max_z}} in its frame"
        )
    return lines


def _pose_lines(rec: Recording, rig: Any) -> list[str]:
    """Where ``studio label`` puts each sensor: its pose, from the rig or the recording's TF (a laser looked
    up scan by scan where its mount moves), why a sensor cannot be placed, and a scanner mounted upside
    down."""
    from studio.io import resolve_sensor_poses, unplaced_reason
    from studio.io.base import upside_down

    placed = resolve_sensor_poses(rec, rig)
    sensors: list[tuple[str, Any, Any]] = [
        ("laser", a, b) for a, b in zip(rig.lasers, placed.lasers, strict=True)
    ]
    if rig.camera is not None:
        sensors.insert(0, ("camera", rig.camera, placed.camera))
    lines = []
    for kind, given, pose_of in sensors:
        pose = pose_of.pose
        if pose is None:
            moving, why = unplaced_reason(rec, rig, given.topic)
            if moving and kind == "laser":
                lines.append(f"{kind} {given.topic}: from TF scan by scan ({why})")
            else:
                lines.append(f"{kind} {given.topic}: cannot be placed: {why} (give its pose in rig.yaml)")
            continue
        x, y, z = np.round(pose.t, 3) + 0.0  # no "-0.000"
        r, p, w = np.round(np.degrees(pose.rpy()), 1) + 0.0
        text = f"{kind} {given.topic}: {x:.3f} {y:.3f} {z:.3f}, {r:.1f} {p:.1f} {w:.1f} "
        text += "(rig)" if given.pose is not None else "(TF)"
        if kind == "laser" and upside_down(pose):
            text += "; mounted upside down: its scans are turned upright"
        lines.append(text)
    return lines


def run(args: argparse.Namespace) -> int:
    """Print the report of ``studio inspect`` (exit status 0; errors raise StudioError → 2)."""
    try:
        _report(args)
        sys.stdout.flush()
    except BrokenPipeError:  # output piped into `head`: stop quietly
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
    return 0
