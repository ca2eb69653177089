"""Cross-validation of the extrinsics fit: the fold assignment and the held-out errors' result.

:func:`studio.calibrate.extrinsics.cross_validate` fits each training split and fills a
:class:`CrossValidation`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray
from scipy.spatial.transform import Rotation

from studio.calibrate.spherical import ExtrinsicsFit
from studio.geometry.se import Pose3

__all__ = ["CrossValidation"]

FloatArray = NDArray[np.float64]

_MIN_TRAIN = 5  # rows a cross-validation training fold needs


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


def _assign_folds(n: int, folds: int, seed: int) -> tuple[NDArray[np.int64], int]:
    """Fold index ``(n,)`` of each point and the number of folds ``k`` (≤ ``folds``; ``n``: leave-one-out).

    Folds shrink until every training split keeps ``_MIN_TRAIN`` points; failing that, leave-one-out.
    """
    k = min(int(folds), n)
    while k > 2 and n - math.ceil(n / k) < _MIN_TRAIN:
        k -= 1
    if n - math.ceil(n / k) < _MIN_TRAIN:
        k = n  # leave-one-out keeps the most training points
    perm = np.random.default_rng(seed).permutation(n)
    fold = np.empty(n, dtype=np.int64)
    fold[perm] = np.arange(n) % k
    return fold, k
