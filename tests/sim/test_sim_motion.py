"""People's motion around the robot: the robot's body blocks them, but never traps them."""

from __future__ import annotations

import numpy as np

from studio.sim import motion as sim_motion
from studio.sim.scenarios import get_scenario
from studio.sim.world import build_world


def _planner() -> sim_motion._Planner:
    return sim_motion._Planner(build_world(), np.zeros((1, 2)), np.random.default_rng(0))


def _walk(pos, goal, robot, steps: int = 100) -> sim_motion._Person:
    pp = sim_motion._Person(np.array(pos, float), heading=0.0, cruise=1.2, waypoints=[np.array(goal, float)])
    pp.heading = float(np.arctan2(goal[1] - pos[1], goal[0] - pos[0]))
    planner = _planner()
    for k in range(steps):
        sim_motion._step_person(pp, 0, [pp], planner, np.array(robot, float), t=k * sim_motion.DT)
    return pp


def test_the_robot_blocks_a_walk_through_it():
    pp = _walk((-0.3, 1.7), (-2.5, 1.2), robot=(-1.0, 1.4, 0.0))
    assert np.hypot(*(pp.pos - [-1.0, 1.4])) >= sim_motion._ROBOT_R + 0.2


def test_someone_the_robot_drove_up_to_can_step_away():
    # the robot stopped 0.69 m from this person (inside the body clearance); walking away must work
    # (it once trapped a simulated person next to the robot for 75 s, and the robot waited for them)
    start = np.array([-0.39, 1.69])
    pp = _walk(start, (1.5, 2.2), robot=(-1.0, 1.37, 0.0))
    assert np.hypot(*(pp.pos - start)) > 1.0


def test_moving_seed_3_keeps_the_robot_moving():
    sc = get_scenario("moving")
    r_motion, _, _ = np.random.default_rng(np.random.SeedSequence(3)).spawn(3)
    m = sim_motion.simulate_motion(sc, build_world(), seconds=sc.seconds, rng=r_motion)
    moving = np.hypot(*np.diff(m.robot[:, :2], axis=0).T) > 1e-4
    assert moving.mean() > 0.4
