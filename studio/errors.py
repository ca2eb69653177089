"""Errors shared by every part of studio.

A :class:`StudioError` is a problem with the user's input (a bag, a rig file, a label file, an option):
the command line prints its message on one line and exits with status 2, never a traceback.
Each subpackage derives its own errors from it in its ``errors.py``.
"""

from __future__ import annotations

__all__ = ["MissingExtraError", "StudioError"]


class StudioError(Exception):
    """An error in the user's input, reported as one readable line (exit status 2)."""


class MissingExtraError(StudioError):
    """An optional backend is not installed; the message names the extra or package to install."""

    def __init__(self, what: str, package: str) -> None:
        super().__init__(f"{what} needs the optional package '{package}' (pip install {package})")
        self.package = package
