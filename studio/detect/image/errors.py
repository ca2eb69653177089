"""Errors of the image people detectors."""

from __future__ import annotations

from studio.errors import StudioError

__all__ = ["ImageDetectorError"]


class ImageDetectorError(StudioError):
    """An unknown detector name, a model file the detector cannot use, or an image it cannot read."""
