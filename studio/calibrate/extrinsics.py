"""The 360° camera's pose from laser ↔ panorama correspondences (``x, y, z, u, v`` rows).

Model: the panorama is an exact central spherical camera (:mod:`studio.geometry.equirect`); a base-frame
point ``p`` is seen at the pixel of the direction ``R^T (p - t)`` where ``(R, t)`` is the camera pose
``T_base_cam``. The fit minimises pixel residuals ``(du, dv)`` — ``du`` wrapped across the seam into
``[-W/2, W/2)`` — with :func:`scipy.optimize.least_squares` and a robust loss:

1. *initialisation without a guess*: camera centres ``(0, 0, h)`` for a few heights ``h``, each with the
   rotation that best aligns the observed rays with the directions to the points (Wahba / SVD), plus a yaw
   grid of level poses; the best few by median residual are refined with a wide robust loss;
2. *outlier rejection*: a point is an outlier when its residual norm exceeds ``max(3.5·σ, floor)``
   (σ from the median residual, floor ``max(2 px, W/2000)`` or ``outlier_px``), then a refit on the
   inliers, repeated until the inlier set settles;
3. the rotation is a rotation vector about the current estimate (no singularity anywhere); with fixed
   rotation parameters it is roll/pitch/yaw so that single angles can be held.

Dual-lens model (``lens_offset``): the panorama of a dual-fisheye camera is seen from two lens centres
``(±b, 0, 0)`` in the camera frame, the hemisphere ``sign(x_cam)`` choosing the lens
(:class:`~studio.geometry.equirect.EquirectCamera`). ``b`` is held (default 0: the central camera) or,
with ``lens_offset=None``, fitted as a 7th parameter after initialising with ``b = 0``;
:mod:`studio.calibrate.lens` decides whether the dual-lens model pays off.

When every ``z`` is equal (the ``z = 0`` when-unknown convention) the fit is still exact: the camera
height is then relative to the targets' plane and row errors absorb the target's true height.

Refused besides degenerate input (:func:`check_correspondences`): a mirrored laser y axis (the fit with
``y → −y`` is far better, or with one ``z`` the only fit is an upside-down camera), a pose whose kept points
are typically more than 5° off, and a pose the points do not determine (1σ from the Jacobian above 5 cm or
0.5° for 0.1° of pixel noise); see :func:`fit_extrinsics`.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.optimize import least_squares
from scipy.spatial.transform import Rotation

from studio.errors import StudioError
from studio.geometry.equirect import EquirectCamera
from studio.geometry.se import Pose3, rot_from_rpy

__all__ = [
    "POSE_PARAMS",
    "CalibrationError",
    "CrossValidation",
    "ExtrinsicsFit",
    "check_correspondences",
    "cross_validate",
    "fit_extrinsics",
    "pixel_residuals",
    "project_points",
]

FloatArray = NDArray[np.float64]
BoolArray = NDArray[np.bool_]

POSE_PARAMS = ("x", "y", "z", "roll", "pitch", "yaw")
_MIN_POINTS = 6  # rows needed for a fit from user input
_MIN_TRAIN = 5  # rows a cross-validation training fold needs
_OUTLIER_SIGMAS = 3.5
_MAX_NOISE_DEG = 5.0  # a fit whose kept points are typically further off than this is no pose
_RAYLEIGH_MEDIAN = 1.1774  # median of a 2-D isotropic Gaussian residual norm, in σ


class CalibrationError(StudioError):
    """Calibration input that cannot give a pose; the message names the problem and the rows."""


# ---------------------------------------------------------------------------------------- input checks
def _rows(idx: ArrayLike, labels: Sequence[str] | None, limit: int = 8) -> str:
    ids = [int(i) for i in np.asarray(idx).reshape(-1)]
    names = [labels[i] if labels is not None else f"row {i + 1}" for i in ids[:limit]]
    more = f" and {len(ids) - limit} more" if len(ids) > limit else ""
    return ", ".join(names) + more


def _image_size(image_size: Any) -> tuple[int, int]:
    try:
        w, h = (int(image_size[0]), int(image_size[1]))
    except (TypeError, ValueError, IndexError):
        raise CalibrationError(f"image size must be (width, height) in px, got {image_size!r}") from None
    if w <= 0 or h <= 0:
        raise CalibrationError(f"image size must be positive, got {w}×{h}")
    return w, h


def check_correspondences(
    xyz: ArrayLike,
    uv: ArrayLike,
    *,
    image_size: tuple[int, int],
    labels: Sequence[str] | None = None,
    min_points: int = _MIN_POINTS,
) -> tuple[FloatArray, FloatArray]:
    """Validate correspondences before a fit.

    Args:
        xyz: ``(N, 3)`` points in the base/laser frame, metres.
        uv: ``(N, 2)`` their panorama pixels, px from the left/top edge.
        image_size: panorama ``(W, H)``, px.
        labels: how to name row ``i`` in messages (e.g. ``"line 7"``); default ``"row i+1"``.
        min_points: fewest rows accepted.

    Returns:
        ``xyz`` and ``uv`` as float64 arrays.

    Raises:
        CalibrationError: wrong shapes, NaN/inf, pixels outside ``[0, W) × [0, H)``, duplicated rows, fewer
            than ``min_points`` rows, or all points on one line (the message names the rows).
    """
    W, H = _image_size(image_size)
    p = np.asarray(xyz, dtype=np.float64)
    q = np.asarray(uv, dtype=np.float64)
    if p.ndim != 2 or p.shape[1] != 3:
        raise CalibrationError(f"points must have shape (N, 3) (x, y, z), got {p.shape}")
    if q.ndim != 2 or q.shape[1] != 2:
        raise CalibrationError(f"pixels must have shape (N, 2) (u, v), got {q.shape}")
    if len(p) != len(q):
        raise CalibrationError(f"{len(p)} points but {len(q)} pixels")
    bad = ~(np.isfinite(p).all(axis=1) & np.isfinite(q).all(axis=1))
    if bad.any():
        raise CalibrationError(f"NaN or infinite values in {_rows(np.flatnonzero(bad), labels)}")
    outside = (q[:, 0] < 0) | (q[:, 0] >= W) | (q[:, 1] < 0) | (q[:, 1] >= H)
    if outside.any():
        i = int(np.flatnonzero(outside)[0])
        raise CalibrationError(
            f"pixels outside the {W}×{H} image (u in [0, {W}), v in [0, {H})) in "
            f"{_rows(np.flatnonzero(outside), labels)} (first: u={q[i, 0]:g}, v={q[i, 1]:g}); "
            "is --image-size right?"
        )
    if len(p) < min_points:
        raise CalibrationError(f"a camera pose needs at least {min_points} correspondences, got {len(p)}")
    rows = np.concatenate([p, q], axis=1)
    _, first, counts = np.unique(rows, axis=0, return_index=True, return_counts=True)
    if (counts > 1).any():
        dup_groups = []
        for f in first[counts > 1][:4]:
            same = np.flatnonzero((rows == rows[f]).all(axis=1))
            dup_groups.append(_rows(same, labels))
        raise CalibrationError(f"duplicated correspondences: {'; '.join(dup_groups)} (remove the copies)")
    centred = p - p.mean(axis=0)
    s = np.linalg.svd(centred, compute_uv=False)
    if s[1] / math.sqrt(len(p)) < 1e-4:
        raise CalibrationError(
            f"all {len(p)} points lie on one line (or at one place): the camera's rotation about it is "
            "undetermined; add points in other directions"
        )
    return p, q


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


@dataclass(frozen=True, eq=False)
class CrossValidation:
    """K-fold held-out errors: each point's error under the pose fitted without its fold.

    Attributes:
        fit: the fit on all points (its ``inliers`` decide which points the statistics cover).
        col_err_px: ``(N,)`` held-out signed column error (wrapped), px.
        row_err_px: ``(N,)`` held-out signed row error, px.
        ang_err_deg: ``(N,)`` held-out angular error, degrees.
        fold: ``(N,)`` fold index of each point.
        fold_poses: the pose fitted on each training split.
    """

    fit: ExtrinsicsFit
    col_err_px: FloatArray
    row_err_px: FloatArray
    ang_err_deg: FloatArray
    fold: NDArray[np.int64]
    fold_poses: tuple[Pose3, ...] = field(default=())

    @property
    def folds(self) -> int:
        return len(self.fold_poses)

    def pose_spread(self) -> tuple[float, float]:
        """Largest distance (m) and rotation angle (deg) of a fold's pose from the full fit's."""
        if not self.fold_poses:
            return 0.0, 0.0
        d = [float(np.linalg.norm(p.t - self.fit.pose.t)) for p in self.fold_poses]
        a = [
            float(np.degrees(np.linalg.norm(Rotation.from_matrix(self.fit.pose.R.T @ p.R).as_rotvec())))
            for p in self.fold_poses
        ]
        return max(d), max(a)

    def to_json(self) -> dict[str, Any]:
        """DESIGN.md keys (over the full fit's inliers) plus extras (``*_all``: every point)."""
        m = self.fit.inliers
        col, row, ang = np.abs(self.col_err_px), np.abs(self.row_err_px), self.ang_err_deg

        def stat(a: FloatArray, f: Any) -> float:
            return round(float(f(a)), 4) if len(a) else math.nan

        spread_m, spread_deg = self.pose_spread()
        return {
            "col_px_mean": stat(col[m], np.mean),
            "col_px_median": stat(col[m], np.median),
            "col_px_p90": stat(col[m], lambda a: np.percentile(a, 90)),
            "row_px_mean": stat(row[m], np.mean),
            "row_px_median": stat(row[m], np.median),
            "ang_deg_mean": stat(ang[m], np.mean),
            "n": len(m),
            "n_outliers": int((~m).sum()),
            "row_px_p90": stat(row[m], lambda a: np.percentile(a, 90)),
            "ang_deg_median": stat(ang[m], np.median),
            "col_px_mean_all": stat(col, np.mean),
            "col_px_median_all": stat(col, np.median),
            "folds": self.folds,
            "fold_spread_m": round(spread_m, 5),
            "fold_spread_deg": round(spread_deg, 4),
            "z_constant": bool(self.fit.z_constant),
            "lens_offset_m": round(self.fit.lens_offset, 6) + 0.0,
        }

    def table(self) -> str:
        """A readable summary of the cross-validated errors."""
        j = self.to_json()
        head = f"held-out error ({j['folds']}-fold CV)"
        lines = [
            f"{head:<30} {'mean':>8} {'median':>8} {'p90':>8}",
            f"{'column (px)':<30} {j['col_px_mean']:>8.2f} {j['col_px_median']:>8.2f} "
            f"{j['col_px_p90']:>8.2f}",
            f"{'row (px)':<30} {j['row_px_mean']:>8.2f} {j['row_px_median']:>8.2f} {j['row_px_p90']:>8.2f}",
            f"{'angle (deg)':<30} {j['ang_deg_mean']:>8.3f} {j['ang_deg_median']:>8.3f} {'':>8}",
            f"{'column, all points (px)':<30} {j['col_px_mean_all']:>8.2f} {j['col_px_median_all']:>8.2f}",
            f"points {j['n']}, outliers rejected {j['n_outliers']}, "
            f"fold pose spread {j['fold_spread_m'] * 100:.1f} cm / {j['fold_spread_deg']:.2f}°",
        ]
        if self.fit.lens_offset:
            std = self.fit.lens_offset_std
            lines.append(
                f"dual-lens model: lens centres at (±b, 0, 0) in the camera frame, b = "
                f"{self.fit.lens_offset * 100:+.2f} cm"
                + (f" ± {std * 100:.2f} cm" if math.isfinite(std) else "")
            )
        if j["z_constant"]:
            lines.append(
                "all points have the same z: the camera z is relative to that plane, and row errors "
                "include the target's true height"
            )
        return "\n".join(lines)


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


def _wahba(obs: FloatArray, tgt: FloatArray) -> FloatArray:
    """Rotation R minimising Σ |R obs_i − tgt_i|² (both (N, 3) unit vectors)."""
    U, _, Vt = np.linalg.svd(tgt.T @ obs)
    D = np.diag([1.0, 1.0, np.sign(np.linalg.det(U @ Vt)) or 1.0])
    return U @ D @ Vt


def _candidates(xyz: FloatArray, uv: FloatArray, W: int, H: int) -> list[Pose3]:
    rays = EquirectCamera(W, H).rays(uv)
    zc = float(np.median(xyz[:, 2]))
    heights = zc + np.array([-1.0, -0.3, 0.0, 0.3, 0.6, 1.0, 1.5, 2.0])
    out: list[Pose3] = []
    for h in heights:
        c = np.array([0.0, 0.0, h])
        d = xyz - c
        n = np.linalg.norm(d, axis=1, keepdims=True)
        if np.any(n < 1e-9):
            continue
        out.append(Pose3(_wahba(rays, d / n), c))
        for yaw in np.linspace(-np.pi, np.pi, 12, endpoint=False):
            out.append(Pose3.from_xyz_rpy(0.0, 0.0, float(h), 0.0, 0.0, float(yaw)))
    return out


def _median_norm(pose: Pose3, xyz: FloatArray, uv: FloatArray, W: int, H: int, b: float = 0.0) -> float:
    r = np.linalg.norm(_res(pose.R, pose.t, xyz, uv, W, H, b), axis=1)
    return float(np.nanmedian(r)) if np.isfinite(r).any() else math.inf


_MIRROR = np.array([1.0, -1.0, 1.0])
_MAX_STD_M = 0.05  # largest 1σ of the camera position for 0.1° of pixel noise, metres
_MAX_STD_DEG = 0.5  # largest 1σ of the camera rotation for 0.1° of pixel noise, degrees


def _all_median(fit: ExtrinsicsFit) -> float:
    """Median residual norm over every point (robust to < 50 % outliers), px."""
    return float(np.median(np.linalg.norm(fit.residual_px, axis=1)))


def _refuse_mirrored(
    p: FloatArray, q: FloatArray, W: int, H: int, fit: ExtrinsicsFit | None, kw: dict[str, Any]
) -> None:
    """Raise when the data look like a laser with a mirrored y axis (mounted upside down).

    With varying ``z`` a mirror is no rigid motion: the fit of ``(x, −y, z)`` is then far better. With one
    ``z`` for all points (or nearly) the mirror equals a half turn about x, so the data as given fit just
    as well with the camera upside down, and the mirrored data with it upright: an upside-down camera that
    fits no better than an upright one with ``y → −y`` is taken as a mirrored laser.
    """
    floor = max(2.0, W / 2000.0)
    upside_down = False
    if fit is not None:
        med = _all_median(fit)
        upside_down = bool(fit.pose.R[2, 2] < 0.0)
        if not upside_down and med <= 2.0 * floor:
            return  # an upright camera that fits well: nothing to compare
    try:
        mirrored = _fit(p * _MIRROR, q, W, H, **kw)
    except CalibrationError:
        return
    med_m = _all_median(mirrored)
    if med_m > max(4.0 * floor, W / 400.0) or mirrored.n_outliers > 0.3 * mirrored.n:
        return  # the mirrored data do not fit well either: not a mirror, just bad data
    note = ""
    if fit is None:
        mirror = True
        given = "no pose fits the file as given"
    else:
        given = f"a median error of {med:.1f} px as given"
        mirror = med_m < 0.5 * med
        if upside_down and mirrored.pose.R[2, 2] > 0.0 and med_m <= 1.2 * med + 1e-6:
            mirror = True
            given += ", where the camera comes out upside down"
            note = (
                " (a camera really mounted upside down: give the targets' true heights in z, which tell "
                "the two apart, or call fit_extrinsics(..., check_mirror=False))"
                if fit.z_constant
                else " (a camera really mounted upside down: fit_extrinsics(..., check_mirror=False))"
            )
    if mirror:
        raise CalibrationError(
            f"the laser's y axis looks mirrored (a laser mounted upside down, or a panorama flipped "
            f"left-right): with y -> -y the points fit with a median error of {med_m:.1f} px, against "
            f"{given}. Negate the y column (y -> -y) and run again; when converting scans to the base "
            f"frame, give the upside-down laser's mount (roll 180°){note}"
        )


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


def _refuse_undetermined(fit: ExtrinsicsFit, p: FloatArray, q: FloatArray, fixed: Sequence[str]) -> None:
    """Raise when the inliers do not determine the pose (see ``check_geometry``)."""
    std = _pose_std(fit, p, q, fixed)
    if std[:3].max() <= _MAX_STD_M and std[3:].max() <= _MAX_STD_DEG:
        return
    pts = p[fit.inliers]
    why = []
    n = len(pts)
    az = np.arctan2(pts[:, 1], pts[:, 0])
    gaps = np.diff(np.sort(np.concatenate([az, az[:1] + 2 * np.pi])))
    span = math.degrees(2 * np.pi - float(gaps.max()))
    sv = np.linalg.svd(pts - pts.mean(axis=0), compute_uv=False)
    if span < 30.0:
        why.append(f"all within {span:.0f}° of azimuth around the laser")
    if sv[1] < 0.05 * sv[0]:
        why.append("nearly on one line")
    if n < 10:
        why.append(f"only {n} points")
    reason = f" (the points are {', '.join(why)})" if why else ""
    worst = (
        f"camera position ±{std[:3].max():.2f} m"
        if std[:3].max() / _MAX_STD_M >= std[3:].max() / _MAX_STD_DEG
        else f"camera rotation ±{std[3:].max():.1f}°"
    )
    raise CalibrationError(
        f"the correspondences do not determine the camera pose{reason}: 0.1° of pixel noise moves the "
        f"{worst}; add target positions in other directions and at other distances around the robot"
    )


def fit_extrinsics(
    xyz: ArrayLike,
    uv: ArrayLike,
    *,
    image_size: tuple[int, int],
    initial: Pose3 | None = None,
    loss: str = "soft_l1",
    outlier_px: float | None = None,
    fixed: Sequence[str] = (),
    labels: Sequence[str] | None = None,
    min_points: int = _MIN_POINTS,
    check_mirror: bool = True,
    check_geometry: bool = True,
    lens_offset: float | None = 0.0,
) -> ExtrinsicsFit:
    """Fit the camera pose ``T_base_cam`` to correspondences.

    Args:
        xyz: ``(N, 3)`` points in the laser/base frame, metres (z above the laser plane; 0 when unknown).
        uv: ``(N, 2)`` their panorama pixels, px from the left/top edge.
        image_size: panorama ``(W, H)``, px.
        initial: a starting pose (also the value of ``fixed`` parameters); None: found automatically.
        loss: scipy robust loss (``linear``, ``soft_l1``, ``huber``, ``cauchy``, ``arctan``).
        outlier_px: reject points whose residual norm exceeds this, px (default: ``max(3.5·σ, W/2000, 2)``).
        fixed: pose parameters held at ``initial``: any of ``x y z roll pitch yaw``.
        labels: names of the rows in error messages (e.g. CSV line numbers).
        min_points: fewest rows accepted.
        check_mirror: refuse data whose y axis looks mirrored (a laser mounted upside down): the points
            fit far better with ``y → −y``, or, with (nearly) one ``z``, they fit only with the camera
            upside down below the targets, which is how a mirrored laser looks then.
        check_geometry: refuse a pose that agrees with none of the points (the kept points typically
            more than 5° off; not with ``outlier_px``) or that the points do not determine (nearly
            collinear, all at one azimuth, too few): 1σ above 0.05 m or 0.5° for 0.1° of pixel noise.
        lens_offset: the dual-lens offset ``b`` (metres, ``|b| < 0.2``) held during the fit; 0 is the
            central camera; None fits it as a 7th parameter (started at 0 after the outlier-robust
            initialisation), with its 1σ in ``lens_offset_std``.

    Returns:
        The :class:`ExtrinsicsFit`.

    Raises:
        CalibrationError: degenerate input (see :func:`check_correspondences`), fixed parameters without
            ``initial``, no pose that agrees with enough points, a mirrored y axis, or a pose that the
            points do not determine.
    """
    W, H = _image_size(image_size)
    p, q = check_correspondences(xyz, uv, image_size=(W, H), labels=labels, min_points=min_points)
    if loss not in ("linear", "soft_l1", "huber", "cauchy", "arctan"):
        raise CalibrationError(f"unknown loss '{loss}' (linear, soft_l1, huber, cauchy, arctan)")
    if fixed and initial is None:
        raise CalibrationError(f"fixed pose parameters {list(fixed)} need an initial pose")
    _Model(Pose3.identity(), fixed)  # validates the names
    if outlier_px is not None and not outlier_px > 0:
        raise CalibrationError(f"outlier threshold must be positive, got {outlier_px}")
    if lens_offset is not None and not (math.isfinite(lens_offset) and abs(lens_offset) < 0.2):
        raise CalibrationError(f"lens offset must be a finite number within ±0.2 m, got {lens_offset}")
    kw: dict[str, Any] = {
        "lens_offset": lens_offset,
        "initial": initial,
        "loss": loss,
        "outlier_px": outlier_px,
        "fixed": tuple(fixed),
        "min_points": min_points,
    }
    mirror = check_mirror and not fixed and initial is None
    try:
        fit = _fit(p, q, W, H, **kw)
    except CalibrationError:
        if mirror:
            _refuse_mirrored(p, q, W, H, None, kw)
        raise
    if mirror:
        _refuse_mirrored(p, q, W, H, fit, kw)
    if check_geometry:
        W = fit.image_size[0]
        if outlier_px is None and fit.sigma_px > W * _MAX_NOISE_DEG / 360.0:
            raise CalibrationError(
                f"no camera pose agrees with the points: the best one leaves a typical error of "
                f"{fit.sigma_px:.0f} px ({fit.sigma_px * 360.0 / W:.1f}°) on the {fit.n - fit.n_outliers} "
                f"of {fit.n} points it keeps; check that each row's pixel and laser position are of the "
                "same target at the same moment, the u/v columns, and --image-size"
            )
        _refuse_undetermined(fit, p, q, fixed)
    return fit


def _fit(
    p: FloatArray,
    q: FloatArray,
    W: int,
    H: int,
    *,
    initial: Pose3 | None,
    loss: str,
    outlier_px: float | None,
    fixed: Sequence[str],
    min_points: int,
    lens_offset: float | None = 0.0,
) -> ExtrinsicsFit:
    floor = max(2.0, W / 2000.0)
    fit_b = lens_offset is None
    b = 0.0 if lens_offset is None else float(lens_offset)
    wide = max(floor, W / 200.0)

    # 1. robust start
    if initial is not None and fixed:
        best, _, _, _ = _refine(
            initial, p, q, W, H, fixed=fixed, loss="soft_l1", f_scale=wide, max_nfev=200, b=b
        )
    else:
        cands = _candidates(p, q, W, H) + ([initial] if initial is not None else [])
        scored = sorted(cands, key=lambda c: _median_norm(c, p, q, W, H, b))
        tried = []
        for c in scored[:4] + ([initial] if initial is not None else []):
            pose, _, _, _ = _refine(
                c, p, q, W, H, fixed=(), loss="soft_l1", f_scale=wide, max_nfev=100, tol=1e-8, b=b
            )
            tried.append((_median_norm(pose, p, q, W, H, b), pose))
        best = min(tried, key=lambda a: a[0])[1]

    # 2. outlier rejection + refit until the inlier set settles
    inl = np.ones(len(p), dtype=bool)
    n_free = len(POSE_PARAMS) - len(set(fixed)) + int(fit_b)
    sigma = math.nan
    thr = math.nan
    cost, nfev = 0.0, 0
    for _ in range(6):
        r = np.linalg.norm(_res(best.R, best.t, p, q, W, H, b), axis=1)
        sigma = float(np.median(r[inl])) / _RAYLEIGH_MEDIAN
        # residuals of a fit to few points understate the noise: the 2m residuals keep 2m − k dof
        dof = 2 * int(inl.sum()) - n_free
        sigma_noise = sigma * math.sqrt(2 * int(inl.sum()) / dof) if dof > 0 else math.inf
        thr = float(outlier_px) if outlier_px is not None else max(_OUTLIER_SIGMAS * sigma_noise, floor)
        new = r <= thr
        need = max(3, min(min_points, _MIN_TRAIN, len(p) - 1))
        if new.sum() < need:
            raise CalibrationError(
                f"no camera pose agrees with enough points: only {int(new.sum())} of {len(p)} are within "
                f"{thr:.1f} px of the best pose (are u/v columns swapped, or --image-size wrong?)"
            )
        fs = max(2.0 * sigma, 0.5) if outlier_px is None else max(float(outlier_px) / 3.0, 0.5)
        best, b, cost, nfev = _refine(
            best, p[new], q[new], W, H, fixed=fixed, loss=loss, f_scale=fs, max_nfev=300, b=b, fit_b=fit_b
        )
        if np.array_equal(new, inl):
            break
        inl = new
    res = _res(best.R, best.t, p, q, W, H, b)
    r = np.linalg.norm(res, axis=1)
    sigma = float(np.median(r[inl])) / _RAYLEIGH_MEDIAN
    b_std = _lens_std(best, b, p[inl], q[inl], W, H, fixed, sigma) if fit_b else math.nan
    return ExtrinsicsFit(
        pose=best,
        inliers=inl,
        residual_px=res,
        ang_err_deg=_angular_error_deg(best, p, q, W, H, b),
        cost=cost,
        n_iter=nfev,
        image_size=(W, H),
        threshold_px=thr,
        sigma_px=sigma,
        z_constant=bool(np.ptp(p[:, 2]) < 1e-9),
        lens_offset=b + 0.0,
        lens_offset_std=b_std,
    )


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


def cross_validate(
    xyz: ArrayLike,
    uv: ArrayLike,
    *,
    image_size: tuple[int, int],
    folds: int = 5,
    seed: int = 0,
    labels: Sequence[str] | None = None,
    **fit_kwargs: Any,
) -> CrossValidation:
    """K-fold cross-validation of :func:`fit_extrinsics`.

    Each point's error comes from the pose fitted on the other folds (each training fit does its own
    initialisation and outlier rejection). With fewer points than folds it is leave-one-out.

    Args:
        xyz: ``(N, 3)`` metres; uv: ``(N, 2)`` px; image_size: ``(W, H)`` px.
        folds: K ≥ 2.
        seed: shuffles the fold assignment.
        labels: names of the rows in error messages.
        **fit_kwargs: passed to :func:`fit_extrinsics`.

    Raises:
        CalibrationError: bad input, ``folds < 2``, or a training fold that cannot be fitted.
    """
    W, H = _image_size(image_size)
    if folds < 2:
        raise CalibrationError(f"cross-validation needs at least 2 folds, got {folds}")
    full = fit_extrinsics(xyz, uv, image_size=(W, H), labels=labels, **fit_kwargs)
    p = np.asarray(xyz, dtype=np.float64)
    q = np.asarray(uv, dtype=np.float64)
    n = len(p)
    k = min(int(folds), n)
    while k > 2 and n - math.ceil(n / k) < _MIN_TRAIN:
        k -= 1
    if n - math.ceil(n / k) < _MIN_TRAIN:
        k = n  # leave-one-out keeps the most training points
    perm = np.random.default_rng(seed).permutation(n)
    fold = np.empty(n, dtype=np.int64)
    fold[perm] = np.arange(n) % k
    col = np.full(n, np.nan)
    row = np.full(n, np.nan)
    ang = np.full(n, np.nan)
    poses: list[Pose3] = []
    kw = dict(fit_kwargs)
    kw["min_points"] = _MIN_TRAIN
    kw["check_mirror"] = False  # the full fit checked these; a fold's errors show the rest
    kw["check_geometry"] = False
    for f in range(k):
        test = fold == f
        train = ~test
        try:
            fit = fit_extrinsics(p[train], q[train], image_size=(W, H), **kw)
        except CalibrationError as exc:
            raise CalibrationError(f"cross-validation fold {f + 1} of {k}: {exc}") from None
        poses.append(fit.pose)
        res = _res(fit.pose.R, fit.pose.t, p[test], q[test], W, H, fit.lens_offset)
        col[test], row[test] = res[:, 0], res[:, 1]
        ang[test] = _angular_error_deg(fit.pose, p[test], q[test], W, H, fit.lens_offset)
    return CrossValidation(
        fit=full, col_err_px=col, row_err_px=row, ang_err_deg=ang, fold=fold, fold_poses=tuple(poses)
    )
