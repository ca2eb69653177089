"""Calibration targets found automatically in a recording (issue #7): ball, board, checkerboard.

* :mod:`studio.calibrate.targets.ball` — PanNote's ball: a circle of known radius in the scans, the ball's
  centre in the panorama from its colour on perspective views; ``x, y, z, u, v`` correspondences and the
  camera's time offset;
* :mod:`studio.calibrate.targets.board` — the thesis's green/white board: its segment in the scans, the
  colour boundary line in a cube face; per-face homographies (thesis Eqs. 3.14–3.15) with the thesis's
  accuracy share, and correspondences for the global spherical fit;
* :mod:`studio.calibrate.targets.checkerboard` — intrinsics check of the cube faces.

This module holds what they share: reading the scans and panoramas of a recording, the target's track
over time, its still periods and the time-offset search. The robot must stand still during a
calibration recording (the scans are put into the base frame with the rig's static laser poses).
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from studio.errors import StudioError
from studio.geometry.equirect import not_equirect
from studio.geometry.se import Pose3
from studio.io.base import Panorama
from studio.io.reader import Recording
from studio.io.rig import Rig

__all__ = [
    "ScanPoints",
    "TargetError",
    "TargetTrack",
    "iter_panoramas",
    "read_scans",
]

FloatArray = NDArray[np.float64]


class TargetError(StudioError):
    """A recording or rig from which no target correspondences can be extracted."""


@dataclass(frozen=True)
class ScanPoints:
    """One scan in the base frame.

    Attributes:
        topic: laser topic.
        stamp_ns: header stamp, ns.
        points: (n_beams, 3) beam end points in the base frame, metres, in beam order; NaN rows for
            invalid beams (no return, dropout).
        origin: (3,) the laser's position in the base frame, metres.
    """

    topic: str
    stamp_ns: int
    points: FloatArray
    origin: FloatArray


def _laser_poses(rec: Recording, rig: Rig) -> list[Pose3]:
    from studio.io.sync import resolve_sensor_poses

    full = resolve_sensor_poses(rec, rig)
    poses = []
    for cfg in full.lasers:
        if cfg.pose is None:
            raise TargetError(f"laser {cfg.topic}: no pose in the rig or the recording's TF")
        poses.append(cfg.pose)
    return poses


def read_scans(rec: Recording, rig: Rig) -> list[ScanPoints]:
    """Every scan of the rig's lasers, in the base frame, in stamp order.

    Raises:
        TargetError: the rig has no laser, or a laser topic is missing from the recording.
        RecordingError: the recording cannot be read.
    """
    from studio.io.decode import decode_scan

    if not rig.lasers:
        raise TargetError("the rig has no laser: targets need scans")
    for cfg in rig.lasers:
        if not rec.has_topic(cfg.topic):
            raise TargetError(f"laser topic {cfg.topic} is not in {rec.path}")
    poses = dict(zip((c.topic for c in rig.lasers), _laser_poses(rec, rig), strict=True))
    names = {rec.resolve_topic(c.topic): c.topic for c in rig.lasers}
    clouds = {c.topic: c.cloud for c in rig.lasers}
    out: list[ScanPoints] = []
    for raw in rec.messages(list(names)):
        topic = names.get(raw.topic, raw.topic)
        scan = decode_scan(rec.decode(raw), raw.log_ns, cloud=clouds[topic])
        a = scan.angles()
        r = np.where(scan.valid(), scan.ranges.astype(np.float64), np.nan)
        p = np.stack([r * np.cos(a), r * np.sin(a), np.zeros_like(r)], axis=1)
        pose = poses[topic]
        out.append(ScanPoints(topic, scan.stamp_ns, pose.apply(p), pose.t.copy()))
    out.sort(key=lambda s: s.stamp_ns)
    return out


def iter_panoramas(rec: Recording, rig: Rig, *, every: int = 1) -> Iterator[Panorama]:
    """The camera's panoramas in log order (every ``every``-th one).

    Raises:
        TargetError: the rig has no camera or its topic is not in the recording, or an image is not 2:1.
    """
    from studio.io.decode import decode_panorama

    if rig.camera is None:
        raise TargetError("the rig has no camera")
    if not rec.has_topic(rig.camera.topic):
        raise TargetError(f"camera topic {rig.camera.topic} is not in {rec.path}")
    for k, raw in enumerate(rec.messages([rig.camera.topic])):
        if k % max(int(every), 1) == 0:
            pano = decode_panorama(rec.decode(raw), raw.log_ns)
            if (wrong := not_equirect(pano.width, pano.height)) is not None:
                raise TargetError(f"{rec.path}: the camera's images are {wrong}")
            yield pano


@dataclass(frozen=True)
class TargetTrack:
    """A target's laser measurements over time, with its still periods.

    Attributes:
        stamps: (N,) int64 scan stamps, ns, increasing.
        values: (N, K) measurement per scan (e.g. ball centre x, y, z and circle radius), metres.
        segment: (N,) index of the still period each scan belongs to, -1 while the target moves.
    """

    stamps: NDArray[np.int64]
    values: FloatArray
    segment: NDArray[np.int64]

    @staticmethod
    def build(
        stamps: NDArray[np.int64], values: FloatArray, *, tol_m: float = 0.02, min_s: float = 0.3
    ) -> TargetTrack:
        """Group scans into still periods: runs whose ``x, y`` (first two values) stay within ``tol_m`` of
        the run's median and that last at least ``min_s`` seconds."""
        order = np.argsort(stamps, kind="stable")
        st, val = stamps[order], values[order]
        seg = np.full(st.shape[0], -1, dtype=np.int64)
        i, k = 0, 0
        n = st.shape[0]
        while i < n:
            j = i + 1
            while j < n and np.all(np.abs(val[j, :2] - np.median(val[i:j, :2], axis=0)) < tol_m):
                j += 1
            if (st[j - 1] - st[i]) * 1e-9 >= min_s and j - i >= 5:
                seg[i:j] = k
                k += 1
            i = j if j > i + 1 else i + 1
        return TargetTrack(st, val, seg)

    def periods(self) -> NDArray[np.int64]:
        """(M, 2) first and last stamp (ns) of each still period, row k for period k."""
        ks = np.unique(self.segment[self.segment >= 0])
        out = np.zeros((ks.size, 2), dtype=np.int64)
        for k in ks:
            st = self.stamps[self.segment == k]
            out[k] = (st[0], st[-1])
        return out

    def still_at(self, t0_ns: int, t1_ns: int, periods: NDArray[np.int64] | None = None) -> int:
        """The still period that covers the whole interval ``[t0, t1]`` ns, or -1 (``periods``: a cached
        :meth:`periods`)."""
        per = self.periods() if periods is None else periods
        hit = np.nonzero((per[:, 0] <= t0_ns) & (t1_ns <= per[:, 1]))[0]
        return int(hit[0]) if hit.size else -1

    def at(self, t_ns: float, *, half_window_s: float = 0.1, min_scans: int = 3) -> FloatArray | None:
        """Values at ``t_ns``: a local linear fit over the scans within ``half_window_s``, or None."""
        dt = (self.stamps - t_ns) * 1e-9
        m = np.abs(dt) <= half_window_s
        if m.sum() < min_scans or dt[m].min() > 0.05 or dt[m].max() < -0.05:
            return None
        a = np.stack([np.ones(int(m.sum())), dt[m]], axis=1)
        coef, *_ = np.linalg.lstsq(a, self.values[m], rcond=None)
        out: FloatArray = coef[0]
        return out
