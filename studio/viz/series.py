"""Whole-run series, logged after tracking with ``send_columns`` (see :mod:`studio.viz.paths` for the tree).

Robot poses, fused people with covariance ellipses, tracks with trails (odom frame) and on the panorama,
counts and calibration residuals per frame; given a ground-truth file, :mod:`studio.viz.compare` adds the
comparison with it.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
import rerun as rr
from numpy.typing import NDArray

from studio.geometry import EquirectCamera
from studio.labels.base import LabelFrame, LabelPerson
from studio.viz import paths as ep
from studio.viz.colors import SOURCE_COLORS, id_color
from studio.viz.draw import ellipse_strips, vertical_strips, wrapped_box_center

__all__ = ["calibration_residuals", "log_run_series"]

FloatArray = NDArray[np.float64]
_PERSON_HEIGHT = 1.8


def _times(index: Sequence[int], stamps: Sequence[int]) -> list[rr.TimeColumn]:
    return [
        rr.TimeColumn(ep.TIMELINE_FRAME, sequence=np.asarray(index, dtype=np.int64)),
        rr.TimeColumn(
            ep.TIMELINE_TIME, timestamp=np.asarray(stamps, dtype=np.int64).astype("datetime64[ns]")
        ),
    ]


def _scalars(
    rec: rr.RecordingStream,
    path: str,
    index: Sequence[int],
    stamps: Sequence[int],
    values: Sequence[float],
    *,
    name: str,
    color: tuple[int, int, int],
) -> None:
    rec.log(path, rr.SeriesLines(names=[name], colors=[color]), static=True)
    if len(values):
        rec.send_columns(
            path,
            indexes=_times(index, stamps),
            columns=rr.Scalars.columns(scalars=np.asarray(values, dtype=np.float64)),
        )


def send_points(
    rec: rr.RecordingStream,
    path: str,
    idx: list[rr.TimeColumn],
    positions: Any,
    colors: Any,
    labels: Sequence[str],
    lengths: Sequence[int],
    *,
    radius: float,
    show_labels: bool,
) -> None:
    """A whole series of 3D points, ``lengths[k]`` of them at time ``k`` (style logged as static)."""
    rec.log(path, rr.Points3D.from_fields(radii=[radius], show_labels=show_labels), static=True)
    rec.send_columns(
        path,
        indexes=idx,
        columns=rr.Points3D.columns(
            positions=np.asarray(positions, np.float64).reshape(-1, 3),
            colors=np.array(colors, np.uint8).reshape(-1, 3),
            labels=list(labels),
        ).partition(lengths),
    )


def send_strips(
    rec: rr.RecordingStream,
    path: str,
    idx: list[rr.TimeColumn],
    strips: Any,
    colors: Any,
    lengths: Sequence[int],
    *,
    radius: float,
    labels: Sequence[str] | None = None,
    image: bool = False,
) -> None:
    """A whole series of line strips (2D on the panorama when ``image``, else 3D), ``lengths[k]`` at k."""
    arch = rr.LineStrips2D if image else rr.LineStrips3D
    style = arch.from_fields(radii=[radius], show_labels=True if labels is not None else None)
    rec.log(path, style, static=True)
    cols: dict[str, Any] = {"strips": strips, "colors": np.array(colors, np.uint8).reshape(-1, 3)}
    if labels is not None:
        cols["labels"] = list(labels)
    rec.send_columns(path, indexes=idx, columns=arch.columns(**cols).partition(lengths))


def _odom_xy(p: LabelPerson, pose: Any) -> tuple[float, float]:
    if p.x_odom is not None and p.y_odom is not None:
        return float(p.x_odom), float(p.y_odom)
    if pose is not None:
        x, y = pose.apply(np.array([p.x, p.y]))
        return float(x), float(y)
    return p.x, p.y


def log_run_series(
    rec: rr.RecordingStream,
    result: Any,
    *,
    ground_truth: Path | None = None,
    trail_s: float = 5.0,
    pano_camera: EquirectCamera | None = None,
) -> None:
    """Log everything of :class:`studio.pipeline.label.LabelRun` that is known only after tracking.

    Args:
        rec: the recording stream.
        result: the run.
        ground_truth: labels file to compare with.
        trail_s: trail length, s.
        pano_camera: the camera of the panorama *as logged* (it may be downscaled); default: the run's.
    """
    pano_camera = pano_camera if pano_camera is not None else result.camera
    frames = list(result.detections)
    if frames:
        _robot(rec, frames)
        _fused(rec, frames)
        if result.camera is not None:
            _calibration(rec, frames, result.camera)
    _tracks(rec, list(result.labels), trail_s=trail_s, camera=pano_camera)
    _counts(rec, frames, list(result.labels))
    _review(rec, list(result.labels))
    if ground_truth is not None:
        from studio.labels.formats import read_labels
        from studio.viz.compare import log_ground_truth

        log_ground_truth(rec, list(result.labels), read_labels(ground_truth), camera=pano_camera)


def _review(rec: rr.RecordingStream, labels: list[LabelFrame]) -> None:
    """The moments where identities are worth checking (:mod:`studio.labels.review`), as a text log: level
    WARN for a doubt of :data:`~studio.labels.review.FIRST_DOUBT` or more (the likeliest errors: filter the
    log's levels), else INFO."""
    from studio.labels.review import FIRST_DOUBT, review_points

    points = review_points(labels) if all(f.stamp_ns is not None for f in labels) else []
    if points:
        rec.send_columns(
            ep.REVIEW,
            indexes=_times([p.frame for p in points], [p.stamp_ns for p in points]),
            columns=rr.TextLog.columns(
                text=[f"frame {p.frame} ({p.kind}, doubt {p.doubt:.2f}): {p.note}" for p in points],
                level=["WARN" if p.doubt >= FIRST_DOUBT else "INFO" for p in points],
            ),
        )


def _robot(rec: rr.RecordingStream, frames: list[Any]) -> None:
    poses = [f.robot_pose for f in frames]
    trans = np.array([[p.x, p.y, 0.0] for p in poses])
    quat = np.array([[0.0, 0.0, np.sin(p.yaw / 2), np.cos(p.yaw / 2)] for p in poses])
    rec.send_columns(
        ep.ROBOT,
        indexes=_times([f.index for f in frames], [f.stamp_ns for f in frames]),
        columns=rr.Transform3D.columns(translation=trans, quaternion=quat),
    )


def _fused(rec: rr.RecordingStream, frames: list[Any]) -> None:
    pos, col, lengths, strips, s_col, s_len = [], [], [], [], [], []
    lab: list[str] = []
    for f in frames:
        o = f.observations
        n = len(o)
        lengths.append(n)
        s_len.append(n)
        if n:
            pos.append(np.c_[o.xy, np.full(n, 0.02)])
            c = [SOURCE_COLORS.get(s, (200, 200, 200)) for s in o.source]
            col.extend(c)
            s_col.extend(c)
            lab.extend(f"{s} ({h})" for s, h in zip(o.source, o.how, strict=True))
            strips.extend(ellipse_strips(o.xy, o.cov, n_sigma=2.0, n=16, z=0.02))
    idx = _times([f.index for f in frames], [f.stamp_ns for f in frames])
    people = f"{ep.ROBOT}/people"
    send_points(
        rec,
        people,
        idx,
        np.concatenate(pos) if pos else np.zeros((0, 3)),
        col,
        lab,
        lengths,
        radius=0.08,
        show_labels=False,
    )
    send_strips(rec, f"{people}/covariance", idx, strips, s_col, s_len, radius=0.006)


def _tracks(
    rec: rr.RecordingStream, labels: list[LabelFrame], *, trail_s: float, camera: EquirectCamera | None
) -> None:
    if not labels or any(lf.stamp_ns is None for lf in labels):
        return
    index = [lf.frame for lf in labels]
    stamps = [int(lf.stamp_ns) for lf in labels]  # type: ignore[arg-type]
    # per track: its stamps and odom positions, in time order
    hist: dict[int, tuple[list[int], list[tuple[float, float]]]] = {}
    for lf, s in zip(labels, stamps, strict=True):
        for p in lf.people:
            h = hist.setdefault(p.id, ([], []))
            h[0].append(s)
            h[1].append(_odom_xy(p, lf.robot_pose))
    arrays = {k: (np.array(v[0], np.int64), np.array(v[1], np.float64)) for k, v in hist.items()}
    trail_ns = int(trail_s * 1e9)
    pos, col, lab, lengths = [], [], [], []
    strips, s_col, s_len = [], [], []
    pan_strips: list[FloatArray] = []
    pan_col: list[tuple[int, int, int]] = []
    pan_lab: list[str] = []
    pan_len: list[int] = []
    for lf, s in zip(labels, stamps, strict=True):
        n_strips = 0
        for p in lf.people:
            xy = _odom_xy(p, lf.robot_pose)
            pos.append((xy[0], xy[1], 0.0))
            col.append(id_color(p.id))
            lab.append(str(p.id))
            ts, pts = arrays[p.id]
            lo, hi = np.searchsorted(ts, s - trail_ns, "left"), np.searchsorted(ts, s, "right")
            if hi - lo >= 2:
                strips.append(np.c_[pts[lo:hi], np.zeros(hi - lo)])
                s_col.append(id_color(p.id))
                n_strips += 1
        lengths.append(len(lf.people))
        s_len.append(n_strips)
        if camera is not None:
            base = lf.xy()
            up, _ = camera.project(np.c_[base, np.full(len(base), _PERSON_HEIGHT)])
            low, _ = camera.project(np.c_[base, np.zeros(len(base))])
            vs, keep = vertical_strips(low, up, camera.width)
            pan_strips.extend(vs)
            pan_col.extend(id_color(lf.people[i].id) for i in keep)
            pan_lab.extend(str(lf.people[i].id) for i in keep)
            pan_len.append(len(vs))
    idx = _times(index, stamps)
    send_points(rec, f"{ep.ODOM}/tracks", idx, pos, col, lab, lengths, radius=0.12, show_labels=True)
    send_strips(rec, f"{ep.ODOM}/trails", idx, strips, s_col, s_len, radius=0.02)
    if camera is not None:
        send_strips(
            rec,
            f"{ep.PANORAMA}/tracks",
            idx,
            pan_strips,
            pan_col,
            pan_len,
            radius=3.0 * max(camera.width / 1920, 0.25),
            labels=pan_lab,
            image=True,
        )


def _counts(rec: rr.RecordingStream, frames: list[Any], labels: list[LabelFrame]) -> None:
    if frames:
        index, stamps = [f.index for f in frames], [f.stamp_ns for f in frames]
        for src in ("fused", "laser", "image"):
            vals = [sum(s == src for s in f.observations.source) for f in frames]
            _scalars(
                rec,
                f"{ep.METRICS}/counts/{src}",
                index,
                stamps,
                vals,
                name=f"{src} observations",
                color=SOURCE_COLORS[src],
            )
    rows = [lf for lf in labels if lf.stamp_ns is not None]
    if rows:
        _scalars(
            rec,
            f"{ep.METRICS}/counts/tracks",
            [lf.frame for lf in rows],
            [int(lf.stamp_ns) for lf in rows],  # type: ignore[arg-type]
            [len(lf.people) for lf in rows],
            name="tracked people",
            color=(230, 230, 230),
        )


def calibration_residuals(obs: Any, camera: EquirectCamera) -> tuple[FloatArray, FloatArray]:
    """Per fused observation measured by a laser detection: box centre − projected laser column, and box
    bottom − projected floor row, px (``(K,)`` each). A calibration error shows up as a bias."""
    sel = np.array(
        [s == "fused" and h == "laser-detection" for s, h in zip(obs.source, obs.how, strict=True)],
        dtype=bool,
    ).reshape(-1)
    if len(obs):
        sel &= np.all(np.isfinite(obs.box), axis=1) & (obs.laser_index >= 0)
    if not sel.any():
        return np.zeros(0), np.zeros(0)
    xy = obs.xy[sel]
    box = obs.box[sel]
    W = float(camera.width)
    mid, _ = camera.project(np.c_[xy, np.full(len(xy), 1.0)])
    floor, _ = camera.project(np.c_[xy, np.zeros(len(xy))])
    du = wrapped_box_center(box, W) - mid[:, 0]
    du = (du + 0.5 * W) % W - 0.5 * W
    dv = box[:, 3] - floor[:, 1]
    return du, dv


def _calibration(rec: rr.RecordingStream, frames: list[Any], camera: EquirectCamera) -> None:
    index, stamps, cols, rows = [], [], [], []
    for f in frames:
        du, dv = calibration_residuals(f.observations, camera)
        if len(du):
            index.append(f.index)
            stamps.append(f.stamp_ns)
            cols.append(float(np.mean(du)))
            rows.append(float(np.mean(dv)))
    _scalars(
        rec,
        f"{ep.CALIBRATION}/column_px",
        index,
        stamps,
        cols,
        name="box centre − laser column, px",
        color=(255, 200, 60),
    )
    _scalars(
        rec,
        f"{ep.CALIBRATION}/row_px",
        index,
        stamps,
        rows,
        name="box bottom − floor row, px",
        color=(60, 200, 255),
    )
