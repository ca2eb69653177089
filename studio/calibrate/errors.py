"""Errors of :mod:`studio.calibrate` (the base of every calibration refusal)."""

from __future__ import annotations

from studio.errors import StudioError

__all__ = ["CalibrationError"]


class CalibrationError(StudioError):
    """Calibration input that cannot give a pose; the message names the problem and the rows."""
