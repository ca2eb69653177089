"""Errors of the annotation store."""

from __future__ import annotations

from studio.errors import StudioError

__all__ = ["AnnotationError", "ConflictError"]


class AnnotationError(StudioError):
    """An invalid operation or bad input (the message says what and why); the state is untouched."""


class ConflictError(AnnotationError):
    """An operation based on a stale revision of a frame it touches (someone else changed it since).

    Attributes:
        frame: the first such frame number. frame_rev: the revision that last changed it.
    """

    def __init__(self, message: str, *, frame: int | None = None, frame_rev: int | None = None) -> None:
        super().__init__(message)
        self.frame = frame
        self.frame_rev = frame_rev
