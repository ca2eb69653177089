"""Laser ↔ panorama calibration: the 360° camera's pose from ``x, y, z, u, v`` correspondences.

* :mod:`studio.calibrate.extrinsics` fits the pose (spherical model, robust loss, outlier rejection),
  cross-validates it and projects points;
* :mod:`studio.calibrate.csvio` reads correspondence / point CSV files and writes pixel CSVs;
* :mod:`studio.calibrate.report` writes the text + PNG report of a calibration.

Usage is in ``docs/calibration.md``.
"""

from __future__ import annotations

from studio.calibrate.extrinsics import (
    CalibrationError,
    CrossValidation,
    ExtrinsicsFit,
    cross_validate,
    fit_extrinsics,
    project_points,
)

__all__ = [
    "CalibrationError",
    "CrossValidation",
    "ExtrinsicsFit",
    "cross_validate",
    "fit_extrinsics",
    "project_points",
]
