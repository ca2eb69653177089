"""Synthetic robot recordings with exact ground truth (``studio simulate``).

A SUMMIT-XL-like robot with two 270° laser scanners (front and rear, at leg height), a 360° camera on a
mast and drifting wheel odometry moves through two rooms and a corridor with tables, chairs and a pillar,
among 3–8 walking, stopping and turning people. :func:`simulate` writes a ROS2 MCAP bag, ``rig.yaml`` and
the ground truth; see :mod:`studio.sim.simulate` for the output and the ground-truth rules.
"""

from __future__ import annotations

from studio.sim.base import SimResult, SimRig
from studio.sim.default import DEFAULT_RECORDING, default_recording, recordings_root
from studio.sim.errors import SimError
from studio.sim.scenarios import SCENARIOS
from studio.sim.simulate import simulate

__all__ = [
    "DEFAULT_RECORDING",
    "SCENARIOS",
    "SimError",
    "SimResult",
    "SimRig",
    "default_recording",
    "recordings_root",
    "simulate",
]
