"""Panoramic People Studio: people's world positions from 360° camera + 2D laser robot recordings."""

from __future__ import annotations

__version__ = "0.1.0"
__all__ = ["__version__"]
