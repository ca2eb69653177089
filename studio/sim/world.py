"""The simulated building: two rooms and a corridor, doors, tables, chairs, a shelf and a pillar.

Every scenario uses the same floor plan (world frame, metres):

* room ``A`` (the lab, 12 × 8 m): x ∈ [-6, 6], y ∈ [-4, 4];
* room ``B`` (the adjacent room, 6 × 8 m): x ∈ [6, 12], y ∈ [-4, 4], door A↔B at x = 6, |y| < 0.6;
* corridor ``C``: x ∈ [-6, 12], y ∈ [4, 6], doors to A at x ≈ -3 and to B at x ≈ 9.

Inner walls are 12 cm thick (both faces and the door jambs are modelled); doors are 2.05 m high openings
under a lintel. Table legs (5 cm) and chair legs (2.4 cm) look like legs to a laser on purpose.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from studio.sim.base import WALL_HEIGHT, World

__all__ = ["DOOR_HEIGHT", "build_world"]

DOOR_HEIGHT = 2.05
_T = 0.06  # half wall thickness, metres
_METAL = (70.0, 72.0, 75.0)
_CHROME = (150.0, 150.0, 155.0)


@dataclass
class _Builder:
    seg: list[tuple[float, float, float, float]] = field(default_factory=list)
    seg_z: list[tuple[float, float]] = field(default_factory=list)
    seg_color: list[tuple[float, float, float]] = field(default_factory=list)
    seg_full: list[bool] = field(default_factory=list)
    circ: list[tuple[float, float, float]] = field(default_factory=list)
    circ_z: list[tuple[float, float]] = field(default_factory=list)
    circ_color: list[tuple[float, float, float]] = field(default_factory=list)
    rect: list[tuple[float, float, float, float, float]] = field(default_factory=list)
    rect_color: list[tuple[float, float, float]] = field(default_factory=list)
    obstacles: list[tuple[float, float, float]] = field(default_factory=list)

    def add_seg(
        self,
        x1: float,
        y1: float,
        x2: float,
        y2: float,
        color: tuple[float, float, float],
        z0: float = 0.0,
        z1: float = WALL_HEIGHT,
    ) -> None:
        self.seg.append((x1, y1, x2, y2))
        self.seg_z.append((z0, z1))
        self.seg_color.append(color)
        self.seg_full.append(z0 <= 0.0 and z1 >= WALL_HEIGHT)

    def wall(
        self,
        x1: float,
        y1: float,
        x2: float,
        y2: float,
        color: tuple[float, float, float],
        *,
        doors: tuple[tuple[float, float], ...] = (),
        thick: bool = True,
        color2: tuple[float, float, float] | None = None,
    ) -> None:
        """An axis-aligned wall from (x1, y1) to (x2, y2) with door gaps given as intervals along it."""
        horizontal = y1 == y2
        a0, a1 = (x1, x2) if horizontal else (y1, y2)
        c = y1 if horizontal else x1
        cuts = [a0]
        for d0, d1 in sorted(doors):
            cuts += [d0, d1]
        cuts.append(a1)
        offsets = [(-_T, color), (_T, color2 or color)] if thick else [(0.0, color)]
        for off, col in offsets:
            for k in range(0, len(cuts), 2):
                s0, s1 = cuts[k], cuts[k + 1]
                self.add_seg(*_pts(horizontal, s0, s1, c + off), col)
            for d0, d1 in doors:  # lintel above each door
                self.add_seg(*_pts(horizontal, d0, d1, c + off), col, DOOR_HEIGHT, WALL_HEIGHT)
        if thick:
            for d0, d1 in doors:  # jambs across the wall thickness
                for s in (d0, d1):
                    if horizontal:
                        self.add_seg(s, c - _T, s, c + _T, (200.0, 200.0, 200.0))
                    else:
                        self.add_seg(c - _T, s, c + _T, s, (200.0, 200.0, 200.0))

    def table(
        self,
        cx: float,
        cy: float,
        lx: float,
        ly: float,
        *,
        h: float = 0.74,
        top: tuple[float, float, float] = (60.0, 105.0, 150.0),
    ) -> None:
        x0, x1, y0, y1 = cx - lx / 2, cx + lx / 2, cy - ly / 2, cy + ly / 2
        self.rect.append((x0, x1, y0, y1, h))
        self.rect_color.append(top)
        apron = tuple(0.8 * v for v in top)
        for a, b, c_, d in ((x0, y0, x1, y0), (x1, y0, x1, y1), (x1, y1, x0, y1), (x0, y1, x0, y0)):
            self.add_seg(a, b, c_, d, apron, h - 0.07, h)  # type: ignore[arg-type]
        for px in (x0 + 0.06, x1 - 0.06):
            for py in (y0 + 0.06, y1 - 0.06):
                self.circ.append((px, py, 0.025))
                self.circ_z.append((0.0, h - 0.02))
                self.circ_color.append(_METAL)
        self.obstacles.append((cx, cy, 0.5 * float(np.hypot(lx, ly)) + 0.1))

    def chair(self, cx: float, cy: float, yaw: float, color: tuple[float, float, float]) -> None:
        """A 42 cm chair facing ``yaw`` (its back on the opposite side)."""
        s = 0.21
        self.rect.append((cx - s, cx + s, cy - s, cy + s, 0.45))
        self.rect_color.append(color)
        for px in (cx - s + 0.03, cx + s - 0.03):
            for py in (cy - s + 0.03, cy + s - 0.03):
                self.circ.append((px, py, 0.012))
                self.circ_z.append((0.0, 0.45))
                self.circ_color.append(_CHROME)
        # backrest on the side opposite to the facing direction (axis-aligned chairs only)
        bx, by = -np.cos(yaw) * s, -np.sin(yaw) * s
        if abs(bx) > abs(by):
            self.add_seg(cx + bx, cy - s, cx + bx, cy + s, color, 0.47, 0.92)
        else:
            self.add_seg(cx - s, cy + by, cx + s, cy + by, color, 0.47, 0.92)
        self.obstacles.append((cx, cy, 0.35))

    def box(
        self, x0: float, x1: float, y0: float, y1: float, h: float, color: tuple[float, float, float]
    ) -> None:
        for a, b, c_, d in ((x0, y0, x1, y0), (x1, y0, x1, y1), (x1, y1, x0, y1), (x0, y1, x0, y0)):
            self.add_seg(a, b, c_, d, color, 0.0, h)
        self.rect.append((x0, x1, y0, y1, h))
        self.rect_color.append(tuple(0.9 * v for v in color))  # type: ignore[arg-type]
        self.obstacles.append(((x0 + x1) / 2, (y0 + y1) / 2, 0.5 * float(np.hypot(x1 - x0, y1 - y0)) + 0.1))


def _pts(horizontal: bool, s0: float, s1: float, c: float) -> tuple[float, float, float, float]:
    return (s0, c, s1, c) if horizontal else (c, s0, c, s1)


def build_world() -> World:
    """The floor plan shared by all scenarios (see the module docstring)."""
    b = _Builder()
    wall_a = (200.0, 214.0, 226.0)  # warm off-white (BGR)
    wall_b = (205.0, 218.0, 196.0)  # pale green
    wall_c = (190.0, 190.0, 186.0)  # corridor grey
    # outer walls (single faces seen from inside)
    b.wall(-6.0, -4.0, 6.0, -4.0, wall_a, thick=False)
    b.wall(6.0, -4.0, 12.0, -4.0, wall_b, thick=False)
    b.wall(-6.0, -4.0, -6.0, 4.0, (195.0, 205.0, 220.0), thick=False)
    b.wall(12.0, -4.0, 12.0, 4.0, wall_b, thick=False)
    b.wall(-6.0, 4.0, -6.0, 6.0, wall_c, thick=False)
    b.wall(12.0, 4.0, 12.0, 6.0, wall_c, thick=False)
    b.wall(-6.0, 6.0, 12.0, 6.0, wall_c, thick=False)
    # inner walls with doors
    b.wall(6.0, -4.0, 6.0, 4.0, wall_a, doors=((-0.6, 0.6),), color2=wall_b)
    b.wall(-6.0, 4.0, 6.0, 4.0, wall_a, doors=((-3.5, -2.5),), color2=wall_c)
    b.wall(6.0, 4.0, 12.0, 4.0, wall_b, doors=((8.5, 9.5),), color2=wall_c)
    # pillar in room A
    b.circ.append((1.8, -1.7, 0.2))
    b.circ_z.append((0.0, WALL_HEIGHT))
    b.circ_color.append((175.0, 178.0, 180.0))
    b.obstacles.append((1.8, -1.7, 0.35))
    # furniture in room A
    b.table(-3.2, -2.3, 1.6, 0.8)
    b.chair(-3.7, -1.6, -np.pi / 2, (40.0, 40.0, 45.0))
    b.chair(-2.7, -1.6, -np.pi / 2, (40.0, 40.0, 45.0))
    b.chair(-3.7, -3.0, np.pi / 2, (40.0, 40.0, 45.0))
    b.table(3.6, 2.7, 1.2, 0.7, top=(200.0, 200.0, 195.0))
    b.chair(3.3, 2.0, np.pi / 2, (140.0, 80.0, 40.0))
    b.chair(4.1, 2.0, np.pi / 2, (140.0, 80.0, 40.0))
    b.chair(-5.0, 2.8, 0.0, (40.0, 60.0, 150.0))
    b.box(0.6, 2.6, -4.0 + _T, -3.6, 1.8, (90.0, 120.0, 150.0))  # shelf against the south wall
    # furniture in room B
    b.table(9.6, -2.4, 1.4, 0.8)
    b.chair(9.2, -1.7, -np.pi / 2, (40.0, 40.0, 45.0))
    b.chair(10.0, -1.7, -np.pi / 2, (40.0, 40.0, 45.0))
    b.chair(11.2, 2.6, np.pi, (40.0, 110.0, 60.0))
    rooms = {
        "A": (-5.4, 5.4, -3.4, 3.4),
        "B": (6.6, 11.4, -3.4, 3.4),
        "C": (-5.4, 11.4, 4.5, 5.5),
    }
    doors = (("A", "B", 6.0, 0.0), ("A", "C", -3.0, 4.0), ("B", "C", 9.0, 4.0))
    return World(
        seg=np.array(b.seg, dtype=np.float64),
        seg_z=np.array(b.seg_z, dtype=np.float64),
        seg_color=np.array(b.seg_color, dtype=np.float64),
        seg_full=np.array(b.seg_full, dtype=bool),
        circ=np.array(b.circ, dtype=np.float64),
        circ_z=np.array(b.circ_z, dtype=np.float64),
        circ_color=np.array(b.circ_color, dtype=np.float64),
        rect=np.array(b.rect, dtype=np.float64),
        rect_color=np.array(b.rect_color, dtype=np.float64),
        rooms=rooms,
        doors=doors,
        obstacles=np.array(b.obstacles, dtype=np.float64),
        floor_color={"A": (150.0, 160.0, 168.0), "B": (70.0, 110.0, 150.0), "C": (135.0, 135.0, 130.0)},
    )
