"""Readers for the real laser bags in ``../shared/data/leg_tracker`` used by the laser benches.

Shared by ``bench_laser_detector.py`` and ``laser_sweep.py``; bags are read with ``studio.io``.
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numpy.typing import NDArray
from scipy.spatial import cKDTree

from studio.io import decode_scan, open_recording

__all__ = ["DATA", "Scan", "icp_odometry", "labelled_scans", "read_scans"]

DATA = Path(__file__).resolve().parents[1] / ".." / "shared" / "data" / "leg_tracker"


@dataclass(frozen=True)
class Scan:
    """One decoded scan: beams in angle order in the laser frame."""

    topic: str
    stamp_ns: int
    points: NDArray[np.float64]  # (M, 2), NaN where invalid
    valid: NDArray[np.bool_]  # (M,)
    angle_increment: float


def _scan(topic: str, msg: object, log_ns: int) -> Scan:
    ls = decode_scan(msg, log_ns)
    return Scan(topic, ls.stamp_ns, ls.points(), ls.valid(), float(ls.angle_increment))


def read_scans(bag: Path, topics: list[str] | None = None) -> Iterator[Scan]:
    """Every LaserScan of ``bag`` (optionally only ``topics``), in log-time order, through ``studio.io``."""
    with open_recording(bag) as rec:
        names = [t for t, info in rec.topics.items() if info.msgtype.endswith("LaserScan")]
        if topics is not None:
            names = [rec.resolve_topic(t) for t in topics]
        for raw in rec.messages(names):
            yield _scan(raw.topic, rec.decode(raw), raw.log_ns)


def labelled_scans(bag: Path) -> list[tuple[Scan, NDArray[np.float64]]]:
    """``(scan, legs (K, 2))`` pairs of a ``legs_labelled/*_extracted.bag``.

    Each ``/leg_cluster_positions`` PoseArray (leg positions in the laser frame) precedes its
    ``/training_scan`` in the bag; a scan without one gets no legs.
    """
    out: list[tuple[Scan, NDArray[np.float64]]] = []
    legs = np.zeros((0, 2))
    with open_recording(bag) as rec:
        for raw in rec.messages(["/training_scan", "/leg_cluster_positions"]):
            m = rec.decode(raw)
            if raw.topic == "/leg_cluster_positions":
                legs = np.array([[q.position.x, q.position.y] for q in m.poses], dtype=np.float64)
                legs = legs.reshape(-1, 2)
                continue
            out.append((_scan(raw.topic, m, raw.log_ns), legs))
            legs = np.zeros((0, 2))
    return out


def _icp(src: np.ndarray, dst: np.ndarray, tree: cKDTree, init: np.ndarray, *, iters: int = 30) -> np.ndarray:
    """3×3 transform taking ``src`` points onto ``dst`` (point-to-point ICP, shrinking match radius)."""
    T = init.copy()
    for it in range(iters):
        p = src @ T[:2, :2].T + T[:2, 2]
        d, j = tree.query(p, distance_upper_bound=0.5 if it < 10 else 0.2)
        ok = np.isfinite(d)
        if ok.sum() < 20:
            break
        a, b = p[ok], dst[j[ok]]
        ca, cb = a.mean(0), b.mean(0)
        U, _, Vt = np.linalg.svd((a - ca).T @ (b - cb))
        R = Vt.T @ U.T
        if np.linalg.det(R) < 0:
            Vt[-1] *= -1
            R = Vt.T @ U.T
        step = np.eye(3)
        step[:2, :2] = R
        step[:2, 2] = cb - R @ ca
        T = step @ T
        if np.hypot(*step[:2, 2]) < 1e-4 and abs(np.arctan2(R[1, 0], R[0, 0])) < 1e-5:
            break
    return T


def icp_odometry(scans: list[Scan], *, keyframe_move: float = 0.4) -> list[np.ndarray]:
    """Poses (3×3, odom ← laser) of one scanner's scans by scan matching against a moving keyframe.

    For bags without odometry (``negative_2.bag``): the first scan defines the odom frame.
    """
    poses: list[np.ndarray] = []
    key_pts: np.ndarray | None = None
    key_pose = np.eye(3)
    tree: cKDTree | None = None
    last = np.eye(3)
    for scan in scans:
        pts = scan.points[scan.valid]
        if key_pts is None or tree is None:
            key_pts, tree, key_pose, last = pts, cKDTree(pts), np.eye(3), np.eye(3)
            poses.append(np.eye(3))
            continue
        rel0 = np.linalg.inv(key_pose) @ last  # key ← previous scan, as the initial guess
        rel = _icp(pts, key_pts, tree, rel0)
        pose = key_pose @ rel
        poses.append(pose)
        last = pose
        if np.hypot(*rel[:2, 2]) > keyframe_move or abs(np.arctan2(rel[1, 0], rel[0, 0])) > 0.2:
            key_pts, tree, key_pose = pts, cKDTree(pts), pose
    return poses
