"""Errors of the tracking stage."""

from __future__ import annotations

from studio.errors import StudioError

__all__ = ["TrackingError"]


class TrackingError(StudioError):
    """Observations handed to a tracker are inconsistent (e.g. time stamps going backwards)."""
