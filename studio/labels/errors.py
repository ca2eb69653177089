"""Errors of label and ground-truth files."""

from __future__ import annotations

from studio.errors import StudioError

__all__ = ["LabelError"]


class LabelError(StudioError):
    """A label / ground-truth file is missing, malformed or inconsistent."""
