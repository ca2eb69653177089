"""Fusion of image boxes and laser people into positions with covariance and provenance."""

from studio.fuse.base import HOW, SOURCES, FusionConfig, PersonObservations, ScanRays
from studio.fuse.fusion import BoxRange, box_ranges, colours_hidden, fuse_frame, points_columns

__all__ = [
    "HOW",
    "SOURCES",
    "BoxRange",
    "FusionConfig",
    "PersonObservations",
    "ScanRays",
    "box_ranges",
    "colours_hidden",
    "fuse_frame",
    "points_columns",
]
