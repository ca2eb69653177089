"""What the scanners saw empty: nobody walked where the beams went through.

A laser beam that returns from farther than a place, or that met nothing within the scanner's range, went
through that place at leg height: nobody stood there at that moment. A tracker that bridges a gap by motion
assumes the person walked on between the two tracklets; where the scanners saw that way empty for a while,
the person did not walk it (they were hidden somewhere else, and the later tracklet is someone else).

Each frame keeps a :class:`ScanView`: for each scanner its position in the tracking frame and, in bins of
bearing around it (tracking frame), the shortest range a beam measured (a return, or the far end of a beam
that met nothing within range); a bin no beam fell in is unknown. :class:`Sight` answers, over the frames
between two stamps, for how long a walk between two places crossed places the scanners saw empty
(:meth:`Sight.clear_seconds`): the walk that leaves the first place at its velocity and reaches the second at
its own (a cubic Hermite curve), so that someone who slows down to stop is looked for where they were, not
half a metre behind.

A place counts as seen empty in a frame when, from one scanner at least ``MIN_RANGE_M`` away, every bin
across ``HALF_WIDTH_M`` on either side of it (at least one bin) is known and its shortest beam reached
``MARGIN_M`` beyond it: a leg there would have stopped a beam short. Dropouts, the robot's own body and beams
past the scanner's range leave a place unseen, never empty.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

__all__ = ["ScanView", "Sight", "scan_view"]

FloatArray = NDArray[np.float64]

N_BINS = 360  # bins of bearing around each scanner (1°)
HALF_WIDTH_M = 0.25  # a place is a person's width, and what a walk at other speeds than assumed strays
MARGIN_M = 0.4  # a beam went this far past the place (a body or a leg stops it short)
MIN_RANGE_M = 0.5  # nearer than this to a scanner a place is not judged (the robot's body, mounts)
MAX_FRAME_S = 0.25  # one frame vouches for at most this long (a gap in the recording is not seen)
_FAR_M = 6.0e4  # the farthest free range stored (float16 holds up to 65504)


@dataclass(frozen=True)
class ScanView:
    """One frame's beams, compactly.

    Attributes:
        origins: (S, 2) the scanners' positions in the tracking frame, metres.
        ranges: (S, N_BINS) float16 per scanner and bin of tracking-frame bearing (bin ``k`` covers
            ``[-π + k·w, -π + (k+1)·w)``, ``w = 2π / N_BINS``) the shortest range a beam measured, metres;
            NaN where no beam fell (unknown).
    """

    origins: FloatArray
    ranges: NDArray[np.float16]

    def sees_empty(self, xy: FloatArray) -> bool:
        """Whether a scanner saw the place ``xy`` (2,) empty (see the module)."""
        w = 2.0 * np.pi / N_BINS
        for o, rng in zip(self.origins, self.ranges, strict=True):
            d = xy - o
            r = float(np.hypot(d[0], d[1]))
            if r < MIN_RANGE_M:
                continue
            theta = float(np.arctan2(d[1], d[0]))
            half = max(HALF_WIDTH_M / r, 0.5 * w)
            lo = int(np.floor((theta - half + np.pi) / w))
            hi = int(np.floor((theta + half + np.pi) / w))
            near = rng[np.arange(lo, hi + 1) % N_BINS].astype(np.float64)
            if np.isfinite(near).all() and near.min() > r + MARGIN_M:
                return True
        return False


def scan_view(scans: Iterable[tuple[FloatArray, FloatArray]]) -> ScanView | None:
    """The view of one frame from its scans in the tracking frame: per scanner ``(beams (M, 2), position
    (2,))``, the beams' ends (returns, and the far ends of beams that met nothing within range; NaN rows
    ignored). None without scanners."""
    origins, ranges = [], []
    w = 2.0 * np.pi / N_BINS
    for ends, origin in scans:
        o = np.asarray(origin, np.float64).reshape(2)
        e = np.asarray(ends, np.float64).reshape(-1, 2)
        e = e[np.isfinite(e).all(axis=1)]
        d = e - o
        best = np.full(N_BINS, np.inf)
        if len(d):
            k = np.floor((np.arctan2(d[:, 1], d[:, 0]) + np.pi) / w).astype(np.intp) % N_BINS
            np.minimum.at(best, k, np.hypot(d[:, 0], d[:, 1]))
        best[~np.isfinite(best)] = np.nan
        origins.append(o)
        # float16 holds up to 65504 m: farther is as good as that (a scanner without a range limit)
        ranges.append(np.minimum(best, _FAR_M).astype(np.float16))
    if not origins:
        return None
    return ScanView(np.array(origins), np.array(ranges))


class Sight:
    """The views of a recording's frames, by stamp (frames without a view are not seen)."""

    def __init__(self, stamps_ns: Sequence[int], views: Sequence[ScanView | None]) -> None:
        if len(stamps_ns) != len(views):
            raise ValueError("Sight: one view (or None) per stamp")
        seen = [(int(t), v) for t, v in zip(stamps_ns, views, strict=True) if v is not None]
        self._stamps = np.array([t for t, _ in seen], np.int64)
        self._views: list[ScanView] = [v for _, v in seen]

    def __bool__(self) -> bool:
        return bool(self._views)

    def clear_seconds(
        self,
        p0: FloatArray,
        t0_ns: int,
        p1: FloatArray,
        t1_ns: int,
        v0: FloatArray | None = None,
        v1: FloatArray | None = None,
    ) -> float:
        """For how long, between ``t0_ns`` and ``t1_ns`` (exclusive), a walk from ``p0`` (leaving at
        velocity ``v0``) to ``p1`` (arriving at ``v1``) was at places the scanners saw empty, seconds (each
        frame counts until the next one, at most ``MAX_FRAME_S``). Without velocities the walk is straight
        at constant speed."""
        if t1_ns <= t0_ns:
            return 0.0
        i0 = int(np.searchsorted(self._stamps, t0_ns, side="right"))
        i1 = int(np.searchsorted(self._stamps, t1_ns, side="left"))
        a, b = np.asarray(p0, np.float64)[:2], np.asarray(p1, np.float64)[:2]
        span_s = (t1_ns - t0_ns) * 1e-9
        va = (b - a) / span_s if v0 is None else np.asarray(v0, np.float64)[:2]
        vb = (b - a) / span_s if v1 is None else np.asarray(v1, np.float64)[:2]
        total = 0.0
        for i in range(i0, i1):
            t = int(self._stamps[i])
            u = (t - t0_ns) / (t1_ns - t0_ns)
            # cubic Hermite: at u = 0 in p0 at v0, at u = 1 in p1 at v1 (straight and steady when both are the
            # mean velocity)
            place = (
                (2 * u**3 - 3 * u**2 + 1) * a
                + (u**3 - 2 * u**2 + u) * span_s * va
                + (3 * u**2 - 2 * u**3) * b
                + (u**3 - u**2) * span_s * vb
            )
            if self._views[i].sees_empty(place):
                nxt = int(self._stamps[i + 1]) if i + 1 < i1 else t1_ns
                total += min((nxt - t) * 1e-9, MAX_FRAME_S)
        return total
