"""The 360° equirectangular camera: a spherical camera, central or with two lens centres.

Conventions (see :mod:`studio.geometry.base` for the full statement):

* camera frame = ROS body convention, x forward, y left, z up; azimuth ``az = atan2(y, x)`` (left
  positive), elevation ``el = atan2(z, hypot(x, y))``, radians;
* pixel coordinates are continuous from the left/top edge, pixel ``(i, j)`` has its centre at
  ``(i + 0.5, j + 0.5)``; ``u = (0.5 - az/2π)·W`` wrapped into ``[0, W)``, ``v = (0.5 - el/π)·H``;
* ``pose`` is ``T_base_cam``: the camera frame expressed in the robot base frame, so
  ``p_base = pose.apply(p_cam)``.

The model is exact both ways (no lens model: a calibrated equirectangular image is already a sphere
sampled on a regular angle grid); all methods are vectorised.

Dual-lens parallax (``lens_offset = b``, metres): a dual-fisheye camera (e.g. a Ricoh Theta) stitches
its panorama from two back-to-back lenses whose centres are not at the same place. The model puts the
front lens centre at ``(+b, 0, 0)`` and the back one at ``(−b, 0, 0)`` in the camera frame, and the
hemisphere decides which lens sees a point: a camera-frame point ``(x, y, z)`` is seen along the
direction ``(x − sign(x)·b, y, z)`` (so a point with ``x > 0`` from the front lens), and a pixel's ray
starts at ``(sign(ray_x)·b, 0, 0)``. ``b = 0`` is the central camera, bit for bit. Points closer than
``|b|`` to the stitching plane ``x = 0`` (where the two images meet) are not modelled exactly: there
the direction's x sign may differ from the point's, and a round trip is exact only for ``|x| > |b|``.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from studio.geometry.base import angles_to_pixel, angles_to_rays, pixel_to_angles, rays_to_angles
from studio.geometry.errors import GeometryError
from studio.geometry.se import Pose3

__all__ = ["EquirectCamera", "not_equirect"]

FloatArray = NDArray[np.float64]


def not_equirect(width: int, height: int) -> str | None:
    """What is wrong with an image of this size as an equirectangular panorama (it spans 360° × 180°, so it
    is twice as wide as high), or None when nothing is: the words every reader of panoramas reports."""
    if width == 2 * height:
        return None
    return f"{width}×{height} px; an equirectangular panorama is twice as wide as high (2:1)"


def _as_uv(uv: ArrayLike) -> FloatArray:
    a = np.asarray(uv, dtype=np.float64)
    if a.shape[-1:] != (2,):
        raise ValueError(f"pixel coordinates must have shape (..., 2), got {a.shape}")
    return a


def _as_xyz(p: ArrayLike, what: str) -> FloatArray:
    a = np.asarray(p, dtype=np.float64)
    if a.shape[-1:] != (3,):
        raise ValueError(f"{what} must have shape (..., 3), got {a.shape}")
    return a


@dataclass(frozen=True, eq=False)
class EquirectCamera:
    """A spherical camera producing ``width × height`` equirectangular images.

    Cameras compare equal (and hash alike) when their sizes, pose matrices and lens offsets are equal, so
    a camera can key a cache.

    Attributes:
        width: image width W, px (normally ``2 · height``).
        height: image height H, px.
        pose: ``T_base_cam``, the camera frame in the robot base frame (metres, rotation).
        lens_offset: ``b``, metres: the two lens centres sit at ``(±b, 0, 0)`` in the camera frame
            (module docstring); 0 is a central camera.
    """

    width: int
    height: int
    pose: Pose3 = field(default_factory=Pose3.identity)
    lens_offset: float = 0.0

    def __post_init__(self) -> None:
        for name in ("width", "height"):
            val = getattr(self, name)
            if isinstance(val, bool) or not isinstance(val, int | np.integer) or int(val) <= 0:
                raise GeometryError(f"equirectangular camera {name} must be a positive integer, got {val!r}")
            object.__setattr__(self, name, int(val))
        if not isinstance(self.pose, Pose3):
            raise GeometryError(f"camera pose must be a Pose3, got {type(self.pose).__name__}")
        b = self.lens_offset
        if isinstance(b, bool) or not isinstance(b, int | float | np.integer | np.floating):
            raise GeometryError(f"camera lens offset must be a number (metres), got {b!r}")
        if not math.isfinite(float(b)):
            raise GeometryError(f"camera lens offset must be finite, got {b!r}")
        object.__setattr__(self, "lens_offset", float(b))

    def __eq__(self, other: object) -> bool:
        if not isinstance(other, EquirectCamera):
            return NotImplemented
        return (
            (self.width, self.height) == (other.width, other.height)
            and np.array_equal(self.pose.R, other.pose.R)
            and np.array_equal(self.pose.t, other.pose.t)
            and self.lens_offset == other.lens_offset
        )

    def __hash__(self) -> int:
        return hash((self.width, self.height, self.pose.R.tobytes(), self.pose.t.tobytes(), self.lens_offset))

    # ------------------------------------------------------------------ construction helpers
    @staticmethod
    def for_image(img: Any, *, pose: Pose3 | None = None, lens_offset: float = 0.0) -> EquirectCamera:
        """A camera matching an image ``(H, W, 3)`` (checked with :meth:`check_image`)."""
        shape = getattr(img, "shape", None)
        if shape is None or len(shape) < 2:
            raise GeometryError(
                f"expected an equirectangular image array (H, W, 3), got {type(img).__name__}"
            )
        cam = EquirectCamera(
            int(shape[1]), int(shape[0]), pose if pose is not None else Pose3.identity(), lens_offset
        )
        cam.check_image(img)
        return cam

    def with_pose(self, pose: Pose3) -> EquirectCamera:
        """The same camera at another pose ``T_base_cam``."""
        return dataclasses.replace(self, pose=pose)

    def check_image(self, img: Any) -> None:
        """Raise :class:`GeometryError` unless ``img`` is an ``(height, width, 3)`` array, 2:1."""
        shape = tuple(getattr(img, "shape", ()))
        if len(shape) != 3 or shape[2] != 3:
            raise GeometryError(
                "expected a colour equirectangular image of shape (H, W, 3), "
                f"got {f'shape {shape}' if shape else type(img).__name__}"
            )
        h, w = int(shape[0]), int(shape[1])
        if w != 2 * h:
            raise GeometryError(
                f"an equirectangular image must be twice as wide as high (2:1), got {w}×{h} px"
            )
        if (h, w) != (self.height, self.width):
            raise GeometryError(f"image is {w}×{h} px but the camera expects {self.width}×{self.height} px")

    # ------------------------------------------------------------------ pixels ↔ angles ↔ rays
    def angles_to_pixel(self, az: ArrayLike, el: ArrayLike) -> tuple[FloatArray, FloatArray]:
        """Azimuth/elevation (rad, any shape) → ``(u, v)`` px, u wrapped into ``[0, W)``."""
        return angles_to_pixel(az, el, self.width, self.height)

    def pixel_to_angles(self, u: ArrayLike, v: ArrayLike) -> tuple[FloatArray, FloatArray]:
        """``(u, v)`` px (any shape) → azimuth in ``[-π, π)`` and elevation (rad)."""
        return pixel_to_angles(u, v, self.width, self.height)

    def rays(self, uv: ArrayLike) -> FloatArray:
        """Unit rays in the camera frame, ``(..., 3)``, of pixels ``uv`` ``(..., 2)`` px."""
        a = _as_uv(uv)
        az, el = self.pixel_to_angles(a[..., 0], a[..., 1])
        return angles_to_rays(az, el)

    def pixel_of_rays(self, rays: ArrayLike) -> FloatArray:
        """Pixels ``(..., 2)`` px of camera-frame directions ``(..., 3)`` (any length; zero → NaN)."""
        az, el = rays_to_angles(_as_xyz(rays, "rays"))
        u, v = self.angles_to_pixel(az, el)
        return np.stack([u, v], axis=-1)

    # ------------------------------------------------------------------ base frame
    def project(self, points_base: ArrayLike) -> tuple[FloatArray, FloatArray]:
        """Project base-frame points into the panorama.

        Args:
            points_base: ``(..., 3)`` points in the base frame, metres.

        Returns:
            ``uv`` ``(..., 2)`` px and ``depth`` ``(...,)`` metres, the distance from the camera centre
            (with a lens offset: from the centre of the lens that sees the point; a point at that centre
            gives NaN pixels and depth 0).
        """
        p = _as_xyz(points_base, "points")
        p_cam = self.pose.inverse().apply(p)
        if self.lens_offset:
            p_cam = p_cam.copy()
            p_cam[..., 0] -= np.sign(p_cam[..., 0]) * self.lens_offset
        depth = np.linalg.norm(p_cam, axis=-1)
        return self.pixel_of_rays(p_cam), depth

    def bearing_base(self, uv: ArrayLike) -> FloatArray:
        """Unit rays ``(..., 3)`` in the base frame of pixels ``uv`` ``(..., 2)`` px (directions only)."""
        return self.rays(uv) @ self.pose.R.T

    def ray_origins_base(self, uv: ArrayLike) -> FloatArray:
        """Where the rays of pixels ``uv`` ``(..., 2)`` start, ``(..., 3)`` base-frame metres.

        The camera centre ``pose.t`` for a central camera; with a lens offset ``b`` the centre of the
        lens that sees the pixel, ``pose.apply((sign(ray_x)·b, 0, 0))``.
        """
        a = _as_uv(uv)
        if not self.lens_offset:
            return np.broadcast_to(self.pose.t, (*a.shape[:-1], 3)).copy()
        return self._origins(self.rays(a))

    def _origins(self, rays_cam: FloatArray) -> FloatArray:
        side = np.sign(rays_cam[..., 0]) * self.lens_offset
        return side[..., None] * self.pose.R[:, 0] + self.pose.t

    def backproject(self, uv: ArrayLike, depth: ArrayLike) -> FloatArray:
        """Base-frame points ``(..., 3)`` at ``depth`` metres along pixels ``uv`` from their ray origins.

        The origin is the camera centre, or with a lens offset the centre of the lens that sees the pixel
        (:meth:`ray_origins_base`), so ``backproject(*project(p))`` gives ``p`` back.
        """
        d = np.asarray(depth, dtype=np.float64)[..., None]
        if not self.lens_offset:
            return self.bearing_base(uv) * d + self.pose.t
        rays = self.rays(uv)
        return (rays @ self.pose.R.T) * d + self._origins(rays)

    def backproject_to_ground(self, uv: ArrayLike, *, ground_z: float = 0.0) -> FloatArray:
        """Where the rays of pixels ``uv`` ``(..., 2)`` meet the plane ``z = ground_z`` of the base frame.

        Args:
            uv: ``(..., 2)`` px.
            ground_z: height of the plane in the base frame, metres.

        Returns:
            ``(..., 3)`` base-frame points, metres; NaN for rays that never reach the plane (parallel to
            it, or pointing away from it, e.g. above the horizon for a camera above the ground).
        """
        if self.lens_offset:
            rays = self.rays(uv)
            d = rays @ self.pose.R.T
            o = self._origins(rays)
        else:
            d = self.bearing_base(uv)
            o = self.pose.t
        dz = d[..., 2]
        with np.errstate(divide="ignore", invalid="ignore"):
            s = (float(ground_z) - o[..., 2]) / dz
        ok = np.isfinite(s) & (s > 0.0) & (np.abs(dz) > 1e-12)
        pts = o + d * np.where(ok, s, np.nan)[..., None]
        pts[..., 2] = np.where(ok, float(ground_z), np.nan)
        return pts
