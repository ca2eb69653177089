"""The scenarios, after the thesis recordings: a static robot, a teleoperated robot, a robot visiting a room.

A robot *program* is a list of commands run one after the other and repeated when it ends:
``("wait", seconds)``, ``("go", x, y)`` (turn towards the point on the spot, then drive there),
``("turn", yaw)`` (turn on the spot to a heading, rad). Points are in the world frame of
:mod:`studio.sim.world`. Each program ends at its start pose, so repeating it is seamless.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from studio.sim.errors import SimError

__all__ = ["SCENARIOS", "Scenario", "get_scenario"]

Command = tuple[str, float] | tuple[str, float, float]


@dataclass(frozen=True)
class Scenario:
    """A scenario.

    Attributes:
        name: scenario name.
        seconds: default duration, s.
        start: robot start pose ``(x, y, yaw)`` in the world, metres / rad.
        program: robot commands (see the module docstring).
        people: (min, max) number of people, drawn from the seed.
        room_weights: probability that a person starts in room A, B, C.
        v_max, w_max: robot speed limits, m/s and rad/s.
    """

    name: str
    seconds: float
    start: tuple[float, float, float]
    program: tuple[Command, ...]
    people: tuple[int, int]
    room_weights: tuple[float, float, float]
    v_max: float = 0.45
    w_max: float = 0.6


SCENARIOS: dict[str, Scenario] = {
    "static": Scenario(
        name="static",
        seconds=50.0,
        start=(0.0, 0.3, 0.0),
        program=(("wait", 1e9),),
        people=(4, 6),
        room_weights=(0.75, 0.15, 0.10),
    ),
    "moving": Scenario(
        name="moving",
        seconds=96.0,
        start=(-4.2, 0.2, 0.0),
        program=(
            ("wait", 1.0),
            ("go", -1.0, 0.2),
            ("turn", np.pi / 2),
            ("wait", 2.0),
            ("go", -1.0, 1.4),
            ("turn", 0.0),
            ("go", 2.2, 1.0),
            ("wait", 3.0),
            ("turn", -np.pi / 2),
            ("go", 3.4, -0.6),
            ("turn", np.pi),
            ("wait", 4.0),
            ("go", 0.0, -0.3),
            ("turn", -3 * np.pi / 4),
            ("wait", 2.0),
            ("go", -1.6, -0.5),
            ("go", -4.2, 0.2),
            ("turn", 0.0),
            ("wait", 4.0),
        ),
        people=(5, 7),
        room_weights=(0.7, 0.15, 0.15),
    ),
    "rooms": Scenario(
        name="rooms",
        seconds=165.0,
        start=(2.6, 0.0, 0.0),
        program=(
            ("wait", 6.0),
            ("go", 4.8, 0.0),
            ("wait", 2.0),
            ("go", 7.3, 0.0),
            ("go", 8.8, 0.4),
            ("wait", 6.0),
            ("turn", np.pi / 2),
            ("wait", 4.0),
            ("go", 9.6, 1.6),
            ("turn", -np.pi / 2),
            ("wait", 8.0),
            ("go", 8.6, -0.2),
            ("turn", np.pi),
            ("wait", 5.0),
            ("go", 7.2, 0.0),
            ("go", 4.8, 0.0),
            ("wait", 4.0),
            ("turn", np.pi / 2),
            ("wait", 6.0),
            ("go", 2.6, 0.0),
            ("turn", 0.0),
            ("wait", 6.0),
        ),
        people=(6, 8),
        room_weights=(0.5, 0.35, 0.15),
        v_max=0.4,
    ),
}


def get_scenario(name: str) -> Scenario:
    """The scenario called ``name``; :class:`SimError` names the known ones otherwise."""
    try:
        return SCENARIOS[name]
    except KeyError:
        from studio.sim.calib import CALIB_SCENARIOS  # beside the people scenarios: calibration ones

        known = ", ".join([*SCENARIOS, *CALIB_SCENARIOS])
        raise SimError(f"unknown scenario '{name}' (choose from {known})") from None
