"""Errors of :mod:`studio.io`: each is a user-input problem reported as one line (exit status 2)."""

from __future__ import annotations

from studio.errors import StudioError

__all__ = ["RecordingError", "RigError", "TfError"]


class RecordingError(StudioError):
    """A recording is missing, unreadable, truncated, or lacks a topic the rig names."""


class RigError(StudioError):
    """A rig.yaml file is missing or invalid (the message names the file and the key)."""


class TfError(StudioError):
    """A transform cannot be looked up (the message names the missing frame and lists the known ones)."""
