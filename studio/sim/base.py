"""Contracts of :mod:`studio.sim`: the simulated rig, the static world and the result of a run.

World frame: x, y on the floor (metres), z up, floor at z = 0. The robot's base frame follows REP-103
(x forward, y left); its odometry frame starts at the robot's first pose and drifts slowly from the world.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from studio.geometry.se import Pose3
from studio.io.base import upside_down

__all__ = ["LASER_Z", "WALL_HEIGHT", "LaserSpec", "SimResult", "SimRig", "World"]

FloatArray = NDArray[np.float64]

WALL_HEIGHT = 2.6
"""Height of walls and ceiling, metres."""

LASER_Z = 0.30
"""Height of the laser scanning plane above the floor, metres (leg height)."""


@dataclass(frozen=True)
class LaserSpec:
    """A 2D laser scanner of the rig.

    Attributes:
        topic: ROS topic of its ``sensor_msgs/LaserScan``.
        frame_id: its TF frame.
        pose: ``T_base_laser`` (z is the scanning height). Level: upright, or upside down with roll π (as
            many robots mount their scanners; it then sweeps clockwise seen from above).
        rate_hz: scan rate, Hz.
        offset_s: time of the first scan after the recording start, seconds.
        angle_min: first beam angle, rad.
        angle_increment: angle between beams, rad.
        n_beams: number of beams.
        range_min, range_max: valid range interval, metres.
        noise_sigma: Gaussian range noise, metres.
        sweep_s: time from the first beam to the last, seconds: a real scanner's beams leave one after
            another as its mirror turns (a 10 Hz scanner over 270°: 0.075 s), written as the scan's
            ``time_increment``; 0 casts every beam at the stamp.
    """

    topic: str
    frame_id: str
    pose: Pose3
    rate_hz: float = 40.0
    offset_s: float = 0.0
    angle_min: float = -0.75 * np.pi
    angle_increment: float = np.deg2rad(0.25)
    n_beams: int = 1081
    range_min: float = 0.05
    range_max: float = 10.0
    noise_sigma: float = 0.012
    sweep_s: float = 0.0

    def angles(self) -> FloatArray:
        """Beam angles (n_beams,), rad, in the laser frame."""
        return self.angle_min + self.angle_increment * np.arange(self.n_beams, dtype=np.float64)

    def base_angles(self) -> FloatArray:
        """Beam directions (n_beams,) in the base frame, rad: a scanner mounted upside down (its z axis
        down) sweeps the other way round."""
        sign = -1.0 if upside_down(self.pose) else 1.0
        return self.pose.to_pose2().yaw + sign * self.angles()


@dataclass(frozen=True)
class SimRig:
    """The simulated SUMMIT-XL-like robot: body, sensors and their rates.

    Attributes:
        base_frame, odom_frame: TF frame names.
        body_length, body_width, body_height: the robot body box, metres (centred on ``base_frame``).
        camera_topic, camera_frame: the 360° camera's ``CompressedImage`` topic and TF frame.
        camera_pose: ``T_base_camera`` (camera frame x forward, y left, z up).
        camera_rate_hz, camera_offset_s: frame rate (Hz) and time of the first image (s).
        width, height: panorama size, pixels (equirectangular, 2:1).
        jpeg_quality: JPEG quality 0–100.
        odom_topic, odom_rate_hz: odometry topic and rate.
        lasers: the scanners.
    """

    base_frame: str = "base_link"
    odom_frame: str = "odom"
    body_length: float = 0.70
    body_width: float = 0.60
    body_height: float = 0.50
    camera_topic: str = "/theta_camera/image/compressed"
    camera_frame: str = "camera_link"
    camera_pose: Pose3 = field(default_factory=lambda: Pose3.from_xyz_rpy(0.0, 0.0, 1.15))
    camera_rate_hz: float = 10.0
    camera_offset_s: float = 0.007
    width: int = 1920
    height: int = 960
    jpeg_quality: int = 85
    odom_topic: str = "/odom"
    odom_rate_hz: float = 50.0
    lasers: tuple[LaserSpec, ...] = (
        LaserSpec("/scan_front", "laser_front", Pose3.from_xyz_rpy(0.40, 0.0, LASER_Z), offset_s=0.002),
        LaserSpec(
            "/scan_rear", "laser_rear", Pose3.from_xyz_rpy(-0.40, 0.0, LASER_Z, yaw=np.pi), offset_s=0.0145
        ),
    )


@dataclass(frozen=True)
class World:
    """The static scene: vertical walls and cylinders, horizontal rectangles, rooms and doors.

    Attributes:
        seg: (S, 4) wall-like vertical segments ``x1, y1, x2, y2``, metres.
        seg_z: (S, 2) their height interval ``z0, z1``, metres.
        seg_color: (S, 3) base colour, BGR 0–255.
        seg_full: (S,) True for full-height walls (the others are lintels, table aprons, chair backs).
        circ: (C, 3) vertical cylinders ``cx, cy, r`` (pillars, table and chair legs), metres.
        circ_z: (C, 2) their height interval, metres.
        circ_color: (C, 3) colour, BGR.
        rect: (R, 5) horizontal rectangles ``xmin, xmax, ymin, ymax, z`` (table tops, seats), metres.
        rect_color: (R, 3) colour, BGR.
        rooms: name → ``(xmin, xmax, ymin, ymax)`` of each room's free floor, metres.
        doors: ``(room_a, room_b, x, y)`` door centres between two rooms.
        obstacles: (K, 3) discs ``cx, cy, r`` that walking people keep clear of (furniture, pillars).
        floor_color: name of room → floor colour, BGR.
    """

    seg: FloatArray
    seg_z: FloatArray
    seg_color: FloatArray
    seg_full: NDArray[np.bool_]
    circ: FloatArray
    circ_z: FloatArray
    circ_color: FloatArray
    rect: FloatArray
    rect_color: FloatArray
    rooms: dict[str, tuple[float, float, float, float]]
    doors: tuple[tuple[str, str, float, float], ...]
    obstacles: FloatArray
    floor_color: dict[str, tuple[float, float, float]]

    def __post_init__(self) -> None:
        s = np.asarray(self.seg, dtype=np.float64).reshape(-1, 4)
        n = s.shape[0]
        checks = {
            "seg_z": (self.seg_z, (n, 2)),
            "seg_color": (self.seg_color, (n, 3)),
        }
        for name, (arr, shape) in checks.items():
            if np.shape(arr) != shape:
                raise ValueError(f"World.{name} has shape {np.shape(arr)}, expected {shape}")
        c = np.asarray(self.circ, dtype=np.float64).reshape(-1, 3)
        if np.shape(self.circ_z) != (c.shape[0], 2) or np.shape(self.circ_color) != (c.shape[0], 3):
            raise ValueError("World.circ_z / circ_color do not match circ")
        r = np.asarray(self.rect, dtype=np.float64).reshape(-1, 5)
        if np.shape(self.rect_color) != (r.shape[0], 3):
            raise ValueError("World.rect_color does not match rect")
        if np.shape(self.seg_full) != (n,):
            raise ValueError("World.seg_full does not match seg")

    def room_of(self, x: float, y: float) -> str | None:
        """The room containing the floor point ``(x, y)``, or None."""
        for name, (x0, x1, y0, y1) in self.rooms.items():
            if x0 <= x <= x1 and y0 <= y <= y1:
                return name
        return None


@dataclass(frozen=True)
class SimResult:
    """What :func:`studio.sim.simulate` wrote, with summary numbers.

    Attributes:
        out: the output directory.
        recording, rig, ground_truth_yaml, ground_truth_jsonl: the files written.
        scenario: scenario name; seed: random seed; seconds: simulated duration, s.
        num_images, num_scans, num_odometry: messages written.
        num_people: people in the scenario; num_gt: person entries in the ground truth (all frames).
        odom_drift_m: distance between odometry and true pose at the end, metres.
        bytes: size of the recording, bytes; wall_s: time the simulation took, seconds.
    """

    out: Path
    recording: Path
    rig: Path
    ground_truth_yaml: Path
    ground_truth_jsonl: Path
    scenario: str
    seed: int
    seconds: float
    num_images: int
    num_scans: int
    num_odometry: int
    num_people: int
    num_gt: int
    odom_drift_m: float
    bytes: int
    wall_s: float
