"""Errors of :mod:`studio.sim` (user-input problems, shown as one line, exit status 2)."""

from __future__ import annotations

from studio.errors import StudioError

__all__ = ["SimError"]


class SimError(StudioError):
    """An unknown scenario, a bad duration or an output directory that cannot be written."""
