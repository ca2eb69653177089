"""The thesis baseline tracker: UKF + plain nearest neighbour in the robot frame.

It exists to be compared against (``studio label --method thesis``), on identical inputs. As in the thesis,
the caller passes positions in the *robot* frame (no odometry): every rotation or translation of the robot
moves all people in that frame, which a constant-velocity model with a fixed gate cannot follow — the main
source of its identity switches. Association is greedy by Euclidean distance within a fixed gate; every
unassociated detection starts a track at once; a track is dropped after a number of frames without a
detection. No Mahalanobis gating, no global assignment, no smoothing, no stitching.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from filterpy.kalman import UnscentedKalmanFilter

from studio.track.base import Observations, TrackEstimate
from studio.track.errors import TrackingError
from studio.track.gnn import greedy_assign
from studio.track.models import make_ukf, white_accel_q

__all__ = ["ThesisTracker", "ThesisTrackerConfig"]


@dataclass(frozen=True)
class ThesisTrackerConfig:
    """Options of :class:`ThesisTracker`.

    Attributes:
        gate_m: largest Euclidean distance between a track's prediction and its detection, metres.
        meas_sigma_m: fixed measurement standard deviation, metres (the observations' own covariances are
            not used).
        accel_sigma: white-noise acceleration of the CV model, m/s².
        init_speed_sigma: velocity standard deviation of a new track, m/s.
        max_misses: a track is dropped after this many consecutive frames without a detection.
    """

    gate_m: float = 0.5
    meas_sigma_m: float = 0.1
    accel_sigma: float = 1.5
    init_speed_sigma: float = 1.0
    max_misses: int = 5


@dataclass
class _Track:
    track_id: int
    ukf: UnscentedKalmanFilter
    stamp_ns: int
    misses: int = 0
    det_index: int = -1


class ThesisTracker:
    """UKF + greedy Euclidean nearest neighbour, robot frame. Implements :class:`~studio.track.base.Tracker`.

    Args:
        config: options.
        first_id: the id given to the first track.
    """

    def __init__(self, *, config: ThesisTrackerConfig | None = None, first_id: int = 0) -> None:
        self.config = config or ThesisTrackerConfig()
        self._tracks: list[_Track] = []
        self._next_id = first_id
        self._stamp_ns: int | None = None

    def step(self, obs: Observations) -> list[TrackEstimate]:
        """Predict, associate greedily, update, start and drop tracks.

        Returns:
            Estimates of all tracks (state ``"confirmed"`` when detected in this frame, else ``"lost"``),
            sorted by id.

        Raises:
            TrackingError: the stamp is earlier than the previous one.
        """
        cfg = self.config
        if self._stamp_ns is not None and obs.stamp_ns < self._stamp_ns:
            raise TrackingError(
                f"observation stamps must not decrease ({obs.stamp_ns} ns after {self._stamp_ns} ns)"
            )
        self._stamp_ns = obs.stamp_ns
        R = np.eye(2) * cfg.meas_sigma_m**2
        for t in self._tracks:
            dt = (obs.stamp_ns - t.stamp_ns) * 1e-9
            t.ukf.Q = white_accel_q(dt, cfg.accel_sigma)
            t.ukf.predict(dt=dt)
            t.stamp_ns = obs.stamp_ns
            t.det_index = -1
        pred = np.array([t.ukf.x[:2] for t in self._tracks]).reshape(-1, 2)
        dist = np.linalg.norm(pred[:, None, :] - obs.xy[None, :, :], axis=2)
        free = np.ones(len(obs), dtype=bool)
        matched = set()
        for r, k in greedy_assign(dist, cfg.gate_m):
            t = self._tracks[r]
            t.ukf.update(obs.xy[k], R=R)
            t.misses = 0
            t.det_index = int(obs.det_index[k])
            free[k] = False
            matched.add(r)
        for r, t in enumerate(self._tracks):
            if r not in matched:
                t.misses += 1
        self._tracks = [t for t in self._tracks if t.misses <= cfg.max_misses]
        for k in map(int, np.flatnonzero(free)):
            P0 = np.diag([cfg.meas_sigma_m**2] * 2 + [cfg.init_speed_sigma**2] * 2)
            ukf = make_ukf(np.array([obs.xy[k, 0], obs.xy[k, 1], 0.0, 0.0]), P0)
            self._tracks.append(_Track(self._next_id, ukf, obs.stamp_ns, det_index=int(obs.det_index[k])))
            self._next_id += 1
        return [
            TrackEstimate(
                t.track_id,
                t.stamp_ns,
                t.ukf.x[:2].copy(),
                t.ukf.x[2:].copy(),
                t.ukf.P[:2, :2].copy(),
                t.det_index,
                "confirmed" if t.det_index >= 0 else "lost",
            )
            for t in sorted(self._tracks, key=lambda t: t.track_id)
        ]
