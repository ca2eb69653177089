"""Online multi-person tracker: one UKF per track, Mahalanobis gating, global nearest neighbour.

Each track runs filterpy's :class:`~filterpy.kalman.UnscentedKalmanFilter` with the constant-velocity model
of :mod:`studio.track.models`; the time step comes from the integer-ns stamps (never a fixed rate) and each
observation brings its own measurement covariance. Association is one-to-one by the Hungarian algorithm on
the negative log-likelihood ``d² + log det S`` of the gated pairs (``d²`` the squared Mahalanobis distance,
gate from the χ² distribution with 2 degrees of freedom). An observation measured ``δ`` after the frame's
stamp (``Observations.dt_s``: a scanner's beams sweep, a scan a little off the camera frame) is compared
with the track's position ``δ`` later (``p + δ·v``, its covariance through ``[I δI]``). The update still
takes it as of the stamp (the offline smoother takes it at its time): updating through ``[I δI]`` too let
the furniture of leg_tracker's ``negative_2.bag`` walk (0.27 → 0.61 false people per frame, session 44).

Life cycle: an unmatched observation starts a *tentative* track; it becomes *confirmed* after M hits within
``confirm_window_s`` seconds of its birth, and dies at the first frame after that window without them (or
when unseen for ``tentative_max_coast_s``). The window is in seconds, not frames, so a sensor that observes
a person on only some frames (an image detector run at a lower rate than the frames) can still confirm
them. A confirmed track that misses a frame is *lost* (coasting on its prediction) until it is observed
again, or deleted when it has not been observed for ``max_coast_s`` seconds.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from filterpy.kalman import UnscentedKalmanFilter, unscented_transform
from numpy.typing import NDArray

from studio.track.appearance import appearance_matrix
from studio.track.base import Observations, TrackEstimate
from studio.track.errors import TrackingError
from studio.track.gnn import chi2_gate, gnn_assign, mahalanobis_costs
from studio.track.models import make_ukf, white_accel_q

__all__ = ["UkfTracker", "UkfTrackerConfig"]

FloatArray = NDArray[np.float64]


@dataclass(frozen=True)
class UkfTrackerConfig:
    """Options of :class:`UkfTracker`.

    Attributes:
        accel_sigma: white-noise acceleration of walking people, m/s² (see
            :func:`studio.track.models.white_accel_q`); larger follows stops and turns faster.
        init_speed_sigma: standard deviation of the unknown velocity of a new track, m/s.
        gate_prob: probability mass of the χ² (2 dof) gate on the squared Mahalanobis distance.
        use_logdet: add ``log det S`` to the assignment cost (prefers precise observations and tracks).
        confirm_hits: M, hits needed to confirm a tentative track ...
        confirm_window_s: ... within this many seconds of its birth; a tentative track still short of M
            hits is deleted at the first frame after that (0.45 s: 3 of the first 5 frames at 10 Hz).
        confirm_min_span_s: ... and its hits must span at least this long (birth to the confirming hit),
            seconds: M hits of a 40 Hz scanner come within 50 ms, too soon to tell a person from a leg or
            clutter that a 10 Hz sensor (M = 3: 0.2 s) would have had to follow longer. 0: hits alone.
        tentative_max_coast_s: a tentative track unobserved for longer than this is deleted, seconds.
        max_coast_s: a confirmed track unobserved for longer than this is deleted, seconds.
        birth_min_separation_m: an unmatched observation closer than this to a confirmed track's position
            starts no track (a duplicate detection of that person), metres.
        min_birth_score: unmatched observations with a lower score start no track.
        cascade: associate confirmed and lost tracks first, then tentative tracks with what is left
            (clutter-born tracks cannot steal a detection from an established track).
        report_tentative: :meth:`UkfTracker.step` also returns tentative tracks.
        appearance_gate: when set and both a track and an observation carry appearance descriptors, pairs
            whose colour difference (:func:`~studio.track.appearance.appearance_distance`, ΔE) exceeds this
            are not associated (off by default: one crop's colours vary with light, pose and occlusion; the
            offline stitcher compares medians over many observations).
        appearance_weight: added cost per unit of colour difference (0: appearance does not count).
        appearance_momentum: a track's descriptor is ``m·old + (1 − m)·new`` after each hit.
        split_pair_separation_m: where a laser leg pair went to a confirmed track and another confirmed
            track at least this far from it (predicted positions, metres) is left without an observation,
            the two legs go one to each when both fit (see ``Observations.alt_of``): two people so close
            that the laser paired a leg of each. None: pairs are never split.
        split_pair_max_relative_speed: ... and only when the two tracks move alike (m/s): people walking or
            standing together, whose legs pair across frame after frame. Two people passing each other
            pair across for a frame or two, and their motion carries them through better than legs that
            could be either's.
        alpha, beta, kappa: scaled sigma-point parameters of the UKF.
    """

    accel_sigma: float = 1.5
    init_speed_sigma: float = 1.0
    gate_prob: float = 0.999
    use_logdet: bool = True
    confirm_hits: int = 3
    confirm_window_s: float = 0.45
    confirm_min_span_s: float = 0.0
    tentative_max_coast_s: float = 0.5
    max_coast_s: float = 2.0
    birth_min_separation_m: float = 0.25
    min_birth_score: float = 0.0
    cascade: bool = True
    report_tentative: bool = False
    appearance_gate: float | None = None
    appearance_weight: float = 0.0
    appearance_momentum: float = 0.8
    split_pair_separation_m: float | None = 0.25
    split_pair_max_relative_speed: float = 0.6
    alpha: float = 1.0
    beta: float = 2.0
    kappa: float = 0.0

    def __post_init__(self) -> None:
        if self.confirm_hits < 1 or not self.confirm_window_s >= 0:
            raise ValueError("need confirm_hits >= 1 and confirm_window_s >= 0")
        if not 0 <= self.confirm_min_span_s <= self.confirm_window_s:
            raise ValueError("need 0 <= confirm_min_span_s <= confirm_window_s")
        if self.accel_sigma <= 0 or self.init_speed_sigma <= 0:
            raise ValueError("accel_sigma and init_speed_sigma must be positive")
        if self.max_coast_s < 0 or self.tentative_max_coast_s < 0:
            raise ValueError("coast times must be non-negative")
        chi2_gate(self.gate_prob)


def _predicted(group: list[_Track], dt: FloatArray | None) -> tuple[FloatArray, FloatArray]:
    """The tracks' predicted positions and their covariances: (T, 2), (T, 2, 2) at the stamp, or (T, N, 2),
    (T, N, 2, 2) at each observation's measurement time when ``dt`` (N,) has any non-zero."""
    zp = np.array([t.z_pred for t in group])
    Pz = np.array([t.Pz for t in group])
    if dt is None or not np.any(dt):
        return zp, Pz
    x = np.array([t.ukf.x for t in group])  # the predicted states (the filter's prior after predict)
    P = np.array([t.ukf.P for t in group])
    d = dt[None, :, None]
    zp_dt = x[:, None, :2] + d * x[:, None, 2:4]
    cross = P[:, None, :2, 2:] + P[:, None, 2:, :2]
    Pz_dt = P[:, None, :2, :2] + d[..., None] * cross + (d**2)[..., None] * P[:, None, 2:, 2:]
    return zp_dt, Pz_dt


@dataclass
class _Track:
    track_id: int
    ukf: UnscentedKalmanFilter
    stamp_ns: int
    last_hit_ns: int
    birth_ns: int
    state: str = "tentative"
    hits: int = 1
    det_index: int = -1
    appearance: NDArray[np.float32] | None = None
    z_pred: FloatArray = field(default_factory=lambda: np.zeros(2))
    Pz: FloatArray = field(default_factory=lambda: np.eye(2))

    def estimate(self) -> TrackEstimate:
        x, P = self.ukf.x, self.ukf.P
        return TrackEstimate(
            self.track_id,
            self.stamp_ns,
            x[:2].copy(),
            x[2:].copy(),
            P[:2, :2].copy(),
            self.det_index,
            self.state,
        )


class UkfTracker:
    """UKF + GNN multi-person tracker (module docstring); a :class:`~studio.track.base.Tracker`.

    Args:
        config: options; the defaults suit walking people observed at 5–20 Hz.
        first_id: the id given to the first track.
    """

    def __init__(self, *, config: UkfTrackerConfig | None = None, first_id: int = 0) -> None:
        self.config = config or UkfTrackerConfig()
        self._gate = chi2_gate(self.config.gate_prob)
        self._tracks: list[_Track] = []
        self._next_id = first_id
        self._stamp_ns: int | None = None

    @property
    def tracks(self) -> list[TrackEstimate]:
        """Current estimates of all live tracks (tentative ones included)."""
        return [t.estimate() for t in self._tracks]

    def step(self, obs: Observations) -> list[TrackEstimate]:
        """Predict all tracks to ``obs.stamp_ns``, associate, update, manage the life cycle.

        Returns:
            Estimates of the confirmed and lost tracks (and tentative ones if ``report_tentative``), sorted
            by track id; ``det_index`` says which observation updated each track (-1: coasting).

        Raises:
            TrackingError: the stamp is earlier than the previous one.
        """
        cfg = self.config
        if self._stamp_ns is not None and obs.stamp_ns < self._stamp_ns:
            raise TrackingError(
                f"observation stamps must not decrease ({obs.stamp_ns} ns after {self._stamp_ns} ns)"
            )
        self._stamp_ns = obs.stamp_ns
        window_ns = cfg.confirm_window_s * 1e9
        self._tracks = [
            t for t in self._tracks if t.state != "tentative" or obs.stamp_ns - t.birth_ns <= window_ns
        ]  # too few hits in the confirmation window
        for t in self._tracks:
            self._predict(t, obs.stamp_ns)

        free = ~obs.alternative  # a pair's legs: only through _split_pairs; other pairings: offline
        groups = (
            [
                [t for t in self._tracks if t.state != "tentative"],
                [t for t in self._tracks if t.state == "tentative"],
            ]
            if cfg.cascade
            else [list(self._tracks)]
        )
        matched: dict[int, int] = {}
        for group in groups:
            cols = np.flatnonzero(free)
            if not group or not len(cols):
                continue
            zp, Pz = _predicted(group, None if obs.dt_s is None else obs.dt_s[cols])
            d2, logdet = mahalanobis_costs(zp, Pz, obs.xy[cols], obs.cov[cols])
            cost = d2 + logdet if cfg.use_logdet else d2
            allowed = d2 <= self._gate
            self._appearance_terms(group, obs, cols, cost, allowed)
            for r, k in gnn_assign(cost, allowed):
                matched[group[r].track_id] = int(cols[k])
                free[cols[k]] = False
            self._split_pairs([t for t in group if t.state != "tentative"], obs, matched)

        for t in list(self._tracks):
            row = matched.get(t.track_id)
            if row is None:
                self._miss(t, obs.stamp_ns)
            else:
                self._hit(t, obs, row)
        self._tracks = [t for t in self._tracks if t.state != "deleted"]
        self._births(obs, free)
        keep = ("tentative", "confirmed", "lost") if cfg.report_tentative else ("confirmed", "lost")
        return [t.estimate() for t in sorted(self._tracks, key=lambda t: t.track_id) if t.state in keep]

    # -- internals -------------------------------------------------------------------------------------

    def _predict(self, t: _Track, stamp_ns: int) -> None:
        dt = (stamp_ns - t.stamp_ns) * 1e-9
        t.ukf.Q = white_accel_q(dt, self.config.accel_sigma)
        t.ukf.predict(dt=dt)  # also with dt = 0: refreshes the sigma points used below
        t.stamp_ns = stamp_ns
        t.det_index = -1
        sigmas_h = np.array([t.ukf.hx(s) for s in t.ukf.sigmas_f])
        t.z_pred, t.Pz = unscented_transform(sigmas_h, t.ukf.Wm, t.ukf.Wc)

    def _split_pairs(self, group: list[_Track], obs: Observations, matched: dict[int, int]) -> None:
        """Give a leg pair's two legs to two established tracks instead of the pair to one (in place).

        Only where the tracks are at least ``split_pair_separation_m`` apart, their velocities differ by at
        most ``split_pair_max_relative_speed``, and each leg lies within ``split_pair_separation_m`` of its
        track, nearer to it than to the other, inside both gates; of several such tracks the one whose
        leg costs least.
        """
        sep = self.config.split_pair_separation_m
        if obs.alt_of is None or sep is None:
            return
        idle = [t for t in group if t.track_id not in matched]
        for a in group:
            row = matched.get(a.track_id)
            if row is None or not idle:
                continue
            legs = np.flatnonzero(obs.alt_of == row)
            if len(legs) != 2:
                continue
            best: tuple[float, _Track, int, int] | None = None
            for b in idle:
                if np.hypot(*(a.z_pred - b.z_pred)) < sep:
                    continue
                if np.hypot(*(a.ukf.x[2:4] - b.ukf.x[2:4])) > self.config.split_pair_max_relative_speed:
                    continue  # passing each other: their motion carries them through a frame or two
                zp, Pz = np.array([a.z_pred, b.z_pred]), np.array([a.Pz, b.Pz])
                d = np.hypot(*(zp[:, None, :] - obs.xy[legs][None, :, :]).transpose(2, 0, 1))  # (track, leg)
                d2, logdet = mahalanobis_costs(zp, Pz, obs.xy[legs], obs.cov[legs])
                cost = d2 + logdet if self.config.use_logdet else d2
                for la, lb in ((0, 1), (1, 0)):
                    if max(d[0, la], d[1, lb]) > sep or d[0, la] > d[1, la] or d[1, lb] > d[0, lb]:
                        continue
                    if d2[0, la] > self._gate or d2[1, lb] > self._gate:
                        continue
                    c = cost[0, la] + cost[1, lb]
                    if best is None or c < best[0]:
                        best = (float(c), b, int(legs[la]), int(legs[lb]))
            if best is not None:
                _, b, la, lb = best
                matched[a.track_id], matched[b.track_id] = la, lb
                idle.remove(b)

    def _appearance_terms(
        self,
        group: list[_Track],
        obs: Observations,
        cols: NDArray[np.intp],
        cost: FloatArray,
        allowed: NDArray[np.bool_],
    ) -> None:
        """Add the appearance cost and gate in place (pairs where both sides have descriptors)."""
        cfg = self.config
        if obs.appearance is None or (cfg.appearance_gate is None and cfg.appearance_weight == 0.0):
            return
        rows = [r for r, t in enumerate(group) if t.appearance is not None]
        if not rows:
            return
        A = np.array([group[r].appearance for r in rows])
        if A.shape[1] != obs.appearance.shape[1]:
            return
        B = obs.appearance[cols]
        has = np.all(np.isfinite(B), axis=1)
        D = np.zeros((len(rows), len(cols)))
        if has.any():
            D[:, has] = appearance_matrix(A, B[has])
        cost[rows] += cfg.appearance_weight * D
        if cfg.appearance_gate is not None:
            allowed[rows] &= cfg.appearance_gate >= D

    def _hit(self, t: _Track, obs: Observations, row: int) -> None:
        cfg = self.config
        if obs.appearance is not None and np.all(np.isfinite(obs.appearance[row])):
            new = obs.appearance[row]
            m = cfg.appearance_momentum
            old = t.appearance
            if old is not None and old.shape == new.shape:
                t.appearance = (m * old + (1.0 - m) * new).astype(np.float32)
            else:
                t.appearance = new.copy()
        t.ukf.update(obs.xy[row], R=obs.cov[row])
        t.ukf.P = 0.5 * (t.ukf.P + t.ukf.P.T)
        t.det_index = int(obs.det_index[row])
        t.last_hit_ns = obs.stamp_ns
        if t.state == "tentative":
            t.hits += 1
            span_s = (obs.stamp_ns - t.birth_ns) * 1e-9
            if t.hits >= cfg.confirm_hits and span_s >= cfg.confirm_min_span_s - 1e-6:
                t.state = "confirmed"
        else:
            t.state = "confirmed"

    def _miss(self, t: _Track, stamp_ns: int) -> None:
        cfg = self.config
        unseen_s = (stamp_ns - t.last_hit_ns) * 1e-9
        if t.state == "tentative":
            if unseen_s > cfg.tentative_max_coast_s:
                t.state = "deleted"
        elif unseen_s > cfg.max_coast_s:
            t.state = "deleted"
        else:
            t.state = "lost"

    def _births(self, obs: Observations, free: NDArray[np.bool_]) -> None:
        cfg = self.config
        anchors = np.array([t.ukf.x[:2] for t in self._tracks if t.state != "tentative"]).reshape(-1, 2)
        for row in np.flatnonzero(free):
            if obs.score[row] < cfg.min_birth_score:
                continue
            if len(anchors) and np.min(np.hypot(*(anchors - obs.xy[row]).T)) < cfg.birth_min_separation_m:
                continue
            P0 = np.zeros((4, 4))
            P0[:2, :2] = obs.cov[row]
            P0[2:, 2:] = np.eye(2) * cfg.init_speed_sigma**2
            x0 = np.array([obs.xy[row, 0], obs.xy[row, 1], 0.0, 0.0])
            ukf = make_ukf(x0, P0, alpha=cfg.alpha, beta=cfg.beta, kappa=cfg.kappa)
            t = _Track(
                self._next_id,
                ukf,
                obs.stamp_ns,
                obs.stamp_ns,
                obs.stamp_ns,
                det_index=int(obs.det_index[row]),
                appearance=None
                if obs.appearance is None or not np.all(np.isfinite(obs.appearance[row]))
                else obs.appearance[row].copy(),
            )
            if cfg.confirm_hits <= 1 and cfg.confirm_min_span_s <= 0:
                t.state = "confirmed"
            self._next_id += 1
            self._tracks.append(t)
