"""Contracts of the evaluator: the metric protocol, its printable results, and frame inputs.

A metric follows the supervision pattern (DESIGN.md §4.9)::

    metric = ClearMOT(radius=0.2)
    for gt_frame, pred_frame in pairs:
        metric.update(gt_frame, pred_frame)
    result = metric.compute()   # a frozen dataclass; print(result) shows a small table

``update`` takes :class:`studio.labels.LabelFrame` objects (``pred`` may be None: a ground-truth frame
with no prediction, all its people are misses). Several sequences go through one metric with the keyword
``sequence``: identities are then namespaced per sequence, which gives the same numbers as evaluating each
sequence alone and summing the counts (motmetrics' ``compute_overall``, TrackEval's ``combine_sequences``).
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Hashable
from typing import Any, Protocol, TypeVar

import numpy as np

from studio.labels.base import LabelFrame

__all__ = ["Metric", "MetricResult", "frame_arrays", "safe_div"]

R_co = TypeVar("R_co", covariant=True)


class Metric(Protocol[R_co]):
    """A metric accumulated frame by frame."""

    def update(self, gt: LabelFrame, pred: LabelFrame | None, *, sequence: Hashable = 0) -> object:
        """Add one ground-truth frame and the prediction aligned with it (None: no prediction).

        May return the frame's own events (e.g. :class:`~studio.evaluate.detection.FrameMatch`).
        """

    def reset(self) -> None:
        """Forget everything accumulated."""

    def compute(self) -> R_co:
        """The metric's result over everything accumulated so far."""


def safe_div(num: float, den: float) -> float:
    """``num / den``, NaN when ``den`` is 0 (an undefined ratio, ``null`` in JSON)."""
    return float(num) / float(den) if den else math.nan


def _fmt(v: Any) -> str:
    if isinstance(v, bool):
        return str(v)
    if isinstance(v, int | np.integer):
        return str(int(v))
    if isinstance(v, float | np.floating):
        return "n/a" if math.isnan(v) else f"{float(v):.4f}"
    if isinstance(v, np.ndarray):
        return f"array{tuple(v.shape)}"
    return str(v)


class MetricResult:
    """Mixin for frozen result dataclasses: ``as_dict()`` of plain numbers and a readable ``str()``."""

    def as_dict(self) -> dict[str, Any]:
        """Fields as plain Python values (arrays become lists, NaN stays NaN)."""
        out: dict[str, Any] = {}
        for f in dataclasses.fields(self):  # type: ignore[arg-type]
            v = getattr(self, f.name)
            if isinstance(v, np.ndarray):
                v = v.tolist()
            elif isinstance(v, np.integer):
                v = int(v)
            elif isinstance(v, np.floating):
                v = float(v)
            out[f.name] = v
        return out

    def __str__(self) -> str:
        items = [
            (f.name, getattr(self, f.name))
            for f in dataclasses.fields(self)  # type: ignore[arg-type]
            if not isinstance(getattr(self, f.name), np.ndarray | tuple | list | dict)
        ]
        width = max((len(k) for k, _ in items), default=0)
        lines = [type(self).__name__]
        lines += [f"  {k:<{width}}  {_fmt(v)}" for k, v in items]
        return "\n".join(lines)


def frame_arrays(frame: LabelFrame | None) -> tuple[np.ndarray, np.ndarray]:
    """Identities (N,) int64 and positions (N, 2) float64 metres of a frame (empty when None)."""
    if frame is None or not frame.people:
        return np.zeros(0, dtype=np.int64), np.zeros((0, 2))
    return frame.ids(), frame.xy()
