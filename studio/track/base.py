"""Contracts of the tracking stage: observations in, track estimates out.

A tracker consumes one :class:`Observations` per labeled frame (people's positions in the *tracking frame*:
the odom frame for our method, the robot frame for the thesis baseline) and returns
:class:`TrackEstimate` objects with persistent ``track_id``\\ s. :func:`track_sequence` runs an online tracker
over a whole recording and collects a :class:`TrackResult`; the offline labeler
(:func:`studio.track.offline.track_offline`) returns the same type, with smoothed and interpolated points.

Time stamps are integer nanoseconds; positions metres, covariances m², velocities m/s.
"""

from __future__ import annotations

from collections.abc import Iterable, Iterator, Sequence
from dataclasses import dataclass, field, replace
from typing import Protocol, runtime_checkable

import numpy as np
from numpy.typing import ArrayLike, NDArray

from studio.geometry.se import Pose2
from studio.track.sight import ScanView

__all__ = [
    "OBSERVATION_SOURCES",
    "TRACK_STATES",
    "Observations",
    "TrackEstimate",
    "TrackFrame",
    "TrackPoint",
    "TrackResult",
    "Tracker",
    "track_sequence",
]

OBSERVATION_SOURCES = ("fused", "laser", "image")
TRACK_STATES = ("tentative", "confirmed", "lost")

FloatArray = NDArray[np.float64]


def _check_cov(cov: FloatArray, what: str) -> None:
    if not np.all(np.isfinite(cov)):
        raise ValueError(f"{what}: covariance must be finite")
    if not np.allclose(cov, np.swapaxes(cov, -1, -2), atol=1e-9, rtol=1e-6):
        raise ValueError(f"{what}: covariance must be symmetric")
    if cov.size and np.any(np.linalg.eigvalsh(cov) <= 0.0):
        raise ValueError(f"{what}: covariance must be positive definite")


@dataclass(frozen=True)
class Observations:
    """People observed in one frame, in the tracking frame.

    Attributes:
        stamp_ns: time of the frame, integer nanoseconds.
        xy: (N, 2) float64 positions, metres.
        cov: (N, 2, 2) float64 position covariances, m² (symmetric positive definite).
        source: N strings, each ``"fused"``, ``"laser"`` or ``"image"``.
        score: (N,) float64 detection confidences.
        appearance: (N, D) float32 appearance descriptors (e.g. clothing colours) or None;
            an all-NaN row means that observation has no descriptor (e.g. a laser-only person).
        det_index: (N,) int64 index of each observation among the frame's detections, so that tracker
            outputs can be joined back to boxes and labels.
        alt_of: (N,) int64 or None. A row ``k`` with ``alt_of[k] = j ≥ 0`` is not an observation of its own
            but one leg of the laser leg pair in row ``j`` (whose ``alt_of`` is -1): a tracker never gives it
            out alone, only both legs of ``j`` to two tracks instead of ``j`` to one (two people close
            enough for the laser to pair a leg of each). None: no such rows.
        dt_s: (N,) float64 or None: when each observation was measured, seconds after ``stamp_ns`` (a scan
            taken before or after the frame, a beam late in a scanner's sweep); the online association and
            the offline smoother take a person's motion over it into account. None: all at ``stamp_ns``.
        view: what the scanners saw in this frame (:class:`~studio.track.sight.ScanView`, tracking frame), or
            None: the offline tracker does not bridge a gap by a walk through places seen empty.
        joins: (N, 2) int64 or None. A row ``k`` with ``joins[k] = (la, lb)`` (two leg rows of two different
            leg pairs) is not an observation of its own either but the midpoint of those two legs: the other
            way to pair the legs of two people side by side, where the laser detector paired a leg of each.
            A tracker gives it out only together with its :meth:`complement` (the other two legs), to two
            tracks instead of the two pairs; ``(-1, -1)`` for every other row. None: no such rows.
    """

    stamp_ns: int
    xy: FloatArray
    cov: FloatArray
    source: tuple[str, ...]
    score: FloatArray
    appearance: NDArray[np.float32] | None
    det_index: NDArray[np.int64]
    alt_of: NDArray[np.int64] | None = None
    dt_s: FloatArray | None = None
    view: ScanView | None = None
    joins: NDArray[np.int64] | None = None

    def __post_init__(self) -> None:
        if isinstance(self.stamp_ns, bool) or not isinstance(self.stamp_ns, int | np.integer):
            raise ValueError(f"stamp_ns must be an integer (ns), got {self.stamp_ns!r}")
        object.__setattr__(self, "stamp_ns", int(self.stamp_ns))
        xy = np.asarray(self.xy, dtype=np.float64).reshape(-1, 2)
        n = len(xy)
        if not np.all(np.isfinite(xy)):
            raise ValueError("observation positions must be finite")
        cov = np.asarray(self.cov, dtype=np.float64)
        if cov.shape != (n, 2, 2):
            raise ValueError(f"cov must have shape ({n}, 2, 2), got {cov.shape}")
        _check_cov(cov, "observation")
        source = tuple(str(s) for s in self.source)
        if len(source) != n or any(s not in OBSERVATION_SOURCES for s in source):
            raise ValueError(f"source must be {n} values out of {OBSERVATION_SOURCES}, got {source}")
        score = np.asarray(self.score, dtype=np.float64).reshape(-1)
        if score.shape != (n,):
            raise ValueError(f"score must have shape ({n},), got {score.shape}")
        app = self.appearance
        if app is not None:
            app = np.asarray(app, dtype=np.float32)
            fin = np.isfinite(app)
            if app.ndim != 2 or len(app) != n or not np.all(fin.all(axis=1) | (~fin).all(axis=1)):
                raise ValueError(f"appearance must be a ({n}, D) array of finite rows (all-NaN row: none)")
        det = np.asarray(self.det_index)
        if det.shape != (n,) or (n and not np.issubdtype(det.dtype, np.integer)):
            raise ValueError(f"det_index must be ({n},) integers")
        if len(np.unique(det)) != n:
            raise ValueError("det_index values must be unique within a frame")
        for name, value in (("xy", xy), ("cov", cov), ("score", score), ("det_index", det.astype(np.int64))):
            value.flags.writeable = False
            object.__setattr__(self, name, value)
        if self.alt_of is not None:
            alt = np.asarray(self.alt_of)
            if alt.shape != (n,) or (n and not np.issubdtype(alt.dtype, np.integer)):
                raise ValueError(f"alt_of must be ({n},) integers")
            alt = alt.astype(np.int64)
            parent = alt[alt >= 0]
            if np.any(alt < -1) or np.any(parent >= n) or np.any(alt[parent] != -1):
                raise ValueError("alt_of must be -1 or the row of an observation that is not an alternative")
            alt.flags.writeable = False
            object.__setattr__(self, "alt_of", alt)
        if self.joins is not None:
            self._check_joins(n)
        if self.dt_s is not None:
            dt = np.asarray(self.dt_s, dtype=np.float64)
            if dt.shape != (n,) or not np.all(np.isfinite(dt)):
                raise ValueError(f"dt_s must be ({n},) finite seconds")
            dt.flags.writeable = False
            object.__setattr__(self, "dt_s", dt)
        if app is not None:
            app.flags.writeable = False
        object.__setattr__(self, "appearance", app)
        object.__setattr__(self, "source", source)

    def _check_joins(self, n: int) -> None:
        joins = np.asarray(self.joins)
        if joins.shape != (n, 2) or (n and not np.issubdtype(joins.dtype, np.integer)):
            raise ValueError(f"joins must be ({n}, 2) integers")
        joins = joins.astype(np.int64)
        rows = np.flatnonzero(joins[:, 0] >= 0)
        alt = self.alt_of if self.alt_of is not None else np.full(n, -1, np.int64)
        legs = joins[rows]
        ok = bool(np.all((joins >= -1) & (joins < n)) and np.all((joins[:, 0] >= 0) == (joins[:, 1] >= 0)))
        ok = ok and bool(np.all(alt[rows] < 0) and np.all(joins[alt[alt >= 0], 0] < 0))
        ok = ok and bool(np.all(alt[legs] >= 0) and np.all(alt[legs[:, 0]] != alt[legs[:, 1]]))
        if not ok:
            raise ValueError("joins must be -1 or two leg rows (alt_of >= 0) of two different leg pairs")
        joins.flags.writeable = False
        object.__setattr__(self, "joins", joins)

    def __len__(self) -> int:
        return len(self.xy)

    @property
    def alternative(self) -> NDArray[np.bool_]:
        """(N,) the rows that are not observations of their own: legs of a pair (``alt_of``) and midpoints
        of two legs of different pairs (``joins``). A tracker gives them out only as those fields say."""
        out = np.zeros(len(self.xy), dtype=bool)
        if self.alt_of is not None:
            out |= self.alt_of >= 0
        if self.joins is not None:
            out |= self.joins[:, 0] >= 0
        return out

    def origin(self, row: int) -> int:
        """The observation whose detection a row comes from: the pair of a leg, the pair of the first leg of
        a midpoint of two legs (``joins``), else the row itself."""
        if self.joins is not None and self.joins[row, 0] >= 0:
            row = int(self.joins[row, 0])
        if self.alt_of is not None and self.alt_of[row] >= 0:
            return int(self.alt_of[row])
        return row

    def complement(self, row: int) -> int:
        """For a midpoint of two legs (``joins``), the midpoint of the other two legs of the same two pairs
        (-1 where the frame has none); -1 for any other row."""
        if self.joins is None or self.joins[row, 0] < 0 or self.alt_of is None:
            return -1
        legs = set(self.joins[row].tolist())
        pairs = {int(self.alt_of[leg]) for leg in legs}
        for k in np.flatnonzero(self.joins[:, 0] >= 0):
            other = set(self.joins[k].tolist())
            if not other & legs and {int(self.alt_of[leg]) for leg in other} == pairs:
                return int(k)
        return -1

    def regroupings(self, a: int, b: int) -> list[tuple[int, int]]:
        """The couples of midpoint rows (``joins``) that pair the four legs of leg pairs ``a`` and ``b`` the
        other ways, each couple once; empty when the frame has none for these two pairs."""
        if self.joins is None or self.alt_of is None or a == b:
            return []
        out = []
        for k in np.flatnonzero(self.joins[:, 0] >= 0):
            if {int(self.alt_of[leg]) for leg in self.joins[k]} == {a, b}:
                c = self.complement(int(k))
                if c > k:
                    out.append((int(k), c))
        return out

    def transformed(self, pose: Pose2) -> Observations:
        """The same observations in another frame: ``pose`` is ``T_new_old`` (e.g. the robot's odom pose
        at this frame to go from the robot frame to the odom frame); covariances are rotated too, and the
        scanners' view is left behind (its bins of bearing belong to the old frame)."""
        c, s = np.cos(pose.yaw), np.sin(pose.yaw)
        R = np.array([[c, -s], [s, c]])
        return replace(self, xy=pose.apply(self.xy), cov=R @ self.cov @ R.T, view=None)

    @staticmethod
    def empty(stamp_ns: int) -> Observations:
        """A frame without observations."""
        return Observations(
            stamp_ns, np.zeros((0, 2)), np.zeros((0, 2, 2)), (), np.zeros(0), None, np.zeros(0, np.int64)
        )

    @staticmethod
    def create(
        stamp_ns: int,
        xy: ArrayLike,
        *,
        cov: ArrayLike | None = None,
        sigma_m: float = 0.1,
        source: str | Sequence[str] = "fused",
        score: ArrayLike | None = None,
        appearance: ArrayLike | None = None,
        det_index: ArrayLike | None = None,
    ) -> Observations:
        """Build observations with defaults for what is not given.

        Args:
            stamp_ns: frame time, ns.
            xy: (N, 2) positions, metres.
            cov: (N, 2, 2) covariances, m²; default ``sigma_m² · I``.
            sigma_m: isotropic standard deviation used when ``cov`` is None, metres.
            source: one source for all, or N of them.
            score: (N,) confidences; default 1.
            appearance: (N, D) descriptors or None.
            det_index: (N,) detection indices; default ``0..N-1``.
        """
        p = np.asarray(xy, dtype=np.float64).reshape(-1, 2)
        n = len(p)
        c = np.tile(np.eye(2) * sigma_m**2, (n, 1, 1)) if cov is None else np.asarray(cov, np.float64)
        src = (source,) * n if isinstance(source, str) else tuple(source)
        sc = np.ones(n) if score is None else np.asarray(score, np.float64)
        app = None if appearance is None else np.asarray(appearance, np.float32)
        det = np.arange(n, dtype=np.int64) if det_index is None else np.asarray(det_index, np.int64)
        return Observations(int(stamp_ns), p, c, src, sc, app, det)


@dataclass(frozen=True)
class TrackEstimate:
    """The state of one track after a tracker step.

    Attributes:
        track_id: persistent identity (≥ 0).
        stamp_ns: time of the estimate, ns.
        xy: (2,) position, metres.
        vxy: (2,) velocity, m/s.
        cov: (2, 2) position covariance, m².
        det_index: ``det_index`` of the observation that updated the track in this step, -1 when coasting.
        state: ``"tentative"``, ``"confirmed"`` or ``"lost"`` (confirmed but coasting).
    """

    track_id: int
    stamp_ns: int
    xy: FloatArray
    vxy: FloatArray
    cov: FloatArray
    det_index: int
    state: str

    def __post_init__(self) -> None:
        object.__setattr__(self, "xy", np.asarray(self.xy, dtype=np.float64).reshape(2))
        object.__setattr__(self, "vxy", np.asarray(self.vxy, dtype=np.float64).reshape(2))
        cov = np.asarray(self.cov, dtype=np.float64)
        if cov.shape != (2, 2):
            raise ValueError(f"track {self.track_id}: cov must be 2×2")
        object.__setattr__(self, "cov", cov)
        if self.state not in TRACK_STATES:
            raise ValueError(f"track {self.track_id}: state must be one of {TRACK_STATES}")


@runtime_checkable
class Tracker(Protocol):
    """An online multi-target tracker."""

    def step(self, obs: Observations) -> list[TrackEstimate]:
        """Advance to ``obs.stamp_ns``, associate and update; return the live tracks' estimates."""
        ...


@dataclass(frozen=True)
class TrackPoint:
    """One track's position in one frame of a :class:`TrackResult`.

    Attributes:
        track_id: identity.
        xy: (2,) position in the tracking frame, metres.
        cov: (2, 2) position covariance, m².
        det_index: the frame's detection this point belongs to, -1 when there is none.
        smoothed: the position comes from the RTS smoother (uses past and future observations).
        interpolated: no observation of this track in this frame (bridged gap); ``det_index`` is -1.
        vxy: (2,) velocity, m/s.
    """

    track_id: int
    xy: FloatArray
    cov: FloatArray
    det_index: int = -1
    smoothed: bool = False
    interpolated: bool = False
    vxy: FloatArray = field(default_factory=lambda: np.zeros(2))

    def __post_init__(self) -> None:
        object.__setattr__(self, "track_id", int(self.track_id))
        object.__setattr__(self, "det_index", int(self.det_index))
        object.__setattr__(self, "xy", np.asarray(self.xy, dtype=np.float64).reshape(2))
        object.__setattr__(self, "vxy", np.asarray(self.vxy, dtype=np.float64).reshape(2))
        cov = np.asarray(self.cov, dtype=np.float64)
        if cov.shape != (2, 2):
            raise ValueError(f"track {self.track_id}: cov must be 2×2")
        object.__setattr__(self, "cov", cov)


@dataclass(frozen=True)
class TrackFrame:
    """The tracks present in one frame (``points`` sorted by track id)."""

    stamp_ns: int
    points: tuple[TrackPoint, ...] = ()

    def __post_init__(self) -> None:
        object.__setattr__(self, "stamp_ns", int(self.stamp_ns))
        pts = tuple(sorted(self.points, key=lambda p: p.track_id))
        ids = [p.track_id for p in pts]
        if len(set(ids)) != len(ids):
            raise ValueError(f"frame {self.stamp_ns}: a track id appears twice")
        object.__setattr__(self, "points", pts)


@dataclass(frozen=True)
class TrackResult:
    """Tracks over a whole sequence: one :class:`TrackFrame` per input frame, in input order."""

    frames: tuple[TrackFrame, ...]

    def __post_init__(self) -> None:
        object.__setattr__(self, "frames", tuple(self.frames))

    def __len__(self) -> int:
        return len(self.frames)

    def __iter__(self) -> Iterator[TrackFrame]:
        return iter(self.frames)

    def track_ids(self) -> list[int]:
        """All track ids, sorted."""
        return sorted({p.track_id for f in self.frames for p in f.points})

    def tracks(self) -> dict[int, list[tuple[int, TrackPoint]]]:
        """Per track id, its ``(frame index, point)`` pairs in frame order."""
        out: dict[int, list[tuple[int, TrackPoint]]] = {}
        for i, f in enumerate(self.frames):
            for p in f.points:
                out.setdefault(p.track_id, []).append((i, p))
        return out


def track_sequence(
    tracker: Tracker,
    observations: Iterable[Observations],
    *,
    states: Sequence[str] = ("confirmed", "lost"),
    include_coasting: bool = False,
) -> TrackResult:
    """Run an online tracker over a sequence of frames.

    Args:
        tracker: the tracker (fresh, or it continues its state).
        observations: one :class:`Observations` per frame, increasing stamps.
        states: which track states to report (``"lost"`` tracks are coasting ones).
        include_coasting: also report tracks that were not observed in the frame (their prediction).

    Returns:
        One frame per input frame; points are filtered (``smoothed=False``), never interpolated.
    """
    frames = []
    for obs in observations:
        pts = [
            TrackPoint(e.track_id, e.xy, e.cov, e.det_index, vxy=e.vxy)
            for e in tracker.step(obs)
            if e.state in states and (include_coasting or e.det_index >= 0)
        ]
        frames.append(TrackFrame(obs.stamp_ns, tuple(pts)))
    return TrackResult(tuple(frames))
