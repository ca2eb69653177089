"""Contract of the 2D-laser people detectors, and the registry that picks one by name.

A detector takes ONE scan's beams in angle order as points ``(M, 2)`` in metres (invalid beams NaN and/or
masked by ``valid``) and returns people as :class:`LaserDetections` in the frame of those points.
Backends register under a short name and import lazily, so ``studio.detect.laser`` costs nothing until a
detector is asked for (a learned DR-SPAAM backend will plug in the same way and needs ``torch``).
"""

from __future__ import annotations

import importlib
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any, Protocol, runtime_checkable

import numpy as np
from numpy.typing import ArrayLike, NDArray

from studio.detect.laser.errors import LaserDetectorError

__all__ = [
    "KIND_BLOB",
    "KIND_LEG",
    "KIND_NAMES",
    "KIND_PAIR",
    "LaserDetections",
    "LaserDetector",
    "get_laser_detector",
    "laser_detector_names",
    "merge_detections",
    "register_laser_detector",
]

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]

KIND_PAIR = 0
"""A person seen as two legs 0.1–0.6 m apart; ``xy`` is their midpoint."""
KIND_LEG = 1
"""A person seen as one leg (the other hidden or missed)."""
KIND_BLOB = 2
"""A person seen as one wide segment (legs together, a skirt, a coat)."""
KIND_NAMES = {KIND_PAIR: "leg pair", KIND_LEG: "single leg", KIND_BLOB: "blob"}


@dataclass(frozen=True)
class LaserDetections:
    """People found in one scan (or in several scans merged), N of them.

    Attributes:
        xy: ``(N, 2)`` float64, positions in metres in the frame of the input points.
        scores: ``(N,)`` float64 in [0, 1], higher is more person-like.
        kind: ``(N,)`` int64, one of :data:`KIND_PAIR`, :data:`KIND_LEG`, :data:`KIND_BLOB`.
        radius: ``(N,)`` float64, rough extent of the person's points around ``xy``, metres.
        segments: optional, per detection the ``int64`` indices of the input points that make it (for a
            merge of several scans: indices into the concatenation of the scans' points, in order).
        legs: optional ``(N, 2, 2)`` float64, the two legs' positions of a :data:`KIND_PAIR` detection (NaN
            rows for the other kinds): where two people stand close, the tracker may give them one each.
    """

    xy: FloatArray
    scores: FloatArray
    kind: IntArray
    radius: FloatArray
    segments: tuple[IntArray, ...] | None = None
    legs: FloatArray | None = None

    def __post_init__(self) -> None:
        xy = np.asarray(self.xy, dtype=np.float64).reshape(-1, 2)
        n = xy.shape[0]
        scores = np.asarray(self.scores, dtype=np.float64).reshape(-1)
        kind = np.asarray(self.kind, dtype=np.int64).reshape(-1)
        radius = np.asarray(self.radius, dtype=np.float64).reshape(-1)
        for name, arr in (("scores", scores), ("kind", kind), ("radius", radius)):
            if arr.shape != (n,):
                raise ValueError(f"LaserDetections.{name} must have shape ({n},), got {arr.shape}")
        if not np.all(np.isfinite(xy)):
            raise ValueError("LaserDetections.xy must be finite")
        if n and (np.any(~np.isfinite(scores)) or scores.min() < 0.0 or scores.max() > 1.0):
            raise ValueError("LaserDetections.scores must lie in [0, 1]")
        object.__setattr__(self, "xy", xy)
        object.__setattr__(self, "scores", scores)
        object.__setattr__(self, "kind", kind)
        object.__setattr__(self, "radius", radius)
        if self.segments is not None:
            segs = tuple(np.asarray(s, dtype=np.int64).reshape(-1) for s in self.segments)
            if len(segs) != n:
                raise ValueError(f"LaserDetections.segments must have {n} entries, got {len(segs)}")
            object.__setattr__(self, "segments", segs)
        if self.legs is not None:
            legs = np.asarray(self.legs, dtype=np.float64)
            if legs.shape != (n, 2, 2):
                raise ValueError(f"LaserDetections.legs must have shape ({n}, 2, 2), got {legs.shape}")
            object.__setattr__(self, "legs", legs)

    def __len__(self) -> int:
        return int(self.xy.shape[0])

    @staticmethod
    def empty(*, with_segments: bool = False) -> LaserDetections:
        """No detections."""
        return LaserDetections(
            xy=np.zeros((0, 2)),
            scores=np.zeros(0),
            kind=np.zeros(0, dtype=np.int64),
            radius=np.zeros(0),
            segments=() if with_segments else None,
        )

    def select(self, which: ArrayLike) -> LaserDetections:
        """The detections picked by a boolean mask or an index array, in that order."""
        idx = np.asarray(which)
        if idx.dtype == bool:
            if idx.shape != (len(self),):
                raise ValueError(f"mask must have shape ({len(self)},), got {idx.shape}")
            idx = np.flatnonzero(idx)
        idx = idx.astype(np.int64).reshape(-1)
        segs = None if self.segments is None else tuple(self.segments[i] for i in idx)
        legs = None if self.legs is None else self.legs[idx]
        return LaserDetections(self.xy[idx], self.scores[idx], self.kind[idx], self.radius[idx], segs, legs)

    def then(self, other: LaserDetections) -> LaserDetections:
        """These detections followed by ``other``'s (no merging; ``segments`` index the same points, and
        are kept when both have them; a side without ``legs`` gets NaN rows)."""
        segs = None if self.segments is None or other.segments is None else self.segments + other.segments
        legs = None
        if self.legs is not None or other.legs is not None:
            nan = lambda d: np.full((len(d), 2, 2), np.nan) if d.legs is None else d.legs  # noqa: E731
            legs = np.concatenate([nan(self), nan(other)])
        return LaserDetections(
            np.concatenate([self.xy, other.xy]),
            np.concatenate([self.scores, other.scores]),
            np.concatenate([self.kind, other.kind]),
            np.concatenate([self.radius, other.radius]),
            segs,
            legs,
        )

    def above(self, threshold: float) -> LaserDetections:
        """The detections whose score is at least ``threshold``."""
        return self.select(self.scores >= threshold)

    def transformed(self, matrix: ArrayLike) -> LaserDetections:
        """The detections moved by a 3×3 homogeneous planar transform (e.g. ``Pose2.matrix()``)."""
        m = np.asarray(matrix, dtype=np.float64)
        xy = self.xy @ m[:2, :2].T + m[:2, 2]
        legs = None if self.legs is None else self.legs @ m[:2, :2].T + m[:2, 2]
        return LaserDetections(xy, self.scores, self.kind, self.radius, self.segments, legs)


def merge_detections(
    parts: Sequence[LaserDetections],
    *,
    radius: float = 0.3,
    offsets: Sequence[int] | None = None,
) -> LaserDetections:
    """Merge detections of several scans (already in one common frame) closer than ``radius``.

    Greedy by score: the best remaining detection absorbs every other one within ``radius`` metres; the
    merged position is the score-weighted mean, the score the maximum, the kind that of the best one.

    Args:
        parts: detections per scan, all in the same frame.
        radius: merge distance, metres.
        offsets: per part, the number added to its segment indices (the index of the part's first point
            in the concatenation of all scans' points). Default: no shift.

    Returns:
        The merged detections; ``segments`` (``legs``) is kept only when every part has them; a merged
        detection has the legs of its best one.
    """
    parts = list(parts)
    if not parts:
        return LaserDetections.empty()
    has_segs = all(p.segments is not None for p in parts)
    xy = np.concatenate([p.xy for p in parts])
    if xy.shape[0] == 0:
        return LaserDetections.empty(with_segments=has_segs)
    scores = np.concatenate([p.scores for p in parts])
    kind = np.concatenate([p.kind for p in parts])
    rad = np.concatenate([p.radius for p in parts])
    has_legs = all(p.legs is not None or not len(p) for p in parts)
    legs = np.concatenate([p.legs for p in parts if p.legs is not None]) if has_legs else None
    segs: list[IntArray] = []
    if has_segs:
        offs = list(offsets) if offsets is not None else [0] * len(parts)
        if len(offs) != len(parts):
            raise ValueError("merge_detections: one offset per part")
        for p, o in zip(parts, offs, strict=True):
            assert p.segments is not None
            segs.extend(s + int(o) for s in p.segments)
    order = np.argsort(-scores, kind="stable")
    taken = np.zeros(len(scores), dtype=bool)
    out_xy, out_s, out_k, out_r, out_seg, out_legs = [], [], [], [], [], []
    for i in order:
        if taken[i]:
            continue
        d = np.hypot(*(xy - xy[i]).T)
        grp = np.flatnonzero((d < radius) & ~taken)
        taken[grp] = True
        w = scores[grp] + 1e-9
        c = (xy[grp] * w[:, None]).sum(0) / w.sum()
        out_xy.append(c)
        out_s.append(scores[i])
        out_k.append(kind[i])
        out_r.append(max(float(rad[i]), float(np.max(np.hypot(*(xy[grp] - c).T) + rad[grp]))))
        if legs is not None:
            out_legs.append(legs[i])
        if has_segs:
            out_seg.append(np.unique(np.concatenate([segs[j] for j in grp])))
    return LaserDetections(
        np.array(out_xy),
        np.array(out_s),
        np.array(out_k),
        np.array(out_r),
        tuple(out_seg) if has_segs else None,
        np.array(out_legs).reshape(-1, 2, 2) if legs is not None else None,
    )


@runtime_checkable
class LaserDetector(Protocol):
    """Finds people in one 2D laser scan."""

    def detect(
        self, points: FloatArray, *, valid: NDArray[np.bool_] | None = None
    ) -> LaserDetections:  # pragma: no cover - protocol
        """People in one scan.

        Args:
            points: ``(M, 2)`` float64, the scan's beams in angle order, metres, in the sensor frame (or any
                frame, see the backend); invalid beams are NaN and/or False in ``valid``.
            valid: ``(M,)`` bool, which beams returned something; default: the finite points.

        Returns:
            People in the frame of ``points``.
        """
        ...


_REGISTRY: dict[str, tuple[str, str]] = {
    "classical": ("studio.detect.laser.classical", "ClassicalLaserDetector"),
}


def register_laser_detector(name: str, module: str, attr: str) -> None:
    """Register a backend: ``module.attr(**options)`` must build a :class:`LaserDetector`."""
    _REGISTRY[name] = (module, attr)


def laser_detector_names() -> list[str]:
    """Names of the registered laser detectors."""
    return sorted(_REGISTRY)


def get_laser_detector(name: str = "classical", **options: Any) -> LaserDetector:
    """Build a laser people detector by name (its backend is imported only now).

    Raises:
        LaserDetectorError: the name is unknown (the message lists the known ones).
    """
    if name not in _REGISTRY:
        raise LaserDetectorError(
            f"unknown laser detector '{name}' (known: {', '.join(laser_detector_names())})"
        )
    module, attr = _REGISTRY[name]
    factory: Callable[..., LaserDetector] = getattr(importlib.import_module(module), attr)
    return factory(**options)
