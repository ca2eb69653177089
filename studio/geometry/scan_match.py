"""Drift correction by scan matching: align each frame's laser points to a local map of recent keyframes.

Wheel odometry drifts: a few degrees of heading over a minute of driving move a wall 5 m away by a third
of a metre in the odometry frame. For offline labeling that blurs the static-world map (thin furniture legs
stop looking static and become false people) and bends the tracks of people seen across long gaps. The
scans themselves hold the fix: the room does not move.

:class:`ScanOdometry` turns the frames' points (base frame) and the odometry poses into corrected poses
``T_world_base``; the world frame is the odometry frame at the first frame. For each frame:

1. *prediction*: the previous corrected pose composed with the odometry increment since the previous frame
   (without odometry: the previous increment again, constant velocity);
2. *registration*: point-to-line ICP of the frame's points (minus those the caller marks as people) to the
   map — the points of the last ``map_keyframes`` keyframes that lie on straight surfaces, each with the
   normal of its surface — with
   Cauchy-weighted residuals and a match radius shrinking from ``max_match`` to ``min_match``; a direction
   the map does not constrain (a straight corridor) stays where the prediction put it;
3. *check*: the result is kept when enough points match (``min_inliers``, ``min_inlier_fraction`` within
   ``min_match``) and it moves the prediction by less than ``max_correction`` / ``max_correction_yaw``;
   otherwise the prediction stands (``rejected`` counts those frames);
4. a frame becomes a keyframe when the robot moved ``keyframe_distance`` or turned ``keyframe_angle``
   since the last one.

There is no loop closure: drift grows with the registration error of each keyframe (≈ 0.05° and a few mm
on the simulated rooms), far less than with wheel odometry; a scene with no structure in reach (an open
hall) falls back to the odometry frame by frame.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.spatial import cKDTree

from studio.geometry.errors import GeometryError
from studio.geometry.se import Pose2

__all__ = ["ScanMatchConfig", "ScanOdometry"]

FloatArray = NDArray[np.float64]


@dataclass(frozen=True)
class ScanMatchConfig:
    """Options of :class:`ScanOdometry` (distances in metres, angles in radians).

    Attributes:
        max_points: a frame's points are thinned to about this many (evenly along the scans) before ICP.
        map_keyframes: the map holds the points of this many latest keyframes.
        keyframe_distance, keyframe_angle: motion since the last keyframe that makes a new one.
        max_match, min_match: ICP match radius, shrinking from the first to the second over the iterations.
        iterations: ICP iterations.
        cauchy: scale of the Cauchy weight of a point-to-line residual.
        min_inliers, min_inlier_fraction: a registration counts when at least this many points, and this
            share of the points, end within ``min_match`` of the map.
        max_correction, max_correction_yaw: a registration that moves the prediction farther is rejected.
        every: with odometry, register every this many frames; the frames between follow the odometry from
            the last registered one (without odometry every frame is registered).
        normal_neighbours, normal_radius: a map point needs this many neighbours within this radius, all
            on a line (spread across the line at most ``max_flatness`` times the spread along it); its
            normal comes from them. Points on clutter, corners and sparse far returns are left out.
        max_flatness: see above.
    """

    max_points: int = 250
    map_keyframes: int = 8
    keyframe_distance: float = 0.3
    keyframe_angle: float = np.radians(10.0)
    max_match: float = 0.5
    min_match: float = 0.1
    iterations: int = 6
    cauchy: float = 0.05
    min_inliers: int = 40
    min_inlier_fraction: float = 0.4
    max_correction: float = 0.3
    max_correction_yaw: float = np.radians(5.0)
    every: int = 1
    normal_neighbours: int = 4
    normal_radius: float = 0.3
    max_flatness: float = 0.3

    def __post_init__(self) -> None:
        if (
            not (0 < self.min_match <= self.max_match)
            or self.iterations < 1
            or self.max_points < 10
            or self.every < 1
        ):
            raise GeometryError(
                "scan matching needs 0 < min_match <= max_match, iterations >= 1, max_points >= 10 and "
                "every >= 1"
            )


@dataclass
class _Map:
    points: FloatArray  # (N, 2) world frame
    normals: FloatArray  # (N, 2) unit
    tree: cKDTree


@dataclass
class ScanOdometry:
    """Corrected robot poses from odometry + scan matching, one frame at a time (module docstring).

    Attributes:
        config: options.
        matched, rejected: frames registered / frames where the prediction stood (no map yet, too few
            points, too few matches or too large a correction).
        skipped: frames between registrations (``every``).
    """

    config: ScanMatchConfig = field(default_factory=ScanMatchConfig)
    matched: int = 0
    rejected: int = 0
    skipped: int = 0
    _since: int = field(default=0, repr=False)
    _keyframes: list[tuple[FloatArray, FloatArray]] = field(default_factory=list, repr=False)
    _map: _Map | None = field(default=None, repr=False)
    _pose: Pose2 | None = field(default=None, repr=False)
    _odom: Pose2 | None = field(default=None, repr=False)
    _step: Pose2 = field(default_factory=Pose2, repr=False)
    _key_pose: Pose2 | None = field(default=None, repr=False)

    def step(self, points: ArrayLike, odom: Pose2 | None) -> Pose2:
        """The corrected pose ``T_world_base`` of the next frame.

        Args:
            points: ``(M, 2)`` the frame's static-looking laser points in the base frame (NaN rows ignored;
                leave out what the laser detector took for people).
            odom: the frame's odometry pose ``T_odom_base``, or None when the robot has no odometry.
        """
        cfg = self.config
        pts = np.asarray(points, dtype=np.float64).reshape(-1, 2)
        full = pts[np.all(np.isfinite(pts), axis=1)]
        pts = full
        if len(pts) > cfg.max_points:
            pts = pts[np.linspace(0, len(pts) - 1, cfg.max_points).round().astype(np.int64)]
        if self._pose is None:  # the first frame defines the world frame
            pose = Pose2() if odom is None else odom
        else:
            inc = self._step if odom is None or self._odom is None else self._odom.inverse().compose(odom)
            guess = self._pose.compose(inc)
            self._since += 1
            if odom is not None and self._since < cfg.every:
                self.skipped += 1
                self._pose, self._odom = guess, odom
                return guess
            self._since = 0
            registered = self._register(pts, guess)
            if registered is None:
                self.rejected += 1
                pose = guess
            else:
                self.matched += 1
                pose = registered
            self._step = self._pose.inverse().compose(pose)
        self._pose, self._odom = pose, odom
        key = self._key_pose
        if key is None or _moved(key, pose, cfg.keyframe_distance, cfg.keyframe_angle):
            self._add_keyframe(pose.apply(full))
            self._key_pose = pose
        return pose

    def _register(self, pts: FloatArray, guess: Pose2) -> Pose2 | None:
        cfg, m = self.config, self._map
        if m is None or len(pts) < cfg.min_inliers:
            return None
        x, y, th = guess.x, guess.y, guess.yaw
        radii = np.geomspace(cfg.max_match, cfg.min_match, cfg.iterations)
        for r in radii:
            c, s = np.cos(th), np.sin(th)
            p = pts @ np.array([[c, s], [-s, c]]) + (x, y)
            d, j = m.tree.query(p, distance_upper_bound=r)
            ok = np.isfinite(d)
            if ok.sum() < cfg.min_inliers:
                return None
            q, n, pk = m.points[j[ok]], m.normals[j[ok]], p[ok]
            res = np.einsum("ij,ij->i", pk - q, n)
            w = 1.0 / (1.0 + (res / cfg.cauchy) ** 2)
            # d(residual)/d(x, y, th) about the current estimate, rotation about the world origin
            J = np.column_stack([n[:, 0], n[:, 1], n[:, 1] * pk[:, 0] - n[:, 0] * pk[:, 1]])
            H = J.T @ (J * w[:, None])
            g = J.T @ (w * res)
            H += np.eye(3) * (1e-6 + 1e-6 * np.trace(H))  # an unconstrained direction stays put
            dx, dy, dth = np.linalg.solve(H, -g)
            # the increment rotates about the origin: apply it to the pose
            cd, sd = np.cos(dth), np.sin(dth)
            x, y = cd * x - sd * y + dx, sd * x + cd * y + dy
            th += dth
        c, s = np.cos(th), np.sin(th)
        d, _ = m.tree.query(pts @ np.array([[c, s], [-s, c]]) + (x, y), distance_upper_bound=cfg.min_match)
        inl = int(np.isfinite(d).sum())
        if inl < cfg.min_inliers or inl < cfg.min_inlier_fraction * len(pts):
            return None
        pose = Pose2(float(x), float(y), float(np.arctan2(np.sin(th), np.cos(th))))
        if _moved(guess, pose, cfg.max_correction, cfg.max_correction_yaw):
            return None
        return pose

    def _add_keyframe(self, world_pts: FloatArray) -> None:
        cfg = self.config
        self._keyframes = [*self._keyframes[-(cfg.map_keyframes - 1) :], _with_normals(world_pts, cfg)]
        pts = np.concatenate([k[0] for k in self._keyframes])
        if len(pts) < cfg.min_inliers:
            self._map = None
            return
        self._map = _Map(pts, np.concatenate([k[1] for k in self._keyframes]), cKDTree(pts))


def _with_normals(pts: FloatArray, cfg: ScanMatchConfig) -> tuple[FloatArray, FloatArray]:
    """The points of one scan that lie on a locally straight surface, and its normals there."""
    n = len(pts)
    k = cfg.normal_neighbours
    if n <= k:
        return np.zeros((0, 2)), np.zeros((0, 2))
    tree = cKDTree(pts)
    d, nb = tree.query(pts, k=k + 1, distance_upper_bound=cfg.normal_radius)
    full = np.isfinite(d).all(axis=1)  # k neighbours within the radius (sparse far returns have none)
    nb = nb[full]
    P = pts[nb] - pts[nb].mean(axis=1, keepdims=True)
    vals, vecs = np.linalg.eigh(np.einsum("nki,nkj->nij", P, P))  # ascending: [:, :, 0] is the normal
    line = vals[:, 0] <= cfg.max_flatness**2 * vals[:, 1]
    return pts[full][line], vecs[line][:, :, 0]


def _moved(a: Pose2, b: Pose2, distance: float, angle: float) -> bool:
    rel = a.inverse().compose(b)
    return bool(np.hypot(rel.x, rel.y) >= distance or abs(rel.yaw) >= angle)
