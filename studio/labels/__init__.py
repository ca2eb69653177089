"""Label and ground-truth files: the thesis YAML format and JSON lines (DESIGN.md §2)."""

from studio.labels.base import SOURCES, LabelFrame, LabelPerson, LabelSet
from studio.labels.errors import LabelError
from studio.labels.formats import (
    dumps_jsonl,
    dumps_yaml,
    frame_from_json,
    frame_to_json,
    read_labels,
    read_labels_jsonl,
    read_labels_yaml,
    write_labels,
    write_labels_jsonl,
    write_labels_yaml,
)
from studio.labels.review import (
    REVIEW_KINDS,
    ReviewConfig,
    ReviewPoint,
    read_review,
    review_jsonl,
    review_points,
    write_review,
)

__all__ = [
    "REVIEW_KINDS",
    "SOURCES",
    "LabelError",
    "LabelFrame",
    "LabelPerson",
    "LabelSet",
    "ReviewConfig",
    "ReviewPoint",
    "dumps_jsonl",
    "dumps_yaml",
    "frame_from_json",
    "frame_to_json",
    "read_labels",
    "read_labels_jsonl",
    "read_labels_yaml",
    "read_review",
    "review_jsonl",
    "review_points",
    "write_labels",
    "write_labels_jsonl",
    "write_labels_yaml",
    "write_review",
]
