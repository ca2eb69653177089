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

The camera model and :class:`ExtrinsicsFit` live in :mod:`studio.calibrate.spherical`, the input,
mirror and geometry checks in :mod:`studio.calibrate.checks`, :class:`CrossValidation` in
:mod:`studio.calibrate.crossval`; this module re-exports their public names.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from studio.calibrate.checks import (
    _MIN_POINTS,
    _refuse_mirrored,
    _refuse_undetermined,
    check_correspondences,
)
from studio.calibrate.crossval import _MIN_TRAIN, CrossValidation, _assign_folds
from studio.calibrate.errors import CalibrationError
from studio.calibrate.spherical import (
    POSE_PARAMS,
    ExtrinsicsFit,
    FloatArray,
    _angular_error_deg,
    _image_size,
    _lens_std,
    _Model,
    _refine,
    _res,
    pixel_residuals,
    project_points,
)
from studio.geometry.equirect import EquirectCamera
from studio.geometry.se import Pose3

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

_OUTLIER_SIGMAS = 3.5
_MAX_NOISE_DEG = 5.0  # a fit whose kept points are typically further off than this is no pose
_RAYLEIGH_MEDIAN = 1.1774  # median of a 2-D isotropic Gaussian residual norm, in σ


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
            _refuse_mirrored(p, q, W, H, None, kw, _fit)
        raise
    if mirror:
        _refuse_mirrored(p, q, W, H, fit, kw, _fit)
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
    fold, k = _assign_folds(n, folds, seed)
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
