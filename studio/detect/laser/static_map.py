"""Static-world filter for offline labeling: what never moves over a whole recording is not a person.

All scans of a recording, in the odom frame (so the robot may move), go into an occupancy-count grid:
per cell, in how many scans it was *hit* (a return fell in it or next to it) and in how many it was seen
*free* (a beam's line crossed it on the way to a return farther away, or a beam that met nothing within
the scanner's range crossed it; the lines are drawn with OpenCV, ~1 ms per 1 081-beam scan). A cell's
occupied fraction is ``hit / (hit + free)`` over the scans that observed it. Walls and furniture score
near 1; a walking person leaves only low fractions; a person who stands still for part of the recording is
kept as long as the place was seen free in more than 30 % of the scans that observed it (default
``occupied=0.7``).

Measured on leg_tracker's bags (bench/bench_laser_detector.py): with the defaults (``occupied=0.7``,
``min_share=0.7``, ``dilate=1``) person recall on the labelled scans drops by < 1 point while clutter
detections of a static robot drop ~8×; a moving robot (``negative_2.bag``, odometry from scan matching)
keeps more clutter, because thin objects are seen free by grazing beams and odometry error spreads them.
``occupied=0.5, min_share=0.5, dilate=2`` removes 3× more of it there, but also a quarter of the people
who walk back and forth in front of a static robot — choose by recording.

Beams that met nothing (``+inf`` or beyond ``range_max``, REP 117) count as free up to ``range_max``:
without them someone who stood still in front of open space (a hall longer than the scanner's reach) was
never seen free there and looked like structure. Drivers that write a small value for "no return" (older
Hokuyo drivers, as in leg_tracker's bags) cannot be told from errors, and those beams mark nothing.

A share cannot tell structure from someone who stood at one spot for most of the time the robot looked
at it (a person waiting 60 s of a 96 s recording, seen mostly while they waited). What can is *when* the
cell was free: structure is never seen empty, a spot someone walked to was, before they came or after
they left. A cell that was seen **empty** — free, with the eight cells around it free too, within
``empty_range`` of the sensor — by ``empty_scans`` scans in a row taken from different places (each
``empty_step`` or more from the last few that counted) with no hit in between is never structure,
whatever its share. Each condition keeps structure out: a thin or round object's cells at the edge of its
silhouette are crossed by grazing beams from some viewpoints (a 0.4 m pillar's were, in runs of 20–60
scans), but the cells beside them inside the object never are; a chair leg far away that falls between
two beams is missed by whole scans, which the range limit ignores (at 4 m the beams of a 0.25–0.5°
scanner are 2–3.5 cm apart); and a table leg between two beams of a robot that stands still is missed by
every scan it takes from there. So a robot that never moves never sees a spot empty: there the share
alone decides.

What a share cannot tell either is a walker's path from furniture that a moving robot sees from many
places. Walking back and forth in front of a robot that stands still (or in front of open space that an old
driver marks nothing in), someone makes the cells of their path look half occupied; a moving robot's beams
graze a thin table leg from some places and hit it from others, and it looks half occupied too. What tells
them apart is whether the cell *changed while the scanner stood still*: per scanner, a cell hit in
``steady_scans`` (3) scans in a row over ``steady_s`` (0.2 s) or more, and seen free in as many over as long,
each run begun and made steady within ``same_view`` (0.2 m) of where the later one became steady, held
something that moved (:meth:`StaticMap.changed_at`). A thin leg that flickers between hit and missed from
one place does not make steady runs of both; a leg that looks different from two places was seen from two
places, and a robot that drives on while a run lasts has left the place (the runs are timed, so a fast
scanner on a moving robot does not count as standing still); each scanner keeps its own runs, as two
scanners on one robot look from places apart.

A detection is static when most of its *segment's* points lie on occupied cells — deciding per segment is
much more robust than per point. Built in the sensor (or base) frame instead of odom, the same map finds
returns from the robot's own body (occupied in every scan whatever the robot does).
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass
from typing import Any

import cv2
import numpy as np
from numpy.typing import ArrayLike, NDArray

from studio.detect.laser.base import LaserDetections
from studio.detect.laser.errors import LaserDetectorError

__all__ = ["StaticMap", "StaticMapBuilder"]

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]
_SHIFT = 8  # fractional bits of the line end points given to OpenCV
_VIEWS = 8  # scan origins remembered by StaticMapBuilder._new_view


class StaticMap:
    """Per-cell hit / free counts of a recording's scans in one fixed frame (usually odom).

    Attributes:
        cell: cell size, metres.
        origin: ``(2,)`` position of the corner of cell ``(0, 0)``, metres.
        hits: ``(W, H)`` int32, scans in which the cell (or a neighbour within ``dilate`` cells) was hit.
        free: ``(W, H)`` int32, scans in which a beam passed through the cell and it was not hit.
        n_scans: number of scans accumulated.
        empty: ``(W, H)`` bool, the cell was once seen empty (see the module docstring): never structure.
        changed: ``(W, H)`` bool, the cell was seen steadily hit and steadily free from one place (see
            :meth:`changed_at`).
    """

    def __init__(self, *, cell: float, origin: ArrayLike, hits: NDArray[np.int32], free: NDArray[np.int32],
                 n_scans: int, empty: NDArray[np.bool_] | None = None,
                 changed: NDArray[np.bool_] | None = None) -> None:  # fmt: skip
        if cell <= 0.0:
            raise LaserDetectorError(f"static map cell size must be positive, got {cell}")
        if hits.shape != free.shape or hits.ndim != 2 or (empty is not None and empty.shape != hits.shape):
            raise ValueError("hits, free and empty must be 2-D arrays of one shape")
        self.cell = float(cell)
        self.origin = np.asarray(origin, dtype=np.float64).reshape(2)
        self.hits = hits
        self.free = free
        self.n_scans = int(n_scans)
        self.empty = np.zeros(hits.shape, dtype=bool) if empty is None else empty
        self.changed = np.zeros(hits.shape, dtype=bool) if changed is None else changed
        if self.changed.shape != hits.shape:
            raise ValueError("changed must have the shape of hits")

    # -- building -------------------------------------------------------------------------------------
    @classmethod
    def build(
        cls,
        scans_in_odom: Iterable[
            tuple[ArrayLike, ArrayLike]
            | tuple[ArrayLike, ArrayLike, ArrayLike]
            | tuple[ArrayLike, ArrayLike, ArrayLike, int, float]
        ],
        *,
        cell: float = 0.05,
        max_free_range: float = 10.0,
        free_margin: float = 0.15,
        dilate: int = 1,
        pad: float = 5.0,
        empty_range: float = 4.0,
        empty_scans: int = 20,
        empty_step: float = 0.05,
        same_view: float = 0.2,
        steady_scans: int = 3,
        steady_s: float = 0.2,
    ) -> StaticMap:
        """Accumulate scans into a map.

        Args:
            scans_in_odom: per scan ``(points (M, 2), sensor_origin (2,))`` in the map frame, metres, in any
                order; invalid beams NaN (they mark nothing: an error says nothing about free space).
                Optionally a third element ``open_ends (K, 2)``: where the beams that met nothing within
                the scanner's ``range_max`` end (:meth:`studio.io.LaserScan.open`); the cells along them
                are free up to ``max_free_range``; and a fourth and fifth, the scanner's index and the
                scan's time in seconds (:meth:`StaticMapBuilder.add`; else scanner 0, untimed).
            cell: cell size, metres.
            max_free_range: beams mark cells free up to this distance from the sensor, metres.
            free_margin: the last ``free_margin`` metres before a return (and the cell before them) are not
                marked free (range noise).
            dilate: a hit marks the cells within this many cells around it too (absorbs jitter).
            pad: extra room added when the grid grows, metres.
            empty_range: a cell is seen empty only within this distance of the sensor, metres.
            empty_scans: a cell seen empty in this many scans in a row (no hit in between) is never
                structure (0: every cell is judged by its share alone).
            empty_step: only scans taken this far or farther from the last few that counted count, metres.
            same_view, steady_scans, steady_s: a cell that one scanner hit in ``steady_scans`` scans in a
                row over ``steady_s`` seconds or more and saw free as long, both runs begun and made steady
                within ``same_view`` metres of where the later one became steady, changed (:meth:`changed_at`;
                ``steady_scans`` 0: none does; untimed scans count by number alone).

        Returns:
            The map.
        """
        builder = StaticMapBuilder(
            cell=cell,
            max_free_range=max_free_range,
            free_margin=free_margin,
            dilate=dilate,
            pad=pad,
            empty_range=empty_range,
            empty_scans=empty_scans,
            empty_step=empty_step,
            same_view=same_view,
            steady_scans=steady_scans,
            steady_s=steady_s,
        )
        for scan in scans_in_odom:
            builder.add(*scan)
        return builder.finish()

    # -- queries --------------------------------------------------------------------------------------
    def _cells(self, points: ArrayLike) -> tuple[IntArray, IntArray]:
        """The indices of the points that are finite and on the map, and their cells ``(K, 2)``."""
        pts = np.asarray(points, dtype=np.float64).reshape(-1, 2)
        ok = np.all(np.isfinite(pts), axis=1)
        ij = np.floor((pts[ok] - self.origin) / self.cell).astype(np.int64)
        inside = (ij >= 0).all(axis=1) & (ij[:, 0] < self.hits.shape[0]) & (ij[:, 1] < self.hits.shape[1])
        return np.flatnonzero(ok)[inside], ij[inside]

    def _lookup(self, points: ArrayLike) -> tuple[NDArray[np.int32], NDArray[np.int32], NDArray[np.bool_]]:
        n = len(np.asarray(points, dtype=np.float64).reshape(-1, 2))
        h = np.zeros(n, dtype=np.int32)
        f = np.zeros(n, dtype=np.int32)
        e = np.zeros(n, dtype=bool)
        sel, ij = self._cells(points)
        h[sel] = self.hits[ij[:, 0], ij[:, 1]]
        f[sel] = self.free[ij[:, 0], ij[:, 1]]
        e[sel] = self.empty[ij[:, 0], ij[:, 1]]
        return h, f, e

    def observations(self, points: ArrayLike) -> NDArray[np.int32]:
        """``(K,)`` number of scans that observed (hit or saw free) the cell of each point."""
        h, f, _ = self._lookup(points)
        return h + f

    def static_fraction(self, points: ArrayLike, *, min_observations: int = 5) -> FloatArray:
        """``(K,)`` occupied fraction ``hit / (hit + free)`` of each point's cell, in [0, 1].

        Cells observed in fewer than ``min_observations`` scans, and NaN points, give 0 (not static).
        """
        h, f, _ = self._lookup(points)
        return _fraction(h, f, min_observations)

    def walk_share(self, points: ArrayLike, *, min_observations: int = 5) -> FloatArray:
        """``(K,)`` :meth:`static_fraction`, 0 where the cell changed while the scanner stood still
        (:meth:`changed_at`): how much a place looked like furniture, for the walk of a track."""
        out = np.zeros(len(np.asarray(points, dtype=np.float64).reshape(-1, 2)))
        sel, ij = self._cells(points)
        h, f = self.hits[ij[:, 0], ij[:, 1]], self.free[ij[:, 0], ij[:, 1]]
        out[sel] = np.where(self.changed[ij[:, 0], ij[:, 1]], 0.0, _fraction(h, f, min_observations))
        return out

    def structure(
        self, points: ArrayLike, *, occupied: float = 0.7, min_observations: int = 5
    ) -> NDArray[np.bool_]:
        """``(K,)`` whether each point lies on structure: its cell's occupied fraction is at least
        ``occupied`` (:meth:`static_fraction`) and the cell was never seen empty."""
        h, f, empty = self._lookup(points)
        return (_fraction(h, f, min_observations) >= occupied) & ~empty

    def seen_empty(self, points: ArrayLike) -> NDArray[np.bool_]:
        """``(K,)`` whether each point's cell was once seen empty (see the module docstring): nothing
        there stood still for the whole recording. NaN points and points off the map give False."""
        return self._lookup(points)[2]

    def changed_at(self, points: ArrayLike) -> NDArray[np.bool_]:
        """``(K,)`` whether each point's cell changed while the scanner stood still (see the module
        docstring): something there moved. NaN points and points off the map give False."""
        out = np.zeros(len(np.asarray(points, dtype=np.float64).reshape(-1, 2)), dtype=bool)
        sel, ij = self._cells(points)
        out[sel] = self.changed[ij[:, 0], ij[:, 1]]
        return out

    def hit_fraction(self, points: ArrayLike) -> FloatArray:
        """``(K,)`` share of all the map's scans that hit each point's cell (0 for NaN points).

        In a map of the scans in the robot's base frame, returns from the robot's own body (a mast, a wheel
        guard, another scanner) score near 1 whatever the robot does; the world passing by scores low.
        """
        h, _, _ = self._lookup(points)
        return h / max(self.n_scans, 1)

    def is_static(
        self,
        detections: LaserDetections,
        points: ArrayLike | None = None,
        *,
        xy: ArrayLike | None = None,
        occupied: float = 0.7,
        min_share: float = 0.7,
        min_observations: int = 5,
    ) -> NDArray[np.bool_]:
        """Which detections lie on static structure.

        Args:
            detections: detections whose ``segments`` index ``points``.
            points: ``(M, 2)`` the scan's points in the map frame (same order as given to the detector).
                Without it (or without segments) each detection is judged by its position ``xy`` alone.
            xy: ``(N, 2)`` detection positions in the map frame; needed only when judging by position.
            occupied: a cell is static when its occupied fraction is at least this (and it was never seen
                empty, :meth:`structure`).
            min_share: a detection is static when at least this share of its segment points is on static
                cells.
            min_observations: see :meth:`static_fraction`.

        Returns:
            ``(N,)`` bool.
        """
        n = len(detections)
        out = np.zeros(n, dtype=bool)
        if n == 0:
            return out
        if points is not None and detections.segments is not None:
            pts = np.asarray(points, dtype=np.float64).reshape(-1, 2)
            on = self.structure(pts, occupied=occupied, min_observations=min_observations)
            for i, seg in enumerate(detections.segments):
                seg = seg[np.all(np.isfinite(pts[seg]), axis=1)]
                if seg.size:
                    out[i] = np.mean(on[seg]) >= min_share
            return out
        if xy is None:
            raise LaserDetectorError("is_static needs the scan points with segments, or the positions xy")
        p = np.asarray(xy, dtype=np.float64).reshape(-1, 2)
        if p.shape[0] != n:
            raise ValueError(f"xy must have shape ({n}, 2), got {p.shape}")
        return self.structure(p, occupied=occupied, min_observations=min_observations)

    def filter(
        self,
        detections: LaserDetections,
        points: ArrayLike | None = None,
        *,
        xy: ArrayLike | None = None,
        occupied: float = 0.7,
        min_share: float = 0.7,
        min_observations: int = 5,
    ) -> LaserDetections:
        """The detections that are not static (arguments as :meth:`is_static`)."""
        static = self.is_static(
            detections,
            points,
            xy=xy,
            occupied=occupied,
            min_share=min_share,
            min_observations=min_observations,
        )
        return detections.select(~static)


def _fraction(h: NDArray[np.int32], f: NDArray[np.int32], min_observations: int) -> FloatArray:
    """``hit / (hit + free)``, 0 where fewer than ``min_observations`` scans observed the cell."""
    seen = h + f
    out = np.zeros(h.shape[0])
    ok = seen >= max(1, min_observations)
    out[ok] = h[ok] / seen[ok]
    return out


class StaticMapBuilder:
    """:meth:`StaticMap.build` one scan at a time (``studio label`` feeds it while it reads the recording).

    Arguments as :meth:`StaticMap.build`.
    """

    def __init__(
        self,
        *,
        cell: float = 0.05,
        max_free_range: float = 10.0,
        free_margin: float = 0.15,
        dilate: int = 1,
        pad: float = 5.0,
        empty_range: float = 4.0,
        empty_scans: int = 20,
        empty_step: float = 0.05,
        same_view: float = 0.2,
        steady_scans: int = 3,
        steady_s: float = 0.2,
    ) -> None:
        if not cell > 0.0:
            raise LaserDetectorError(f"static map cell size must be positive, got {cell}")
        self.cell = float(cell)
        self.max_free_range = float(max_free_range)
        self.free_margin = float(free_margin)
        self.dilate = max(int(dilate), 0)
        self.empty_range = min(float(empty_range), self.max_free_range)
        self.empty_scans = max(int(empty_scans), 0)
        self.empty_step = float(empty_step)
        self.same_view = float(same_view)
        self.steady_scans = min(max(int(steady_scans), 0), 1000)
        self.steady_s = float(steady_s)
        self._t_first: float | None = None
        self._views: list[FloatArray] = []
        n = int(np.ceil(max(self.empty_range, 0.0) / cell))
        ij = np.arange(-n, n + 1) * cell
        self._disk = (np.hypot(ij[:, None], ij[None, :]) <= self.empty_range).astype(np.uint8)
        self._grid = _Grid(cell=cell, pad=pad)
        self.n_scans = 0
        self._done = False

    def add(
        self,
        points: ArrayLike,
        origin: ArrayLike,
        open_ends: ArrayLike | None = None,
        sensor: int = 0,
        stamp_s: float | None = None,
    ) -> None:
        """One scan: ``points (M, 2)`` in the map frame (NaN = an error, marks nothing), ``origin (2,)`` and
        optionally ``open_ends (K, 2)``, the far ends of the beams that met nothing within range; ``sensor``,
        which scanner took it, and ``stamp_s``, when (seconds, any epoch), for the runs that tell a change
        (:meth:`StaticMap.changed_at`; without a time they count scans only).

        The scan's hits (dilated by ``dilate`` cells) count once each in ``hits``; every cell a beam's line
        crosses from the sensor to ``free_margin`` + one cell before its return, or to its open end (at most
        ``max_free_range`` out), and that the scan did not hit counts once in ``free``. The lines are drawn
        with OpenCV on the window of the grid the scan covers. A cell the scan saw empty (free, its eight
        neighbours too, within ``empty_range``) adds one to its run of such scans; a hit ends the run.
        """
        if self._done:
            raise RuntimeError("StaticMapBuilder.add after finish (the map shares the builder's counts)")
        grid, cell, dilate = self._grid, self.cell, self.dilate
        pts = np.asarray(points, dtype=np.float64).reshape(-1, 2)
        o = np.asarray(origin, dtype=np.float64).reshape(2)
        self.n_scans += 1
        pts = pts[np.all(np.isfinite(pts), axis=1)]
        ends = np.zeros((0, 2)) if open_ends is None else np.asarray(open_ends, dtype=np.float64)
        ends = ends.reshape(-1, 2)
        ends = ends[np.all(np.isfinite(ends), axis=1)]
        if self.max_free_range <= 0.0:
            ends = ends[:0]
        elif len(ends):  # an open beam is free as far as the map marks anything free
            de = ends - o
            re = np.maximum(np.hypot(de[:, 0], de[:, 1]), 1e-9)
            ends = o + de * (np.minimum(re, self.max_free_range) / re)[:, None]
        if not len(pts) and not len(ends):
            return
        hit = grid.cells(pts)
        o_cell = grid.cells(o[None])[0]
        # the returns, their dilation and every beam line lie in this box of cells
        box = np.concatenate([hit, grid.cells(ends), o_cell[None]])
        lo = box.min(0) - dilate
        hi = box.max(0) + dilate
        grid.ensure(np.stack([lo, hi]))
        shape = (int(hi[0] - lo[0] + 1), int(hi[1] - lo[1] + 1))
        hits = np.zeros(shape, np.uint8)
        hits[hit[:, 0] - lo[0], hit[:, 1] - lo[1]] = 1
        hit_mask = hits
        if dilate:
            hit_mask = np.asarray(cv2.dilate(hits, np.ones((2 * dilate + 1,) * 2, np.uint8)), np.uint8)
        d = np.concatenate([pts - o, ends - o])
        r = np.maximum(np.hypot(d[:, 0], d[:, 1]), 1e-9)
        reach = np.minimum(r - self.free_margin - cell, self.max_free_range)
        reach[len(pts) :] = r[len(pts) :]  # open beams: no return to keep a margin from
        beams = reach > 0.0
        free_mask = np.zeros(shape, np.uint8)
        if beams.any():
            end = o + d[beams] * (reach[beams] / r[beams])[:, None]
            # window pixel (i, j) is cell lo + (i, j), its centre at integer coordinates; OpenCV wants
            # (column, row) in fixed point
            px = np.empty((int(beams.sum()), 2, 2))
            px[:, 0] = (o / cell - lo - 0.5)[::-1]
            px[:, 1] = (end / cell - lo - 0.5)[:, ::-1]
            lines = np.round(px * (1 << _SHIFT)).astype(np.int32)
            cv2.polylines(free_mask, list(lines), False, 1, lineType=cv2.LINE_8, shift=_SHIFT)
        win = grid.window(lo, hi)
        grid.hits[win] += hit_mask
        free_now = free_mask & (hit_mask ^ 1)
        grid.free[win] += free_now
        if self.same_view > 0.0 and self.steady_scans > 0:
            self._changed(win, hit_mask, free_now, o, int(sensor), stamp_s)
        if self.empty_scans and self.empty_range > 0.0:
            run = grid.run[win]  # views: updated in place
            run[hit_mask == 1] = 0
            if not self._new_view(o):
                return
            # the free cells within empty_range of the sensor (a disk around its cell) whose neighbours
            # are free too
            c, n = o_cell - lo, self._disk.shape[0] // 2
            a, b = np.maximum(c - n, 0), np.minimum(c + n + 1, shape)
            disk = self._disk[a[0] - c[0] + n : b[0] - c[0] + n, a[1] - c[1] + n : b[1] - c[1] + n]
            near = free_mask[a[0] : b[0], a[1] : b[1]] & (hit_mask[a[0] : b[0], a[1] : b[1]] ^ 1) & disk
            seen_empty = np.asarray(cv2.erode(near, np.ones((3, 3), np.uint8)), np.uint8)
            run[a[0] : b[0], a[1] : b[1]] += seen_empty
            grid.empty[win] |= run >= self.empty_scans

    def _changed(
        self,
        win: tuple[slice, slice],
        hit: NDArray[Any],
        free: NDArray[Any],
        o: FloatArray,
        sensor: int,
        stamp_s: float | None,
    ) -> None:
        """Count this scan into the scanner's run of hits or of free looks at each cell; a run that has
        lasted ``steady_scans`` scans and ``steady_s`` becomes steady, and marks the cell changed when the
        scanner's last steady run of the other kind there and this one both began within ``same_view`` of
        here (it stood still meanwhile)."""
        g, n = self._grid, self.steady_scans
        if stamp_s is not None and self._t_first is None:
            self._t_first = float(stamp_s)
        t = np.float32(0.0 if stamp_s is None or self._t_first is None else stamp_s - self._t_first)
        v = g.view(sensor)
        width = g.hits.shape[1]
        runs, began_t, began_at = v.run.reshape(-1), v.began_t.reshape(-1), v.began_at.reshape(-1, 2)
        here = o.astype(np.float32)
        # per cell the current run (its count, n + 1 once steady; when and where it began) and, per kind,
        # where the last steady run of that kind began (NaN: none yet)
        for mask, sign, last_other, last_mine in (
            (hit, 1, v.free_began_at, v.hit_began_at),
            (free, -1, v.hit_began_at, v.free_began_at),
        ):
            i, j = np.divmod(np.flatnonzero(mask), mask.shape[1])
            cells = (i + win[0].start) * width + (j + win[1].start)  # flat indices into the grid
            r = runs[cells] * sign  # this kind's run so far (<= 0: none, or the other kind's)
            new = r <= 0
            began_t[cells[new]] = t
            began_at[cells[new]] = here
            r = np.where(new, 1, np.where(r > n, r, np.minimum(r + 1, n)))
            no_clock = stamp_s is None or self.steady_s <= 0.0  # untimed scans count by number alone
            ready = (r == n) & (no_clock or (t - began_t[cells] >= self.steady_s))
            r[ready] = n + 1
            runs[cells] = r * sign
            steady = cells[ready]
            if not len(steady):
                continue
            start = began_at[steady]
            other = last_other.reshape(-1, 2)[steady]  # NaN: no steady run of the other kind yet
            near = np.maximum(np.hypot(*(other - here).T), np.hypot(*(start - here).T)) < self.same_view
            g.changed.reshape(-1)[steady[near]] = True
            last_mine.reshape(-1, 2)[steady] = start

    def _new_view(self, origin: FloatArray) -> bool:
        """Whether a scan from ``origin`` counts towards the runs of empty scans: it lies ``empty_step`` or
        more from the origins of the last few scans that counted (several scanners take turns)."""
        views = self._views
        if views and min(float(np.hypot(*(origin - v))) for v in views) < self.empty_step:
            return False
        views.append(origin)
        del views[:-_VIEWS]
        return True

    def finish(self) -> StaticMap:
        """The map of the scans added so far (it takes over the counts: add no scans after this)."""
        self._done = True
        g = self._grid
        return StaticMap(
            cell=self.cell,
            origin=g.origin(),
            hits=g.hits,
            free=g.free,
            n_scans=self.n_scans,
            empty=g.empty,
            changed=g.changed,
        )


@dataclass
class _Runs:
    """One scanner's runs per cell (:meth:`StaticMapBuilder._changed`): the current run (> 0 hits, < 0 free
    looks, ± (steady_scans + 1) once steady), when and where it began, and where the last steady run of
    hits and of free looks began."""

    run: NDArray[np.int16]
    began_t: NDArray[np.float32]
    began_at: NDArray[np.float32]
    hit_began_at: NDArray[np.float32]
    free_began_at: NDArray[np.float32]


class _Grid:
    """A dense count grid that grows to hold any cell index."""

    def __init__(self, *, cell: float, pad: float) -> None:
        self.cell = cell
        self.pad = max(1, int(np.ceil(pad / cell)))
        self.lo = np.zeros(2, dtype=np.int64)  # cell index of array element (0, 0)
        self.hits = np.zeros((0, 0), dtype=np.int32)
        self.free = np.zeros((0, 0), dtype=np.int32)
        self.run = np.zeros((0, 0), dtype=np.int32)  # scans in a row that saw the cell empty, until a hit
        self.empty = np.zeros((0, 0), dtype=bool)  # the run reached StaticMapBuilder.empty_scans once
        self.changed = np.zeros((0, 0), dtype=bool)  # changed while a scanner stood still
        self.views: list[_Runs] = []  # per scanner: its runs of hits and of free looks

    def cells(self, pts: FloatArray) -> IntArray:
        return np.floor(np.asarray(pts).reshape(-1, 2) / self.cell).astype(np.int64)

    def origin(self) -> FloatArray:
        return self.lo.astype(np.float64) * self.cell

    def ensure(self, ij: IntArray) -> None:
        if ij.shape[0] == 0:
            return
        mn, mx = ij.min(0), ij.max(0)
        shape = np.array(self.hits.shape, dtype=np.int64)
        if self.hits.size and np.all(mn >= self.lo) and np.all(mx < self.lo + shape):
            return
        if self.hits.size:
            new_lo = np.minimum(self.lo, mn - self.pad)
            new_hi = np.maximum(self.lo + shape, mx + 1 + self.pad)
        else:
            new_lo, new_hi = mn - self.pad, mx + 1 + self.pad
        size = new_hi - new_lo
        if size.prod() > 400_000_000:
            raise LaserDetectorError(
                "static map would exceed 400 M cells: points far away or a huge cell count"
            )
        a = self.lo - new_lo

        def grown(old: NDArray[Any]) -> NDArray[Any]:
            fill = np.nan if old.dtype == np.float32 else 0  # NaN: never seen from anywhere
            new = np.full(tuple(size) + old.shape[2:], fill, dtype=old.dtype)
            if old.size:
                new[a[0] : a[0] + shape[0], a[1] : a[1] + shape[1]] = old
            return new

        self.hits, self.free, self.run = grown(self.hits), grown(self.free), grown(self.run)
        self.empty, self.changed = grown(self.empty), grown(self.changed)
        for v in self.views:
            for name in _Runs.__dataclass_fields__:
                setattr(v, name, grown(getattr(v, name)))
        self.lo = new_lo

    def view(self, sensor: int) -> _Runs:
        """The runs of scanner ``sensor`` (made on first use)."""
        while len(self.views) <= sensor:
            shape = self.hits.shape
            self.views.append(
                _Runs(
                    np.zeros(shape, np.int16),
                    np.full(shape, np.nan, np.float32),
                    np.full((*shape, 2), np.nan, np.float32),
                    np.full((*shape, 2), np.nan, np.float32),
                    np.full((*shape, 2), np.nan, np.float32),
                )
            )
        return self.views[sensor]

    def window(self, lo: IntArray, hi: IntArray) -> tuple[slice, slice]:
        """The array slices of cells ``lo`` … ``hi`` (inclusive; :meth:`ensure` them first)."""
        a, b = lo - self.lo, hi - self.lo + 1
        return slice(int(a[0]), int(b[0])), slice(int(a[1]), int(b[1]))
