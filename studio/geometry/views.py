"""Perspective (pinhole) views of the panorama: cube faces, horizon views, exact pixel and box mapping.

A :class:`PerspectiveView` is a virtual pinhole camera at the panorama centre looking at azimuth ``yaw``
and elevation ``pitch`` (radians, in the camera frame of :mod:`studio.geometry.equirect`: x forward, y left,
z up; yaw left positive, pitch up positive), without roll. Its optical frame is the usual one: z forward
(the viewing direction), x right, y down. Intrinsics: square pixels, focal length
``f = (width / 2) / tan(fov / 2)`` px for the horizontal field of view ``fov``, principal point at the
view centre ``(width / 2, height / 2)``.

View pixel coordinates use the same continuous convention as the panorama: pixel ``(i, j)`` covers
``[i, i+1) × [j, j+1)``, its centre is ``(i + 0.5, j + 0.5)`` (so ``K`` below differs from OpenCV's
integer-centre convention by half a pixel: OpenCV's ``c = width/2 - 0.5``).

Cube faces (:func:`cube_faces`) are 90° views of ``size × size`` px, ``f = size / 2`` (the thesis's
cube-face pinhole model): front (yaw 0), left (+π/2), back (π), right (-π/2), up (pitch +π/2, image top
towards the back), down (pitch -π/2, image top towards the front).

Rendering lives in :mod:`studio.geometry.render` (:class:`ViewRenderer`, re-exported here).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from studio.geometry.base import TWO_PI, angles_to_pixel, pixel_to_angles, rays_to_angles, wrap_u
from studio.geometry.errors import GeometryError
from studio.geometry.render import ViewRenderer

__all__ = ["PerspectiveView", "ViewRenderer", "cube_faces", "horizon_views"]

FloatArray = NDArray[np.float64]


def _as_uv(uv: ArrayLike) -> FloatArray:
    a = np.asarray(uv, dtype=np.float64)
    if a.ndim == 1:
        a = a[None, :]
    if a.shape[-1:] != (2,):
        raise ValueError(f"pixel coordinates must have shape (N, 2), got {np.shape(uv)}")
    return a


@dataclass(frozen=True)
class PerspectiveView:
    """A pinhole view of the panorama (hashable: it keys the renderer's look-up tables).

    Attributes:
        yaw: azimuth of the optical axis, rad (left positive).
        pitch: elevation of the optical axis, rad, in [-π/2, π/2] (up positive).
        fov: horizontal field of view, rad, in (0, π).
        width: view width, px.
        height: view height, px.
        name: free label (e.g. ``"front"``); part of the identity of the view.
    """

    yaw: float
    pitch: float
    fov: float
    width: int
    height: int
    name: str = ""

    def __post_init__(self) -> None:
        for key in ("yaw", "pitch", "fov"):
            val = getattr(self, key)
            try:
                fval = float(val)
            except (TypeError, ValueError):
                raise GeometryError(f"perspective view {key} must be a number (rad), got {val!r}") from None
            if not math.isfinite(fval):
                raise GeometryError(f"perspective view {key} must be finite, got {val!r}")
            object.__setattr__(self, key, fval)
        for key in ("width", "height"):
            val = getattr(self, key)
            if isinstance(val, bool) or not isinstance(val, int | np.integer) or int(val) <= 0:
                raise GeometryError(f"perspective view {key} must be a positive integer (px), got {val!r}")
            object.__setattr__(self, key, int(val))
        if not 0.0 < self.fov < math.pi:
            raise GeometryError(
                f"perspective view fov must be in (0, 180)°, got {math.degrees(self.fov):.3f}°"
            )
        if abs(self.pitch) > math.pi / 2 + 1e-12:
            raise GeometryError(
                f"perspective view pitch must be in [-90, 90]°, got {math.degrees(self.pitch):.3f}°"
            )

    # ------------------------------------------------------------------ model
    @property
    def focal(self) -> float:
        """Focal length f, px (square pixels)."""
        return (self.width / 2.0) / math.tan(self.fov / 2.0)

    @property
    def vfov(self) -> float:
        """Vertical field of view, rad."""
        return 2.0 * math.atan((self.height / 2.0) / self.focal)

    def K(self) -> FloatArray:  # noqa: N802  (the usual name of the intrinsic matrix)
        """Intrinsic matrix (3, 3) in the continuous pixel convention (principal point ``(W/2, H/2)``)."""
        f = self.focal
        return np.array([[f, 0.0, self.width / 2.0], [0.0, f, self.height / 2.0], [0.0, 0.0, 1.0]])

    def R_cam_view(self) -> FloatArray:  # noqa: N802  (R_a_b: rotation of frame b in frame a)
        """Rotation (3, 3) of the view's optical frame (x right, y down, z forward) in the camera frame.

        Columns are the optical axes expressed in the camera frame: ``ray_cam = R_cam_view() @ ray_opt``.
        """
        cy, sy = math.cos(self.yaw), math.sin(self.yaw)
        cp, sp = math.cos(self.pitch), math.sin(self.pitch)
        forward = (cp * cy, cp * sy, sp)
        right = (sy, -cy, 0.0)
        down = (sp * cy, sp * sy, -cp)
        return np.array([right, down, forward]).T

    # ------------------------------------------------------------------ view pixels ↔ rays
    def rays(self, uv_view: ArrayLike) -> FloatArray:
        """Unit rays ``(N, 3)`` in the camera frame of view pixels ``(N, 2)`` px."""
        uv = _as_uv(uv_view)
        f = self.focal
        opt = np.empty((*uv.shape[:-1], 3))
        opt[..., 0] = (uv[..., 0] - self.width / 2.0) / f
        opt[..., 1] = (uv[..., 1] - self.height / 2.0) / f
        opt[..., 2] = 1.0
        opt /= np.linalg.norm(opt, axis=-1, keepdims=True)
        return opt @ self.R_cam_view().T

    def pixel_of_rays(self, rays_cam: ArrayLike) -> FloatArray:
        """View pixels ``(N, 2)`` of camera-frame directions ``(N, 3)``; NaN for rays not in front of it."""
        r = np.asarray(rays_cam, dtype=np.float64)
        if r.ndim == 1:
            r = r[None, :]
        if r.shape[-1:] != (3,):
            raise ValueError(f"rays must have shape (N, 3), got {r.shape}")
        opt = r @ self.R_cam_view()
        z = opt[..., 2]
        front = z > 1e-12 * np.linalg.norm(opt, axis=-1)
        zs = np.where(front, z, np.nan)
        f = self.focal
        return np.stack(
            [f * opt[..., 0] / zs + self.width / 2.0, f * opt[..., 1] / zs + self.height / 2.0], axis=-1
        )

    # ------------------------------------------------------------------ view ↔ panorama
    def view_to_pano(self, uv_view: ArrayLike, pano_w: int, pano_h: int) -> FloatArray:
        """Panorama pixels ``(N, 2)`` (u wrapped into [0, W)) of view pixels ``(N, 2)``."""
        az, el = rays_to_angles(self.rays(uv_view))
        u, v = angles_to_pixel(az, el, pano_w, pano_h)
        return np.stack([u, v], axis=-1)

    def pano_to_view(self, uv_pano: ArrayLike, pano_w: int, pano_h: int) -> FloatArray:
        """View pixels ``(N, 2)`` of panorama pixels ``(N, 2)``; NaN where the ray is behind the view."""
        uv = _as_uv(uv_pano)
        az, el = pixel_to_angles(uv[..., 0], uv[..., 1], pano_w, pano_h)
        ce = np.cos(el)
        rays = np.stack([ce * np.cos(az), ce * np.sin(az), np.sin(el)], axis=-1)
        return self.pixel_of_rays(rays)

    def box_to_pano(self, box: ArrayLike, pano_w: int, pano_h: int) -> FloatArray:
        """Exact panorama bounds ``(N, 4)`` of view boxes ``(4,)`` or ``(N, 4)`` ``[u1, v1, u2, v2]`` px.

        The box outline is four straight segments in the view, i.e. four great-circle arcs on the sphere.
        Azimuth is monotonic along such an arc (unless it passes through a pole), so the azimuth range of
        the outline is reached at the corners, unwrapped around the loop; elevation can peak inside an
        edge, at the point of the arc's great circle nearest to a pole, which is added when it lies on the
        arc. The result equals the limit of sampling the outline infinitely densely. A box whose outline
        crosses the seam comes out as one box with ``u1`` in ``[0, W)`` and ``u2 > W``; a box containing a
        pole (inside or on its outline) spans the full width ``[0, W]`` and reaches row 0 (north) or H
        (south).
        """
        b = np.asarray(box, dtype=np.float64)
        if b.ndim == 1:
            b = b[None, :]
        if b.ndim != 2 or b.shape[1] != 4:
            raise ValueError(f"boxes must have shape (4,) or (N, 4), got {np.shape(box)}")
        n = b.shape[0]
        lo_u, hi_u = np.minimum(b[:, 0], b[:, 2]), np.maximum(b[:, 0], b[:, 2])
        lo_v, hi_v = np.minimum(b[:, 1], b[:, 3]), np.maximum(b[:, 1], b[:, 3])
        corners = np.stack(
            [
                np.stack([lo_u, lo_v], -1),
                np.stack([hi_u, lo_v], -1),
                np.stack([hi_u, hi_v], -1),
                np.stack([lo_u, hi_v], -1),
            ],
            axis=1,
        )  # (N, 4, 2) going round the outline
        c = self.rays(corners.reshape(-1, 2)).reshape(n, 4, 3)
        az_c, el_c = rays_to_angles(c)

        # Azimuth: unwrap around the closed loop (each edge turns by less than π).
        d_az = np.diff(az_c, axis=1, append=az_c[:, :1])
        d_az = (d_az + np.pi) % TWO_PI - np.pi
        az_un = az_c[:, :1] + np.concatenate([np.zeros((n, 1)), np.cumsum(d_az[:, :3], axis=1)], axis=1)
        az_max, az_min = az_un.max(axis=1), az_un.min(axis=1)

        # Elevation: corners, plus each edge's extreme point when it falls inside the edge.
        el_max, el_min = el_c.max(axis=1), el_c.min(axis=1)
        a, bb = c, np.roll(c, -1, axis=1)
        nrm = np.cross(a, bb)
        nn = np.linalg.norm(nrm, axis=-1, keepdims=True)
        ok_n = nn[..., 0] > 1e-15
        nh = nrm / np.where(nn > 0.0, nn, 1.0)
        p = np.array([0.0, 0.0, 1.0]) - nh[..., 2:3] * nh  # ẑ projected onto the great circle's plane
        pn = np.linalg.norm(p, axis=-1, keepdims=True)
        ok_p = ok_n & (pn[..., 0] > 1e-12)
        p = p / np.where(pn > 0.0, pn, 1.0)
        for sgn in (1.0, -1.0):
            q = sgn * p
            inside = (
                ok_p
                & (np.einsum("...i,...i->...", np.cross(a, q), nrm) >= 0.0)
                & (np.einsum("...i,...i->...", np.cross(q, bb), nrm) >= 0.0)
            )
            el_q = np.arcsin(np.clip(q[..., 2], -1.0, 1.0))
            if sgn > 0:
                el_max = np.maximum(el_max, np.where(inside, el_q, -np.inf).max(axis=1))
            else:
                el_min = np.minimum(el_min, np.where(inside, el_q, np.inf).min(axis=1))

        # Poles inside (or on) the box: full width.
        tol = 1e-9 * max(self.width, self.height)
        full = np.zeros(n, dtype=bool)
        for sgn in (1.0, -1.0):
            pu = self.pixel_of_rays(np.array([[0.0, 0.0, sgn]]))[0]
            if np.all(np.isfinite(pu)):
                inside = (
                    (lo_u - tol <= pu[0])
                    & (pu[0] <= hi_u + tol)
                    & (lo_v - tol <= pu[1])
                    & (pu[1] <= hi_v + tol)
                )
                full |= inside
                if sgn > 0:
                    el_max = np.where(inside, np.pi / 2, el_max)
                else:
                    el_min = np.where(inside, -np.pi / 2, el_min)

        W, H = float(pano_w), float(pano_h)
        u1 = (0.5 - az_max / TWO_PI) * W
        u2 = (0.5 - az_min / TWO_PI) * W
        u1w = wrap_u(u1, W)
        u2w = u1w + (u2 - u1)
        out = np.stack(
            [
                np.where(full, 0.0, u1w),
                (0.5 - el_max / np.pi) * H,
                np.where(full, W, u2w),
                (0.5 - el_min / np.pi) * H,
            ],
            axis=-1,
        )
        return out


def cube_faces(face_size: int) -> dict[str, PerspectiveView]:
    """The six 90° cube faces of ``face_size × face_size`` px (``f = face_size / 2``).

    Keys: ``front`` (yaw 0), ``left`` (+π/2), ``back`` (π), ``right`` (-π/2), ``up`` (pitch +π/2, image top
    towards the back), ``down`` (pitch -π/2, image top towards the front).
    """
    s = int(face_size)
    q = math.pi / 2
    spec = {
        "front": (0.0, 0.0),
        "left": (q, 0.0),
        "back": (math.pi, 0.0),
        "right": (-q, 0.0),
        "up": (0.0, q),
        "down": (0.0, -q),
    }
    return {k: PerspectiveView(yaw, pitch, q, s, s, name=k) for k, (yaw, pitch) in spec.items()}


def horizon_views(
    *, count: int, fov: float, width: int, height: int, pitch: float = 0.0, yaw0: float = 0.0
) -> list[PerspectiveView]:
    """``count`` views evenly spaced around the horizon, starting at ``yaw0`` and turning left (CCW).

    Yaws are ``yaw0 + 2πk/count`` wrapped into [-π, π); names ``h0 … h{count-1}``. With ``fov`` ≥
    ``2π/count`` neighbouring views overlap, so every person is whole in at least one view when the overlap
    is at least a person's angular width.
    """
    if isinstance(count, bool) or not isinstance(count, int | np.integer) or int(count) <= 0:
        raise GeometryError(f"horizon_views count must be a positive integer, got {count!r}")
    n = int(count)
    out = []
    for k in range(n):
        yaw = (yaw0 + TWO_PI * k / n + math.pi) % TWO_PI - math.pi
        out.append(PerspectiveView(yaw, pitch, fov, width, height, name=f"h{k}"))
    return out
