"""Motion of the robot and of the people, simulated together at 50 Hz, and the drifting odometry.

The robot runs its scenario program (turn on the spot, drive, wait) under speed and acceleration limits
and stops for a person in its way. People walk from goal to goal (through doors when the goal is in
another room) with a smooth speed profile, turn, stop for a while, keep clear of furniture and wait for the
robot. They keep their distance from each other the way walkers do: each predicts the closest approach to
everyone over the next 3 s and, when it is under 1 m, sidesteps early (half of the way each, all of it past
someone standing), and slows down close behind someone. Bodies do not overlap: a step that brings two people's
centres closer than 0.4 m is blocked (stepping apart is free). Someone whose way a person blocks walks
around them instead, along their side; a step into a wall slides along it. Two people meeting in a door
passage keep to its opposite sides; someone who gets no further for 2 s in a door passage squeezes past,
and someone who cannot get past for 4 s in a room gives up that goal and chooses another. A route drawn
from inside a door passage leaves it along the door's axis. Routes keep 0.3 m clear of furniture, except
that one may start closer and lead away (stepping around someone can leave a person next to a table, who
must still be able to walk off).
Odometry integrates the true wheel velocities with a
per-run scale error, a small curvature bias and noise proportional to the speed, so it drifts only while
the robot moves.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from studio.geometry.se import wrap_angle
from studio.sim.base import World
from studio.sim.scenarios import Scenario

__all__ = ["DT", "Motion", "simulate_motion", "stride_length"]

FloatArray = NDArray[np.floating[Any]]

DT = 0.02
"""Simulation step, seconds (also the odometry period: 50 Hz)."""

_ROBOT_R = 0.46  # half-diagonal of the 0.7 × 0.6 m body
_BODY_GAP = 0.4  # m: two people's centres come no closer (shoulders ~0.45 m wide, bodies ~0.25 m deep)
_SQUEEZE_S = 2.0  # s: someone blocked by another person this long in a door passage squeezes past
_GIVE_UP_S = 4.0  # s: someone who gets no closer to their next waypoint this long in a room gives up the goal
_SLIDE_ANGLE = np.deg2rad(100.0)  # a step around someone in the way: this far from the direction to them
_COMFORT_M = 1.0  # m: walkers adapt when their predicted closest approach is under this (Olivier 2012)
_LOOK_M, _LOOK_S = 5.0, 3.0  # m, s: how far and how far ahead others are taken into account
_MAX_AVOID = 0.8  # rad: the largest heading change an avoidance asks for
_ROOMS = ("A", "B", "C")
_WALK = {  # walkable rectangles: rooms with 0.25 m margin to walls, plus door passages
    "A": (-5.75, 5.75, -3.75, 3.75),
    "B": (6.25, 11.75, -3.75, 3.75),
    "C": (-5.75, 11.75, 4.25, 5.75),
    "AB": (5.5, 6.5, -0.42, 0.42),
    "AC": (-3.22, -2.78, 3.5, 4.5),
    "BC": (8.78, 9.22, 3.5, 4.5),
}


def stride_length(v: FloatArray | float) -> FloatArray:
    """Length of a full gait cycle (two steps), metres, at walking speed ``v`` (m/s)."""
    return np.asarray(0.75 + 0.55 * np.asarray(v, dtype=np.float64))


@dataclass(frozen=True)
class Motion:
    """Sampled motion, one row per step of :data:`DT` seconds from the recording start.

    Attributes:
        t: (N,) time, s.
        robot: (N, 3) true robot pose ``x, y, yaw`` in the world, metres / rad.
        odom: (N, 3) odometry pose ``T_odom_base`` (starts at 0), metres / rad.
        people: (P, N, 5) per person ``x, y, heading, speed, gait phase`` (world, metres, rad, m/s, rad).
        standstill_s: (P,) per person the longest time they stood still on their way somewhere (people in
            the way, a wall, the robot; not a stop at a goal), seconds.
    """

    t: FloatArray
    robot: FloatArray
    odom: FloatArray
    people: FloatArray
    standstill_s: FloatArray = field(default_factory=lambda: np.zeros(0))

    def __post_init__(self) -> None:
        n = self.t.shape[0]
        if self.robot.shape != (n, 3) or self.odom.shape != (n, 3) or self.people.shape[1:] != (n, 5):
            raise ValueError("Motion arrays do not share the time axis")
        if self.standstill_s.shape not in ((0,), (self.people.shape[0],)):
            raise ValueError("Motion.standstill_s needs one value per person")

    def _interp(self, arr: FloatArray, t: float, angle_cols: tuple[int, ...]) -> FloatArray:
        f = float(np.clip(t / DT, 0.0, self.t.shape[0] - 1.000001))
        i = int(f)
        a = f - i
        lo, hi = arr[..., i, :], arr[..., i + 1, :]
        out = lo + a * (hi - lo)
        for c in angle_cols:
            out[..., c] = lo[..., c] + a * wrap_angle(hi[..., c] - lo[..., c])
        return out

    def robot_at(self, t: float) -> FloatArray:
        """True robot pose ``x, y, yaw`` at time ``t`` (s), linearly interpolated."""
        return self._interp(self.robot, t, (2,))

    def odom_at(self, t: float) -> FloatArray:
        """Odometry pose at ``t`` (s), interpolated between the published 50 Hz samples."""
        return self._interp(self.odom, t, (2,))

    def people_at(self, t: float) -> FloatArray:
        """(P, 5) people states at ``t`` (s); the gait phase is not wrapped, so it interpolates linearly."""
        return self._interp(self.people, t, (2,))


def _walkable(x: float, y: float) -> bool:
    return any(x0 <= x <= x1 and y0 <= y <= y1 for x0, x1, y0, y1 in _WALK.values())


def _passage(x: float, y: float) -> tuple[float, float, float, float] | None:
    """The walkable rectangle of the door passage holding ``(x, y)`` (not in a room), or None."""
    if _in_room(x, y):
        return None
    return next(
        (r for k, r in _WALK.items() if k not in _ROOMS and r[0] <= x <= r[1] and r[2] <= y <= r[3]), None
    )


def _in_room(x: float, y: float) -> bool:
    """Inside a room's walkable rectangle (not in a door passage between rooms)."""
    return any(_WALK[r][0] <= x <= _WALK[r][1] and _WALK[r][2] <= y <= _WALK[r][3] for r in _ROOMS)


def _seg_clear(p: FloatArray, q: FloatArray, obstacles: FloatArray, margin: float) -> bool:
    """Whether the segment ``p``–``q`` keeps ``margin`` clear of every obstacle. A segment that starts
    closer than that to an obstacle (someone who stepped around a person next to a table) may still
    leave it: heading away from it, its start is its closest point to it."""
    d = q - p
    L2 = float(d @ d) + 1e-12
    s = np.clip(((obstacles[:, :2] - p) @ d) / L2, 0.0, 1.0)
    closest = p + s[:, None] * d
    dist = np.hypot(*(obstacles[:, :2] - closest).T)
    return bool(np.all((dist > obstacles[:, 2] + margin) | (s == 0.0)))


class _Planner:
    """Draws people's goals and routes through doors."""

    def __init__(self, world: World, route: FloatArray, rng: np.random.Generator) -> None:
        self.world = world
        self.route = route  # (K, 2) points along the robot's path, kept clear of dwelling people
        self.rng = rng
        adj: dict[str, list[tuple[str, float, float]]] = {}
        for a, b, x, y in world.doors:
            adj.setdefault(a, []).append((b, x, y))
            adj.setdefault(b, []).append((a, x, y))
        self.adj = adj

    def room_near(self, p: FloatArray) -> str:
        r = self.world.room_of(float(p[0]), float(p[1]))
        if r is not None:
            return r
        centres = {n: ((x0 + x1) / 2, (y0 + y1) / 2) for n, (x0, x1, y0, y1) in self.world.rooms.items()}
        best = min(centres, key=lambda n: self._rect_dist(n, p))
        del centres
        return best

    def _rect_dist(self, name: str, p: FloatArray) -> float:
        x0, x1, y0, y1 = self.world.rooms[name]
        return float(np.hypot(max(x0 - p[0], 0.0, p[0] - x1), max(y0 - p[1], 0.0, p[1] - y1)))

    def door_points(self, a: str, b: str, x: float, y: float) -> list[FloatArray]:
        x0, x1, _, _ = self.world.rooms[a]
        ax, ay = (1.0, 0.0) if not (x0 <= x <= x1) else (0.0, 1.0)
        ca = self.world.rooms[a]
        centre_a = np.array([(ca[0] + ca[1]) / 2, (ca[2] + ca[3]) / 2])
        n = np.array([ax, ay])
        if n @ (np.array([x, y]) - centre_a) < 0:
            n = -n
        c = np.array([x, y])
        return [c - 0.8 * n, c.copy(), c + 0.8 * n]

    def door_at(self, p: FloatArray) -> tuple[str, str, float, float] | None:
        """The door whose passage holds ``p`` (a point between two rooms), or None."""
        rect = _passage(float(p[0]), float(p[1]))
        if rect is None:
            return None
        return next(
            (d for d in self.world.doors if rect in (_WALK.get(d[0] + d[1]), _WALK.get(d[1] + d[0]))), None
        )

    def route_to(self, start: FloatArray, room: str, goal: FloatArray) -> list[FloatArray] | None:
        here = self.room_near(start)
        pts: list[FloatArray] = []
        door = self.door_at(start)
        if door is not None:
            # inside a door passage: leave it along the door's axis first (a straight line from the
            # passage to a point in the room can cut the jamb: someone walked into it for the rest of the
            # recording, version 4)
            a, b, x, y = door
            side = room if room in (a, b) else (here if here in (a, b) else a)
            pts.append(self.door_points(b if side == a else a, side, x, y)[-1])
            here = side
        if room != here:
            hop = next((d for d in self.adj[here] if d[0] == room), None)
            if hop is None:
                return None
            pts += self.door_points(here, room, hop[1], hop[2])
        pts.append(goal)
        prev = start
        for q in pts:
            if not _seg_clear(prev, q, self.world.obstacles, 0.3):
                return None
            prev = q
        return pts

    def draw(
        self, start: FloatArray, others: list[FloatArray], *, dwell: bool, robot_room: str
    ) -> list[FloatArray] | None:
        """A route to a new goal, mostly in the robot's room, sometimes elsewhere (people leave, return)."""
        here = self.room_near(start)
        adjacent = [d[0] for d in self.adj[here]]
        for _ in range(40):
            u = self.rng.random()
            if here == robot_room:
                room = here if u < 0.85 else adjacent[int(self.rng.integers(len(adjacent)))]
            elif u < 0.7 and robot_room in adjacent:
                room = robot_room
            elif u < 0.9:
                room = here
            else:
                room = adjacent[int(self.rng.integers(len(adjacent)))]
            x0, x1, y0, y1 = self.world.rooms[room]
            g = np.array([self.rng.uniform(x0, x1), self.rng.uniform(y0, y1)])
            ob = self.world.obstacles
            if np.any(np.hypot(*(ob[:, :2] - g).T) < ob[:, 2] + 0.35):
                continue
            if any(float(np.hypot(*(g - o))) < 1.0 for o in others):
                continue
            if dwell and self.route.size and float(np.min(np.hypot(*(self.route - g).T))) < 1.1:
                continue
            pts = self.route_to(start, room, g)
            if pts is not None:
                return pts
        return None


@dataclass
class _Person:
    pos: FloatArray
    heading: float
    cruise: float
    v: float = 0.0
    phase: float = 0.0
    waypoints: list[FloatArray] | None = None
    dwell_left: float = 0.0
    dwell_heading: float | None = None
    waiting: float = 0.0
    ignore_robot_until: float = -1.0
    blocked_s: float = 0.0
    best_gap: float = np.inf
    stuck_s: float = 0.0
    still_s: float = 0.0
    longest_still_s: float = 0.0


def _robot_route(sc: Scenario) -> FloatArray:
    pts = [np.array(sc.start[:2])]
    for cmd in sc.program:
        if cmd[0] == "go":
            q = np.array([cmd[1], cmd[2]])  # type: ignore[misc]
            n = max(2, int(np.hypot(*(q - pts[-1])) / 0.2))
            pts += [pts[-1] + (q - pts[-1]) * k / n for k in range(1, n + 1)]
    return np.array(pts)


def simulate_motion(sc: Scenario, world: World, *, seconds: float, rng: np.random.Generator) -> Motion:
    """Simulate robot, people and odometry for ``seconds`` (+ 1 s margin) at :data:`DT`.

    Args:
        sc: the scenario (robot program, number of people).
        world: the static world.
        seconds: duration, s.
        rng: random generator (people, odometry errors).

    Returns:
        The sampled :class:`Motion`.
    """
    n = int(np.ceil((seconds + 1.0) / DT)) + 1
    r_people, r_odom = rng.spawn(2)
    route = _robot_route(sc)
    planner = _Planner(world, route, r_people)
    n_people = int(r_people.integers(sc.people[0], sc.people[1] + 1))
    people: list[_Person] = []
    names = list(world.rooms)
    for _ in range(n_people):
        for _try in range(100):
            room = names[int(r_people.choice(3, p=np.array(sc.room_weights)))]
            x0, x1, y0, y1 = world.rooms[room]
            p = np.array([r_people.uniform(x0, x1), r_people.uniform(y0, y1)])
            ob = world.obstacles
            if np.any(np.hypot(*(ob[:, :2] - p).T) < ob[:, 2] + 0.35):
                continue
            if any(float(np.hypot(*(p - q.pos))) < 1.0 for q in people):
                continue
            if float(np.min(np.hypot(*(route - p).T))) < 1.2:
                continue
            break
        person = _Person(
            pos=p, heading=float(r_people.uniform(-np.pi, np.pi)), cruise=float(r_people.uniform(0.6, 1.35))
        )
        person.dwell_left = float(r_people.uniform(0.0, 4.0))
        people.append(person)

    robot = np.zeros((n, 3))
    people_out = np.zeros((n_people, n, 5))
    x, y, yaw = sc.start
    v = w = 0.0
    cmd_i, cmd_t0 = 0, 0.0
    wheel_v = np.zeros(n)
    wheel_w = np.zeros(n)
    for k in range(n):
        t = k * DT
        robot[k] = (x, y, yaw)
        for i, pp in enumerate(people):
            people_out[i, k] = (pp.pos[0], pp.pos[1], pp.heading, pp.v, pp.phase)
        # --- robot ---
        cmd = sc.program[cmd_i % len(sc.program)]
        v_des = w_des = 0.0
        done = False
        if cmd[0] == "wait":
            done = t - cmd_t0 >= cmd[1]
        elif cmd[0] == "turn":
            err = float(wrap_angle(cmd[1] - yaw))
            w_des = float(np.clip(1.5 * err, -sc.w_max, sc.w_max))
            done = abs(err) < 0.01 and abs(w) < 0.05
        else:
            dx, dy = cmd[1] - x, cmd[2] - y  # type: ignore[misc]
            dist = float(np.hypot(dx, dy))
            err = float(wrap_angle(np.arctan2(dy, dx) - yaw)) if dist > 0.05 else 0.0
            if abs(err) > 0.2 and v < 0.05:
                w_des = float(np.clip(1.5 * err, -sc.w_max, sc.w_max))
            else:
                v_des = min(sc.v_max, 0.8 * dist) * max(0.0, float(np.cos(err)))
                w_des = float(np.clip(2.0 * err, -sc.w_max, sc.w_max))
            done = dist < 0.03
            c, s = np.cos(yaw), np.sin(yaw)
            for pp in people:
                rx, ry = c * (pp.pos[0] - x) + s * (pp.pos[1] - y), -s * (pp.pos[0] - x) + c * (pp.pos[1] - y)
                if 0.3 < rx < 1.4 and abs(ry) < 0.6:
                    v_des = 0.0
        if done:
            cmd_i += 1
            cmd_t0 = t
        v += float(np.clip(v_des - v, -0.6 * DT, 0.6 * DT))
        w += float(np.clip(w_des - w, -1.2 * DT, 1.2 * DT))
        wheel_v[k], wheel_w[k] = v, w
        yaw_mid = yaw + 0.5 * w * DT
        x += v * np.cos(yaw_mid) * DT
        y += v * np.sin(yaw_mid) * DT
        yaw = float(wrap_angle(yaw + w * DT))
        # --- people ---
        for i, pp in enumerate(people):
            _step_person(pp, i, people, planner, np.array([x, y, yaw]), t)

    odom = _integrate_odometry(wheel_v, wheel_w, r_odom)
    return Motion(
        t=np.arange(n) * DT,
        robot=robot,
        odom=odom,
        people=people_out,
        standstill_s=np.array([pp.longest_still_s for pp in people]),
    )


def _step_person(
    pp: _Person, i: int, people: list[_Person], planner: _Planner, robot: FloatArray, t: float
) -> None:
    rng = planner.rng
    v_des = 0.0
    h_des = pp.heading
    turn_rate = 2.5
    if pp.waypoints is None:
        if pp.dwell_left > 0.0:
            pp.dwell_left -= DT
            if pp.dwell_heading is not None:
                h_des, turn_rate = pp.dwell_heading, 1.5
        else:
            others = [q.waypoints[-1] if q.waypoints else q.pos for j, q in enumerate(people) if j != i]
            pts = planner.draw(pp.pos, others, dwell=True, robot_room=planner.room_near(robot[:2]))
            if pts is None:
                pp.dwell_left = 1.0
            else:
                pp.waypoints = pts
    if pp.waypoints is not None:
        target = pp.waypoints[0]
        d = target - pp.pos
        dist = float(np.hypot(*d))
        final = len(pp.waypoints) == 1
        if not final and dist < 0.3:
            pp.waypoints.pop(0)
            pp.best_gap, pp.stuck_s = np.inf, 0.0
            target = pp.waypoints[0]
            d = target - pp.pos
            dist = float(np.hypot(*d))
            final = len(pp.waypoints) == 1
        if final and dist < 0.06:
            pp.waypoints = None
            u = rng.random()
            pp.dwell_left = (
                0.0 if u < 0.3 else (rng.uniform(1.0, 6.0) if u < 0.75 else rng.uniform(8.0, 25.0))
            )
            pp.dwell_heading = float(rng.uniform(-np.pi, np.pi)) if rng.random() < 0.5 else None
        else:
            h_des = float(np.arctan2(d[1], d[0]))
            remaining = dist + sum(
                float(np.hypot(*(b - a))) for a, b in zip(pp.waypoints[:-1], pp.waypoints[1:], strict=False)
            )
            err = float(wrap_angle(h_des - pp.heading))
            v_des = pp.cruise * min(1.0, remaining / 1.0 + 0.1) * max(0.15, float(np.cos(err)))
            h_des += _avoid_heading(pp, i, people, h_des, v_des)
            # slow down close behind someone
            for j, q in enumerate(people):
                if j == i:
                    continue
                rel = q.pos - pp.pos
                if float(np.hypot(*rel)) < 0.6:
                    ang = float(wrap_angle(np.arctan2(rel[1], rel[0]) - pp.heading))
                    if abs(ang) < 0.8:
                        v_des *= 0.25
            # wait for the robot, then step aside
            rel = robot[:2] - pp.pos
            dr = float(np.hypot(*rel))
            ang = float(wrap_angle(np.arctan2(rel[1], rel[0]) - pp.heading))
            if t >= pp.ignore_robot_until and dr < 1.5 and abs(ang) < 1.2:
                v_des = 0.0
                pp.waiting += DT
                if pp.waiting > 2.5:
                    side = np.array([-np.sin(pp.heading), np.cos(pp.heading)]) * (1.0 if ang < 0 else -1.0)
                    aside = pp.pos + 1.2 * side
                    if _walkable(*aside):
                        pp.waypoints.insert(0, aside)
                        pp.best_gap, pp.stuck_s = np.inf, 0.0
                    pp.ignore_robot_until = t + 2.5
                    pp.waiting = 0.0
            else:
                pp.waiting = 0.0
    err = float(wrap_angle(h_des - pp.heading))
    pp.heading = float(wrap_angle(pp.heading + np.clip(err, -turn_rate * DT, turn_rate * DT)))
    pp.v += float(np.clip(v_des - pp.v, -0.9 * DT, 0.7 * DT))
    ob = planner.world.obstacles
    d_old_q = [float(np.hypot(*(pp.pos - q.pos))) for j, q in enumerate(people) if j != i]
    nearest = [q for j, q in enumerate(people) if j != i][int(np.argmin(d_old_q))] if d_old_q else None
    in_door = not _in_room(*pp.pos)
    if in_door and pp.stuck_s >= _SQUEEZE_S:
        # no closer to the way out for a while, whatever stops them (two people stepping around each
        # other can take turns at blocking): squeeze past
        pp.blocked_s = max(pp.blocked_s, _SQUEEZE_S)
    squeezing = in_door and pp.blocked_s >= _SQUEEZE_S

    def check(new: FloatArray) -> tuple[bool, bool]:
        """Whether a step to ``new`` is free, and whether a person blocks it."""
        d_new = float(np.hypot(*(new - robot[:2])))
        # the robot's body blocks steps towards it; someone it drove up to can still step away
        by_robot = d_new < _ROBOT_R + 0.28 and d_new < float(np.hypot(*(pp.pos - robot[:2])))
        # nor can two bodies overlap: a step towards someone closer than _BODY_GAP is blocked (steps
        # apart are free), unless the person squeezes past in a narrow door
        d_new_q = [float(np.hypot(*(new - q.pos))) for j, q in enumerate(people) if j != i]
        closing = any(a < _BODY_GAP and a < b for a, b in zip(d_new_q, d_old_q, strict=True))
        by_person = closing and not squeezing
        blocked = (
            not _walkable(*new)
            or by_robot
            or by_person
            or bool(np.any(np.hypot(*(ob[:, :2] - new).T) < ob[:, 2] - 0.05))
        )
        return not blocked, by_person

    step = pp.v * DT * np.array([np.cos(pp.heading), np.sin(pp.heading)])
    new = pp.pos + step
    free, by_person = check(new)
    if not free and not by_person and not _walkable(*new):
        # a wall in the way (steering around someone can aim at a door jamb): slide along it, the longer
        # of the step's two components first; one that runs into someone counts as blocked by them
        for slide in sorted(
            (np.array([new[0], pp.pos[1]]), np.array([pp.pos[0], new[1]])),
            key=lambda q: -float(np.hypot(*(q - pp.pos))),
        ):
            if _walkable(*slide):
                ok, by = check(slide)
                if ok:
                    new, free = slide, True
                    break
                by_person = by_person or by
    in_the_way = by_person
    if by_person and nearest is not None:
        # someone in the way: walk around them, along their side (square to the line between the two,
        # turned a little away), on the side nearer the way one was going
        q = nearest
        toward = (q.pos - pp.pos) / max(float(np.hypot(*(q.pos - pp.pos))), 1e-6)
        length = float(np.hypot(*step))
        ways = [_turn(toward, sign * _SLIDE_ANGLE) for sign in (1.0, -1.0)]
        for way in sorted(ways, key=lambda w: -float(w @ step)):
            slide = np.asarray(pp.pos + length * way, dtype=np.float64)
            ok, _ = check(slide)
            if ok:
                new, free, by_person = slide, True, False
                break
    rect = _passage(*pp.pos)
    if rect is not None and (in_the_way or squeezing) and nearest is not None:
        # two people meeting in a door passage keep to its opposite sides (across a 0.94 m door, their
        # centres pass 0.44 m apart), sidestepping at up to 0.5 m/s
        q = nearest
        lat = 0 if rect[1] - rect[0] < rect[3] - rect[2] else 1  # the passage's narrow side
        edge = rect[2 * lat] if q.pos[lat] >= pp.pos[lat] else rect[2 * lat + 1]
        side = np.array(new if free else pp.pos, dtype=np.float64)
        side[lat] += float(np.clip(edge - pp.pos[lat], -0.5 * DT, 0.5 * DT))
        if _walkable(*side) and (squeezing or check(side)[0]):
            new, free = side, True
    if squeezing:  # squeezes past until clear of everyone
        d_new_q = [float(np.hypot(*(new - q.pos))) for j, q in enumerate(people) if j != i]
        pp.blocked_s = pp.blocked_s if min(d_new_q, default=np.inf) < _BODY_GAP else 0.0
    else:
        pp.blocked_s = pp.blocked_s + DT if in_the_way else 0.0
    if not free:
        pp.v *= 0.5
    else:
        pp.phase += 2.0 * np.pi * float(np.hypot(*(new - pp.pos))) / float(stride_length(pp.v))
        pp.pos = new
    if pp.waypoints is not None:
        # no closer to the next waypoint for a while (people in the way, no gap to pass): in a room, give
        # up this goal and choose another
        gap = float(np.hypot(*(pp.waypoints[0] - pp.pos)))
        if gap < pp.best_gap - 0.05:
            pp.best_gap, pp.stuck_s = gap, 0.0
        else:
            pp.stuck_s += DT
        if pp.stuck_s >= _GIVE_UP_S and not in_door:
            pp.waypoints = None
            pp.dwell_left = float(planner.rng.uniform(1.0, 3.0))
    if pp.waypoints is None:
        pp.best_gap, pp.stuck_s = np.inf, 0.0
    pp.still_s = pp.still_s + DT if pp.waypoints is not None and pp.v < 0.05 else 0.0
    pp.longest_still_s = max(pp.longest_still_s, pp.still_s)


def _avoid_heading(pp: _Person, i: int, people: list[_Person], h_des: float, v_des: float) -> float:
    """Heading change that keeps the predicted closest approach to everyone at ``_COMFORT_M`` or more.

    Walkers predict the closest distance to each other over the next few seconds and adapt only when it
    is under about 1 m (Olivier et al. 2012, "minimal predicted distance"); each of two walkers takes half
    of the sidestep, someone passing a person who stands takes all of it. The prediction holds both
    velocities (one's own along the desired heading), so the sidestep already made counts and the
    heading returns to the way once the predicted distance is comfortable or the closest point passed.
    """
    u = np.array([np.cos(h_des), np.sin(h_des)])
    left = np.array([-u[1], u[0]])
    speed = max(v_des, 0.3)
    vp = speed * u
    lateral = 0.0
    for j, q in enumerate(people):
        if j == i:
            continue
        rel = q.pos - pp.pos
        if float(np.hypot(*rel)) > _LOOK_M:
            continue
        vrel = q.v * np.array([np.cos(q.heading), np.sin(q.heading)]) - vp
        s2 = float(vrel @ vrel)
        if s2 < 1e-9:
            continue
        tau = -float(rel @ vrel) / s2
        if not 0.0 < tau <= _LOOK_S:
            continue
        cpa = rel + tau * vrel
        mpd = float(np.hypot(*cpa))
        if mpd >= _COMFORT_M:
            continue
        away = -1.0 if float(cpa @ left) >= 0.0 else 1.0  # dead ahead: keep to the right
        share = 0.5 if q.v > 0.2 else 1.0
        lateral += away * share * (_COMFORT_M - mpd) / max(tau, 0.5)
    if lateral == 0.0:
        return 0.0
    return float(np.clip(np.arctan2(lateral, speed), -_MAX_AVOID, _MAX_AVOID))


def _turn(u: FloatArray, angle: float) -> FloatArray:
    """The unit vector ``u`` turned by ``angle`` radians."""
    c, s = np.cos(angle), np.sin(angle)
    return np.array([c * u[0] - s * u[1], s * u[0] + c * u[1]])


def _integrate_odometry(v: FloatArray, w: FloatArray, rng: np.random.Generator) -> FloatArray:
    """Odometry ``T_odom_base`` from wheel velocities with scale errors, curvature bias and noise."""
    n = v.shape[0]
    scale_v = 1.0 + rng.normal(0.0, 0.01)
    scale_w = 1.0 + rng.normal(0.0, 0.01)
    kappa = rng.normal(0.0, 0.004)  # rad per metre driven
    vm = v * scale_v + rng.normal(0.0, 0.02, n) * np.abs(v)
    wm = w * scale_w + kappa * v + rng.normal(0.0, 0.03, n) * np.abs(w)
    out = np.zeros((n, 3))
    x = y = yaw = 0.0
    for k in range(n):
        out[k] = (x, y, yaw)
        yaw_mid = yaw + 0.5 * wm[k] * DT
        x += vm[k] * np.cos(yaw_mid) * DT
        y += vm[k] * np.sin(yaw_mid) * DT
        yaw = float(wrap_angle(yaw + wm[k] * DT))
    return out
