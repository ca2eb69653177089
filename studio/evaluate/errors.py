"""Errors of the evaluator."""

from __future__ import annotations

from studio.labels.errors import LabelError

__all__ = ["FrameAlignmentError"]


class FrameAlignmentError(LabelError):
    """Predictions and ground truth cannot be put side by side (no shared frame, empty ground truth)."""
