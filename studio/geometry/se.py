"""Rigid transforms in the plane (SE(2)) and in space (SE(3)).

Conventions (REP-103): x forward, y left, z up; yaw about +z, counter-clockwise positive, radians.
A pose ``T_a_b`` expresses frame *b* in frame *a*: ``T_a_b.apply(p_b) == p_a``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

__all__ = [
    "Pose2",
    "Pose3",
    "quat_from_rpy",
    "rot_from_quat",
    "rot_from_rpy",
    "rpy_from_rot",
    "wrap_angle",
]

FloatArray = NDArray[np.float64]


def wrap_angle(a: ArrayLike) -> FloatArray:
    """Wrap angles (rad) to [-pi, pi)."""
    return (np.asarray(a, dtype=np.float64) + np.pi) % (2.0 * np.pi) - np.pi


@dataclass(frozen=True)
class Pose2:
    """A planar pose: translation ``(x, y)`` in metres and heading ``yaw`` in radians."""

    x: float = 0.0
    y: float = 0.0
    yaw: float = 0.0

    @staticmethod
    def from_matrix(m: ArrayLike) -> Pose2:
        """From a 3×3 homogeneous matrix."""
        a = np.asarray(m, dtype=np.float64)
        return Pose2(float(a[0, 2]), float(a[1, 2]), float(np.arctan2(a[1, 0], a[0, 0])))

    def matrix(self) -> FloatArray:
        """The 3×3 homogeneous matrix."""
        c, s = np.cos(self.yaw), np.sin(self.yaw)
        return np.array([[c, -s, self.x], [s, c, self.y], [0.0, 0.0, 1.0]])

    def compose(self, other: Pose2) -> Pose2:
        """``self ∘ other`` (apply ``other`` first)."""
        c, s = np.cos(self.yaw), np.sin(self.yaw)
        return Pose2(
            self.x + c * other.x - s * other.y,
            self.y + s * other.x + c * other.y,
            float(wrap_angle(self.yaw + other.yaw)),
        )

    def inverse(self) -> Pose2:
        """The inverse transform."""
        c, s = np.cos(self.yaw), np.sin(self.yaw)
        return Pose2(-(c * self.x + s * self.y), -(-s * self.x + c * self.y), float(wrap_angle(-self.yaw)))

    def apply(self, xy: ArrayLike) -> FloatArray:
        """Transform points of shape (..., 2), metres."""
        p = np.asarray(xy, dtype=np.float64)
        c, s = np.cos(self.yaw), np.sin(self.yaw)
        out = np.empty_like(p)
        out[..., 0] = c * p[..., 0] - s * p[..., 1] + self.x
        out[..., 1] = s * p[..., 0] + c * p[..., 1] + self.y
        return out

    def as_dict(self) -> dict[str, float]:
        return {"x": float(self.x), "y": float(self.y), "yaw": float(self.yaw)}


def rot_from_rpy(roll: float, pitch: float, yaw: float) -> FloatArray:
    """Rotation matrix R = Rz(yaw) · Ry(pitch) · Rx(roll) (fixed-axis roll, pitch, yaw as in ROS)."""
    cr, sr = np.cos(roll), np.sin(roll)
    cp, sp = np.cos(pitch), np.sin(pitch)
    cy, sy = np.cos(yaw), np.sin(yaw)
    return np.array(
        [
            [cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr],
            [sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr],
            [-sp, cp * sr, cp * cr],
        ]
    )


def rpy_from_rot(R: ArrayLike) -> tuple[float, float, float]:
    """Inverse of :func:`rot_from_rpy` (pitch in [-pi/2, pi/2])."""
    m = np.asarray(R, dtype=np.float64)
    pitch = float(np.arcsin(np.clip(-m[2, 0], -1.0, 1.0)))
    roll = float(np.arctan2(m[2, 1], m[2, 2]))
    yaw = float(np.arctan2(m[1, 0], m[0, 0]))
    return roll, pitch, yaw


def quat_from_rpy(roll: float, pitch: float, yaw: float) -> tuple[float, float, float, float]:
    """Quaternion ``(x, y, z, w)`` of :func:`rot_from_rpy`."""
    cr, sr = np.cos(roll / 2), np.sin(roll / 2)
    cp, sp = np.cos(pitch / 2), np.sin(pitch / 2)
    cy, sy = np.cos(yaw / 2), np.sin(yaw / 2)
    return (
        float(sr * cp * cy - cr * sp * sy),
        float(cr * sp * cy + sr * cp * sy),
        float(cr * cp * sy - sr * sp * cy),
        float(cr * cp * cy + sr * sp * sy),
    )


def rot_from_quat(x: float, y: float, z: float, w: float) -> FloatArray:
    """Rotation matrix of a quaternion ``(x, y, z, w)`` (normalised first)."""
    q = np.array([x, y, z, w], dtype=np.float64)
    n = np.linalg.norm(q)
    if not np.isfinite(n) or n < 1e-12:
        raise ValueError("quaternion has zero or non-finite norm")
    x, y, z, w = q / n
    return np.array(
        [
            [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
            [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
            [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
        ]
    )


@dataclass(frozen=True)
class Pose3:
    """A rigid transform in space: rotation ``R`` (3×3) and translation ``t`` (3,), metres."""

    R: FloatArray
    t: FloatArray

    def __post_init__(self) -> None:
        R = np.asarray(self.R, dtype=np.float64)
        t = np.asarray(self.t, dtype=np.float64).reshape(-1)
        if R.shape != (3, 3) or t.shape != (3,):
            raise ValueError(f"Pose3 needs R (3,3) and t (3,), got {R.shape} and {t.shape}")
        object.__setattr__(self, "R", R)
        object.__setattr__(self, "t", t)

    @staticmethod
    def identity() -> Pose3:
        return Pose3(np.eye(3), np.zeros(3))

    @staticmethod
    def from_xyz_rpy(
        x: float = 0.0,
        y: float = 0.0,
        z: float = 0.0,
        roll: float = 0.0,
        pitch: float = 0.0,
        yaw: float = 0.0,
    ) -> Pose3:
        return Pose3(rot_from_rpy(roll, pitch, yaw), np.array([x, y, z], dtype=np.float64))

    @staticmethod
    def from_quat(t: ArrayLike, q_xyzw: ArrayLike) -> Pose3:
        q = np.asarray(q_xyzw, dtype=np.float64)
        return Pose3(rot_from_quat(*q), np.asarray(t, dtype=np.float64))

    @staticmethod
    def from_matrix(m: ArrayLike) -> Pose3:
        a = np.asarray(m, dtype=np.float64)
        return Pose3(a[:3, :3].copy(), a[:3, 3].copy())

    def matrix(self) -> FloatArray:
        m = np.eye(4)
        m[:3, :3] = self.R
        m[:3, 3] = self.t
        return m

    def compose(self, other: Pose3) -> Pose3:
        """``self ∘ other`` (apply ``other`` first)."""
        return Pose3(self.R @ other.R, self.R @ other.t + self.t)

    def inverse(self) -> Pose3:
        Rt = self.R.T
        return Pose3(Rt, -Rt @ self.t)

    def apply(self, pts: ArrayLike) -> FloatArray:
        """Transform points of shape (..., 3), metres."""
        p = np.asarray(pts, dtype=np.float64)
        return p @ self.R.T + self.t

    def rpy(self) -> tuple[float, float, float]:
        return rpy_from_rot(self.R)

    def quat(self) -> tuple[float, float, float, float]:
        return quat_from_rpy(*self.rpy())

    def to_pose2(self) -> Pose2:
        """Projection onto the plane: (x, y) and the heading of the x axis."""
        return Pose2(float(self.t[0]), float(self.t[1]), float(np.arctan2(self.R[1, 0], self.R[0, 0])))

    def as_dict(self) -> dict[str, float]:
        """``{x, y, z, roll, pitch, yaw}`` as in rig.yaml."""
        r, p, y = self.rpy()
        return {
            "x": float(self.t[0]),
            "y": float(self.t[1]),
            "z": float(self.t[2]),
            "roll": r,
            "pitch": p,
            "yaw": y,
        }
