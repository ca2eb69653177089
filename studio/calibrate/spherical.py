"""The spherical camera model of the extrinsics fit (:mod:`studio.calibrate.extrinsics`).

Projection of base-frame points into the panorama (central or dual-lens), the wrapped pixel residuals
the fit minimises, the pose parameterisation handed to :func:`scipy.optimize.least_squares`, the
Jacobian-based 1σ of the pose and of a fitted lens offset, and the fit result :class:`ExtrinsicsFit`.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.optimize import least_squares
from scipy.spatial.transform import Rotation

from studio.calibrate.errors import CalibrationError
from studio.geometry.equirect import EquirectCamera
from studio.geometry.se import Pose3, rot_from_rpy

__all__ = ["POSE_PARAMS", "ExtrinsicsFit", "pixel_residuals", "project_points"]

FloatArray = NDArray[np.float64]
BoolArray = NDArray[np.bool_]

POSE_PARAMS = ("x", "y", "z", "roll", "pitch", "yaw")


def _image_size(image_size: Any) -> tuple[int, int]:
    try:
        w, h = (int(image_size[0]), int(image_size[1]))
    except (TypeError, ValueError, IndexError):
        raise CalibrationError(f"image size must be (width, height) in px, got {image_size!r}") from None
    if w <= 0 or h <= 0:
        raise CalibrationError(f"image size must be positive, got {w}×{h}")
    return w, h


# ---------------------------------------------------------------------------------------- projection
def project_points(
    pose: Pose3, xyz: ArrayLike, *, image_size: tuple[int, int], lens_offset: float = 0.0
) -> FloatArray:
    """Panorama pixels of base-frame points.

    Args:
        pose: camera pose ``T_base_cam``.
        xyz: ``(N, 3)`` points, metres, base frame.
        image_size: ``(W, H)``, px.
        lens_offset: dual-lens offset ``b``, metres (0: central camera).

    Returns:
        ``(N, 2)`` ``u, v`` px (u in ``[0, W)``; NaN for a point at the camera centre).
    """
    W, H = _image_size(image_size)
    uv, _ = EquirectCamera(W, H, pose, lens_offset).project(np.asarray(xyz, dtype=np.float64).reshape(-1, 3))
    return uv


def _cam_dirs(pose_R: FloatArray, pose_t: FloatArray, xyz: FloatArray, b: float) -> FloatArray:
    """Camera-frame directions ``(N, 3)`` to the points from the lens centre that sees each."""
    pc = (xyz - pose_t) @ pose_R
    if b:
        pc[:, 0] -= np.sign(pc[:, 0]) * b
    return pc


def _angles(
    pose_R: FloatArray, pose_t: FloatArray, xyz: FloatArray, b: float = 0.0
) -> tuple[FloatArray, FloatArray]:
    pc = _cam_dirs(pose_R, pose_t, xyz, b)
    return np.arctan2(pc[:, 1], pc[:, 0]), np.arctan2(pc[:, 2], np.hypot(pc[:, 0], pc[:, 1]))


def _res(
    R: FloatArray, t: FloatArray, xyz: FloatArray, uv: FloatArray, W: int, H: int, b: float = 0.0
) -> FloatArray:
    az, el = _angles(R, t, xyz, b)
    u = (0.5 - az / (2 * np.pi)) * W
    v = (0.5 - el / np.pi) * H
    du = np.mod(u - uv[:, 0] + W / 2.0, W) - W / 2.0
    return np.stack([du, v - uv[:, 1]], axis=1)


def pixel_residuals(
    pose: Pose3, xyz: ArrayLike, uv: ArrayLike, *, image_size: tuple[int, int], lens_offset: float = 0.0
) -> FloatArray:
    """Projected minus observed pixels, ``(N, 2)`` px; the column part is wrapped into ``[-W/2, W/2)``.

    ``lens_offset`` is the dual-lens offset ``b``, metres (0: central camera).
    """
    W, H = _image_size(image_size)
    p = np.asarray(xyz, dtype=np.float64).reshape(-1, 3)
    q = np.asarray(uv, dtype=np.float64).reshape(-1, 2)
    return _res(pose.R, pose.t, p, q, W, H, float(lens_offset))


def _angular_error_deg(
    pose: Pose3, xyz: FloatArray, uv: FloatArray, W: int, H: int, b: float = 0.0
) -> FloatArray:
    cam = EquirectCamera(W, H, pose)
    obs = cam.bearing_base(uv)
    d = _cam_dirs(pose.R, pose.t, xyz, b) @ pose.R.T if b else xyz - pose.t
    n = np.linalg.norm(d, axis=1, keepdims=True)
    d = d / np.where(n > 0, n, 1.0)
    cross = np.linalg.norm(np.cross(obs, d), axis=1)
    return np.degrees(np.arctan2(cross, np.sum(obs * d, axis=1)))  # exact also for tiny angles


# ---------------------------------------------------------------------------------------- results
@dataclass(frozen=True, eq=False)
class ExtrinsicsFit:
    """A fitted camera pose.

    Attributes:
        pose: ``T_base_cam`` (the rig camera pose convention of :mod:`studio.geometry.equirect`).
        inliers: ``(N,)`` bool, the points the final fit used.
        residual_px: ``(N, 2)`` projected − observed ``(du, dv)`` px, du wrapped into ``[-W/2, W/2)``.
        ang_err_deg: ``(N,)`` angle between observed and predicted rays, degrees.
        cost: final robust cost of the inliers (scipy's ``0.5·Σρ``), px².
        n_iter: function evaluations of the final refinement.
        image_size: ``(W, H)`` px.
        threshold_px: residual norm above which a point was rejected, px.
        sigma_px: robust noise scale of the inliers' residual norms, px.
        z_constant: every point has the same ``z`` (camera height is relative to that plane).
        lens_offset: dual-lens offset ``b``, metres (held or fitted; 0: the central camera).
        lens_offset_std: 1σ of a fitted ``b`` from the Jacobian at the inliers' noise ``sigma_px``,
            metres; NaN when ``b`` was held.
    """

    pose: Pose3
    inliers: BoolArray
    residual_px: FloatArray
    ang_err_deg: FloatArray
    cost: float
    n_iter: int
    image_size: tuple[int, int] = (0, 0)
    threshold_px: float = math.nan
    sigma_px: float = math.nan
    z_constant: bool = False
    lens_offset: float = 0.0
    lens_offset_std: float = math.nan

    @property
    def lens_fitted(self) -> bool:
        """Whether ``lens_offset`` was fitted (not held)."""
        return not math.isnan(self.lens_offset_std)

    def __post_init__(self) -> None:
        n = len(self.inliers)
        if self.residual_px.shape != (n, 2) or self.ang_err_deg.shape != (n,):
            raise ValueError("ExtrinsicsFit arrays must have N, (N, 2) and (N,) rows")

    @property
    def n(self) -> int:
        return len(self.inliers)

    @property
    def n_outliers(self) -> int:
        return int((~self.inliers).sum())


# ---------------------------------------------------------------------------------------- fitting
class _Model:
    """Maps a free-parameter vector to a pose (rotation vector about R0, or roll/pitch/yaw when held)."""

    def __init__(self, start: Pose3, fixed: Sequence[str], *, b0: float = 0.0, fit_b: bool = False) -> None:
        unknown = [f for f in fixed if f not in POSE_PARAMS]
        if unknown:
            raise CalibrationError(f"unknown fixed pose parameter(s) {unknown}; expected {POSE_PARAMS}")
        self.fixed = set(fixed)
        self.rpy_mode = bool(self.fixed & {"roll", "pitch", "yaw"})
        self.R0 = start.R
        rot0 = np.array(start.rpy()) if self.rpy_mode else np.zeros(3)
        self.full0 = np.concatenate([start.t, rot0])
        self.free = np.array([k not in self.fixed for k in POSE_PARAMS])
        self.b0 = float(b0)
        self.fit_b = bool(fit_b)

    def x0(self) -> FloatArray:
        x = self.full0[self.free].copy()
        return np.append(x, self.b0) if self.fit_b else x

    def lens(self, x: FloatArray) -> float:
        """The lens offset ``b`` of a parameter vector (the last entry when fitted), metres."""
        return float(x[-1]) if self.fit_b else self.b0

    def pose_parts(self, x: FloatArray) -> tuple[FloatArray, FloatArray]:
        full = self.full0.copy()
        full[self.free] = x[:-1] if self.fit_b else x
        if self.rpy_mode:
            R = rot_from_rpy(*full[3:])
        else:
            R = self.R0 @ Rotation.from_rotvec(full[3:]).as_matrix()
        return R, full[:3]


def _refine(
    start: Pose3,
    xyz: FloatArray,
    uv: FloatArray,
    W: int,
    H: int,
    *,
    fixed: Sequence[str],
    loss: str,
    f_scale: float,
    max_nfev: int,
    tol: float = 1e-12,
    b: float = 0.0,
    fit_b: bool = False,
) -> tuple[Pose3, float, float, int]:
    """Least-squares refinement; returns the pose, the lens offset, the cost and the evaluations."""
    model = _Model(start, fixed, b0=b, fit_b=fit_b)
    x0 = model.x0()
    if x0.size == 0:
        return start, b, 0.0, 0

    def fun(x: FloatArray) -> FloatArray:
        R, t = model.pose_parts(x)
        return _res(R, t, xyz, uv, W, H, model.lens(x)).ravel()

    try:
        sol = least_squares(
            fun,
            x0,
            loss=loss,
            f_scale=f_scale,
            max_nfev=max_nfev,
            x_scale="jac",
            ftol=tol,
            xtol=tol,
            gtol=tol,
        )
    except ValueError as exc:
        raise CalibrationError(f"least-squares fit failed: {exc}") from None
    R, t = model.pose_parts(sol.x)
    return Pose3(R, t), model.lens(sol.x), float(sol.cost), int(sol.nfev)


def _pose_std(fit: ExtrinsicsFit, p: FloatArray, q: FloatArray, fixed: Sequence[str]) -> FloatArray:
    """1σ of ``x y z`` (m) and of the rotation about the camera axes (deg) for 0.1° of pixel noise.

    Held parameters have 0; an undetermined one is inf.
    """
    W, H = fit.image_size
    m = fit.inliers
    model = _Model(fit.pose, [f for f in fixed if f in ("x", "y", "z")])
    x0 = model.x0()

    def f(x: FloatArray) -> FloatArray:
        R, t = model.pose_parts(x)
        return _res(R, t, p[m], q[m], W, H, fit.lens_offset).ravel()

    r0 = f(x0)
    J = np.empty((r0.size, x0.size))
    for k in range(x0.size):
        h = 1e-6
        dx = np.zeros_like(x0)
        dx[k] = h
        J[:, k] = (f(x0 + dx) - f(x0 - dx)) / (2 * h)
    noise = W / 3600.0  # px per 0.1°
    out = np.zeros(6)
    try:
        cov = np.linalg.inv(J.T @ J) * noise**2
        d = np.sqrt(np.clip(np.diag(cov), 0.0, None))
        if not np.isfinite(d).all() or np.linalg.cond(J) > 1e12:
            raise np.linalg.LinAlgError
    except np.linalg.LinAlgError:
        d = np.full(x0.size, np.inf)
    free = [k for k in POSE_PARAMS[:3] if k not in fixed] + ["rx", "ry", "rz"]
    for name, v in zip(free, d, strict=True):
        if name in POSE_PARAMS[:3]:
            out[POSE_PARAMS.index(name)] = v
        else:
            out[3 + ("rx", "ry", "rz").index(name)] = math.degrees(v) if math.isfinite(v) else v
    if any(k in fixed for k in ("roll", "pitch", "yaw")):
        out[3:] = 0.0  # rotation partly held: not judged here
    return out


def _lens_std(
    pose: Pose3, b: float, p: FloatArray, q: FloatArray, W: int, H: int, fixed: Sequence[str], sigma: float
) -> float:
    """1σ of a fitted lens offset (metres) from the Jacobian of all free parameters, ``sigma`` px noise."""
    model = _Model(pose, fixed, b0=b, fit_b=True)
    x0 = model.x0()

    def f(x: FloatArray) -> FloatArray:
        R, t = model.pose_parts(x)
        return _res(R, t, p, q, W, H, model.lens(x)).ravel()

    J = np.empty((2 * len(p), x0.size))
    for k in range(x0.size):
        dx = np.zeros_like(x0)
        dx[k] = 1e-6
        J[:, k] = (f(x0 + dx) - f(x0 - dx)) / 2e-6
    dof = J.shape[0] - J.shape[1]
    if dof <= 0 or np.linalg.cond(J) > 1e12:
        return math.inf
    s2 = max(float(sigma), 1e-3) ** 2 * J.shape[0] / dof  # per-component noise, few-points corrected
    var = float(np.linalg.inv(J.T @ J)[-1, -1]) * s2
    return math.sqrt(var) if var >= 0 and math.isfinite(var) else math.inf
