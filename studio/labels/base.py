"""People labels per frame: the in-memory form of ``labels.yaml`` / ``labels.jsonl`` (DESIGN.md §2).

Positions are metres in the rig's ``base_frame`` (``x``, ``y``) and, when odometry is known, in the odom
frame (``x_odom``, ``y_odom``). Time stamps are integer nanoseconds.
"""

from __future__ import annotations

import math
from collections.abc import Iterator, Mapping, Sequence
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from studio.geometry.se import Pose2

__all__ = ["SOURCES", "LabelFrame", "LabelPerson", "LabelSet", "as_box"]


def as_box(values: Any) -> tuple[float, float, float, float] | None:
    """``(u1, v1, u2, v2)`` as floats, or None when absent or not finite (e.g. a NaN row)."""
    if values is None:
        return None
    b = np.asarray(values, dtype=np.float64).reshape(-1)
    if b.shape != (4,) or not np.all(np.isfinite(b)):
        return None
    return (float(b[0]), float(b[1]), float(b[2]), float(b[3]))


SOURCES = ("fused", "laser", "image", "manual", "gt")


@dataclass(frozen=True)
class LabelPerson:
    """One person in one frame.

    Attributes:
        id: identity (track id); in ``detections.yaml`` just the index within the frame.
        x, y: position in the base frame, metres.
        x_odom, y_odom: position in the odom frame, metres (None when unknown).
        cov: 2×2 position covariance in the base frame, m² (None when unknown).
        source: how the position was obtained: fused | laser | image | manual | gt.
        box: panorama box ``(u1, v1, u2, v2)`` in pixels, ``u2`` may exceed the width across the seam.
        score: detection confidence in [0, 1].
        extra: further keys of the JSONL object, kept on round trips (e.g. ``visible``, ``occluded``).
    """

    id: int
    x: float
    y: float
    x_odom: float | None = None
    y_odom: float | None = None
    cov: tuple[tuple[float, float], tuple[float, float]] | None = None
    source: str | None = None
    box: tuple[float, float, float, float] | None = None
    score: float | None = None
    extra: Mapping[str, Any] = field(default_factory=dict)

    def __post_init__(self) -> None:
        if not isinstance(self.id, int | np.integer) or isinstance(self.id, bool):
            raise ValueError(f"person id must be an integer, got {self.id!r}")
        object.__setattr__(self, "id", int(self.id))
        for name in ("x", "y"):
            v = float(getattr(self, name))
            if not math.isfinite(v):
                raise ValueError(f"person {self.id}: {name} must be finite, got {v}")
            object.__setattr__(self, name, v)
        if self.cov is not None:
            c = np.asarray(self.cov, dtype=float)
            if c.shape != (2, 2) or not np.all(np.isfinite(c)):
                raise ValueError(f"person {self.id}: cov must be a finite 2×2 matrix")
            object.__setattr__(self, "cov", ((c[0, 0], c[0, 1]), (c[1, 0], c[1, 1])))
        if self.box is not None:
            b = tuple(float(v) for v in self.box)
            if len(b) != 4 or not all(math.isfinite(v) for v in b):
                raise ValueError(f"person {self.id}: box must be 4 finite numbers")
            object.__setattr__(self, "box", b)

    @property
    def xy(self) -> tuple[float, float]:
        return (self.x, self.y)

    def with_(self, **changes: Any) -> LabelPerson:
        """A copy with some fields changed."""
        return replace(self, **changes)


@dataclass(frozen=True)
class LabelFrame:
    """The people of one labeled frame (a panorama, or a scan on laser-only rigs)."""

    frame: int
    people: tuple[LabelPerson, ...] = ()
    stamp_ns: int | None = None
    robot_pose: Pose2 | None = None
    extra: Mapping[str, Any] = field(default_factory=dict)

    def __post_init__(self) -> None:
        object.__setattr__(self, "frame", int(self.frame))
        object.__setattr__(self, "people", tuple(self.people))
        if self.stamp_ns is not None:
            object.__setattr__(self, "stamp_ns", int(self.stamp_ns))
        ids = [p.id for p in self.people]
        if len(set(ids)) != len(ids):
            raise ValueError(f"frame {self.frame}: duplicate person ids {sorted(ids)}")

    def xy(self) -> np.ndarray:
        """Positions in the base frame, shape (N, 2), metres."""
        if not self.people:
            return np.zeros((0, 2))
        return np.array([[p.x, p.y] for p in self.people], dtype=np.float64)

    def ids(self) -> np.ndarray:
        """Identities, shape (N,)."""
        return np.array([p.id for p in self.people], dtype=np.int64)


@dataclass(frozen=True)
class LabelSet:
    """A sequence of labeled frames, sorted by frame index, plus free-form metadata."""

    frames: tuple[LabelFrame, ...]
    meta: Mapping[str, Any] = field(default_factory=dict)

    def __post_init__(self) -> None:
        frames = tuple(sorted(self.frames, key=lambda f: f.frame))
        idx = [f.frame for f in frames]
        if len(set(idx)) != len(idx):
            raise ValueError("duplicate frame indices")
        object.__setattr__(self, "frames", frames)

    def __len__(self) -> int:
        return len(self.frames)

    def __iter__(self) -> Iterator[LabelFrame]:
        return iter(self.frames)

    def by_frame(self) -> dict[int, LabelFrame]:
        return {f.frame: f for f in self.frames}

    def has_stamps(self) -> bool:
        return bool(self.frames) and all(f.stamp_ns is not None for f in self.frames)

    def track_ids(self) -> list[int]:
        return sorted({p.id for f in self.frames for p in f.people})

    @staticmethod
    def from_frames(frames: Sequence[LabelFrame], **meta: Any) -> LabelSet:
        return LabelSet(tuple(frames), dict(meta))
