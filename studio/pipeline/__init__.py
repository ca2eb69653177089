"""The labeling pipeline: recording + rig → per-frame people with identities (no rerun, torch or web here)."""

from studio.pipeline.base import METHODS, SOURCES_OPTIONS, FrameResult, LabelOptions
from studio.pipeline.label import LabelRun, label_recording, observations_to_frames

__all__ = [
    "METHODS",
    "SOURCES_OPTIONS",
    "FrameResult",
    "LabelOptions",
    "LabelRun",
    "label_recording",
    "observations_to_frames",
]
