"""Ground-truth annotation: auto-labels (or an empty set, or a ground-truth file) + a log of corrections.

:class:`AnnotationStore` holds the ground truth of one run directory; every correction is an operation
appended to ``RUN/annotations/corrections.jsonl`` and the ground truth is materialised as
``RUN/ground_truth.yaml`` / ``RUN/ground_truth.jsonl``. Formats and ops: ``docs/annotation.md``.
"""

from studio.annotate.errors import AnnotationError, ConflictError
from studio.annotate.ops import OPS, normalize_op
from studio.annotate.store import AnnotationStore, OpResult

__all__ = ["OPS", "AnnotationError", "AnnotationStore", "ConflictError", "OpResult", "normalize_op"]
