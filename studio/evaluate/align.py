"""Put ground-truth and predicted frames side by side.

* Both files have a ``stamp_ns`` on every frame → frames are matched by stamp: equal stamps first, then
  each remaining ground-truth frame takes the nearest unused predicted frame within ``stamp_tolerance_ns``
  (default 10 ms: well under half the frame period of a 30 Hz camera or a 40 Hz laser), closest pairs first.
* Otherwise → frames are matched by frame index.

A ground-truth frame with no predicted frame is still evaluated (all its people are misses); a predicted
frame with no ground-truth frame is ignored (a ground-truth file may cover only the reviewed frames).
If no frame is shared at all, :class:`FrameAlignmentError` is raised.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from studio.evaluate.errors import FrameAlignmentError
from studio.labels.base import LabelFrame, LabelSet

__all__ = ["DEFAULT_STAMP_TOLERANCE_NS", "Alignment", "align_frames"]

DEFAULT_STAMP_TOLERANCE_NS = 10_000_000


@dataclass(frozen=True)
class Alignment:
    """Ground-truth frames in time order with the predicted frame of each (None when missing).

    Attributes:
        pairs: ``(gt_frame, pred_frame | None)`` in evaluation order.
        mode: ``"stamp"`` or ``"index"``.
        num_matched: ground-truth frames that have a predicted frame.
        num_pred_unmatched: predicted frames left out (no ground truth for them).
    """

    pairs: tuple[tuple[LabelFrame, LabelFrame | None], ...]
    mode: str
    num_matched: int
    num_pred_unmatched: int


def _by_stamp(gt: LabelSet, pred: LabelSet, tol: int) -> list[LabelFrame | None]:
    gts = sorted(gt.frames, key=lambda f: (f.stamp_ns, f.frame))
    pframes = sorted(pred.frames, key=lambda f: (f.stamp_ns, f.frame))
    pstamps = np.array([f.stamp_ns for f in pframes], dtype=np.int64)
    out: list[LabelFrame | None] = [None] * len(gts)
    used = np.zeros(len(pframes), dtype=bool)
    exact: dict[int, int] = {}
    for j, s in enumerate(pstamps.tolist()):
        exact.setdefault(s, j)
    # exact stamps first
    for i, f in enumerate(gts):
        twin = exact.get(int(f.stamp_ns))  # type: ignore[arg-type]
        if twin is not None and not used[twin]:
            out[i], used[twin] = pframes[twin], True
    # then nearest within the tolerance, closest pairs first
    cands: list[tuple[int, int, int]] = []
    if tol > 0 and len(pframes):
        for i, f in enumerate(gts):
            if out[i] is not None:
                continue
            s = int(f.stamp_ns)  # type: ignore[arg-type]
            lo = int(np.searchsorted(pstamps, s - tol, side="left"))
            hi = int(np.searchsorted(pstamps, s + tol, side="right"))
            cands.extend((abs(int(pstamps[j]) - s), i, j) for j in range(lo, hi) if not used[j])
    for _, i, j in sorted(cands):
        if out[i] is None and not used[j]:
            out[i], used[j] = pframes[j], True
    return out


def align_frames(
    pred: LabelSet, gt: LabelSet, *, stamp_tolerance_ns: int = DEFAULT_STAMP_TOLERANCE_NS
) -> Alignment:
    """Align predicted frames with ground-truth frames (see the module doc for the rules).

    Args:
        pred: predicted labels.
        gt: ground truth.
        stamp_tolerance_ns: largest stamp difference for a non-exact match, ns (0: exact stamps only).

    Raises:
        FrameAlignmentError: the ground truth has no frame, or no ground-truth frame has a prediction.
    """
    if stamp_tolerance_ns < 0:
        raise ValueError("stamp_tolerance_ns must be >= 0")
    gname = gt.meta.get("path", "ground truth")
    pname = pred.meta.get("path", "predictions")
    if not gt.frames:
        raise FrameAlignmentError(f"{gname}: no frames to evaluate")
    if gt.has_stamps() and pred.has_stamps():
        mode = "stamp"
        gts = sorted(gt.frames, key=lambda f: (f.stamp_ns, f.frame))
        preds = _by_stamp(gt, pred, int(stamp_tolerance_ns))
    else:
        mode = "index"
        gts = list(gt.frames)
        by_index = pred.by_frame()
        preds = [by_index.get(f.frame) for f in gts]
    matched = sum(p is not None for p in preds)
    if matched == 0:
        how = (
            f"no frame stamp within {stamp_tolerance_ns / 1e6:g} ms"
            if mode == "stamp"
            else "no frame index in common"
        )
        raise FrameAlignmentError(
            f"{pname} and {gname} share no frame ({how}; ground truth frames "
            f"{_span(gt, mode)}, predictions {_span(pred, mode)})"
        )
    return Alignment(
        pairs=tuple(zip(gts, preds, strict=True)),
        mode=mode,
        num_matched=matched,
        num_pred_unmatched=len(pred.frames) - matched,
    )


def _span(ls: LabelSet, mode: str) -> str:
    if not ls.frames:
        return "none"
    if mode == "stamp":
        s = sorted(int(f.stamp_ns) for f in ls.frames)  # type: ignore[arg-type]
        return f"stamps {s[0]}..{s[-1]} ns"
    return f"{ls.frames[0].frame}..{ls.frames[-1].frame}"
