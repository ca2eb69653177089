"""Laser ↔ panorama calibration: the 360° camera's pose from ``x, y, z, u, v`` correspondences.

* :mod:`studio.calibrate.extrinsics` fits the pose (spherical model, robust loss, outlier rejection),
  cross-validates it and projects points (central or dual-lens camera model);
* :mod:`studio.calibrate.lens` cross-validates both camera models and keeps the dual-lens one when it pays
  off;
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
from studio.calibrate.lens import LensChoice, choose_lens_model

__all__ = [
    "CalibrationError",
    "CrossValidation",
    "ExtrinsicsFit",
    "LensChoice",
    "choose_lens_model",
    "cross_validate",
    "fit_extrinsics",
    "project_points",
]
