"""Errors of the laser people detectors."""

from __future__ import annotations

from studio.errors import StudioError

__all__ = ["LaserDetectorError"]


class LaserDetectorError(StudioError):
    """An unknown laser detector name, or a scan / option the detector cannot use."""
