"""Errors of :mod:`studio.geometry`."""

from __future__ import annotations

from studio.errors import StudioError

__all__ = ["GeometryError"]


class GeometryError(StudioError):
    """Bad geometric input: an image of the wrong shape, an invalid view or camera description."""
