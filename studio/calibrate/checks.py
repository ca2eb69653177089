"""Checks of the extrinsics fit: the input rows before it, a mirrored laser and an undetermined pose after.

* :func:`check_correspondences` refuses degenerate input (shapes, NaN, pixels outside the image,
  duplicates, too few rows, all points on one line), naming the rows;
* ``_refuse_mirrored`` refuses data whose laser y axis looks mirrored (a laser mounted upside down);
* ``_refuse_undetermined`` refuses a pose the points do not determine (1σ from the Jacobian above 5 cm or
  0.5° for 0.1° of pixel noise).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from studio.calibrate.errors import CalibrationError
from studio.calibrate.spherical import ExtrinsicsFit, _image_size, _pose_std

__all__ = ["check_correspondences"]

FloatArray = NDArray[np.float64]

_MIN_POINTS = 6  # rows needed for a fit from user input


# ---------------------------------------------------------------------------------------- input checks
def _rows(idx: ArrayLike, labels: Sequence[str] | None, limit: int = 8) -> str:
    ids = [int(i) for i in np.asarray(idx).reshape(-1)]
    names = [labels[i] if labels is not None else f"row {i + 1}" for i in ids[:limit]]
    more = f" and {len(ids) - limit} more" if len(ids) > limit else ""
    return ", ".join(names) + more


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


_MIRROR = np.array([1.0, -1.0, 1.0])
_MAX_STD_M = 0.05  # largest 1σ of the camera position for 0.1° of pixel noise, metres
_MAX_STD_DEG = 0.5  # largest 1σ of the camera rotation for 0.1° of pixel noise, degrees


def _all_median(fit: ExtrinsicsFit) -> float:
    """Median residual norm over every point (robust to < 50 % outliers), px."""
    return float(np.median(np.linalg.norm(fit.residual_px, axis=1)))


def _refuse_mirrored(
    p: FloatArray,
    q: FloatArray,
    W: int,
    H: int,
    fit: ExtrinsicsFit | None,
    kw: dict[str, Any],
    refit: Callable[..., ExtrinsicsFit],
) -> None:
    """Raise when the data look like a laser with a mirrored y axis (mounted upside down).

    With varying ``z`` a mirror is no rigid motion: the fit of ``(x, −y, z)`` is then far better. With one
    ``z`` for all points (or nearly) the mirror equals a half turn about x, so the data as given fit just
    as well with the camera upside down, and the mirrored data with it upright: an upside-down camera that
    fits no better than an upright one with ``y → −y`` is taken as a mirrored laser. ``refit`` is the
    fit (``refit(p, q, W, H, **kw)``) tried on the mirrored points.
    """
    floor = max(2.0, W / 2000.0)
    upside_down = False
    if fit is not None:
        med = _all_median(fit)
        upside_down = bool(fit.pose.R[2, 2] < 0.0)
        if not upside_down and med <= 2.0 * floor:
            return  # an upright camera that fits well: nothing to compare
    try:
        mirrored = refit(p * _MIRROR, q, W, H, **kw)
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
