"""Put ground-truth and predicted frames side by side.

* Both files have a ``stamp_ns`` on every frame → frames are matched by stamp: equal stamps first, then
  each remaining ground-truth frame takes the nearest unused predicted frame within ``stamp_tolerance_ns``
  (default 10 ms: well under half the frame period of a 30 Hz camera or a 40 Hz laser), closest pairs first.
  A ground-truth frame still without one, but between two predicted frames close enough in time (at most
  ``interpolate_gap_ns`` apart: by default 2.5 predicted frame periods, so one dropped frame is bridged),
  is compared with the predictions *interpolated* to its stamp (:func:`interpolate_frame`): ground truth
  annotated on another sensor's stamps, or on a scanner the labels were not made from, is measured as
  well as ground truth on the labels' own stamps.
* Otherwise → frames are matched by frame index.

A ground-truth frame with no predicted frame is still evaluated (all its people are misses); a predicted
frame with no ground-truth frame is ignored (a ground-truth file may cover only the reviewed frames).
If no frame is shared at all, :class:`FrameAlignmentError` is raised.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from studio.evaluate.errors import FrameAlignmentError
from studio.geometry.se import Pose2, wrap_angle
from studio.labels.base import LabelFrame, LabelPerson, LabelSet

__all__ = ["DEFAULT_STAMP_TOLERANCE_NS", "Alignment", "align_frames", "interpolate_frame"]

DEFAULT_STAMP_TOLERANCE_NS = 10_000_000
_GAP_PERIODS = 2.5  # the default largest span of two predicted frames interpolated between, in frame periods


@dataclass(frozen=True)
class Alignment:
    """Ground-truth frames in time order with the predicted frame of each (None when missing).

    Attributes:
        pairs: ``(gt_frame, pred_frame | None)`` in evaluation order.
        mode: ``"stamp"`` or ``"index"``.
        num_matched: ground-truth frames that have a predicted frame (interpolated ones included).
        num_pred_unmatched: predicted frames left out (no ground truth for them, directly or as one of the
            two frames an interpolated frame was made from).
        num_interpolated: ground-truth frames compared with predictions interpolated to their stamp (their
            predicted frame carries the index of the nearer of the two it was made from).
    """

    pairs: tuple[tuple[LabelFrame, LabelFrame | None], ...]
    mode: str
    num_matched: int
    num_pred_unmatched: int
    num_interpolated: int = 0


def _by_stamp(
    gt: LabelSet, pred: LabelSet, tol: int, gap: int | None
) -> tuple[list[LabelFrame | None], int, int]:
    """The predicted frame of each ground-truth frame (in stamp order), how many were interpolated, and how
    many predicted frames were used."""
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
    # then between two predicted frames
    if gap is None:
        gap = int(_GAP_PERIODS * float(np.median(np.diff(pstamps)))) if len(pstamps) > 1 else 0
    made = 0
    for i, f in enumerate(gts):
        if out[i] is not None:
            continue
        s = int(f.stamp_ns)  # type: ignore[arg-type]
        k = int(np.searchsorted(pstamps, s, side="left"))
        if not 0 < k < len(pframes) or pstamps[k] == s or int(pstamps[k] - pstamps[k - 1]) > gap:
            continue  # (a stamp equal to a predicted frame's that another ground-truth frame took: none)
        out[i] = interpolate_frame(pframes[k - 1], pframes[k], s)
        used[k - 1] = used[k] = True
        made += 1
    return out, made, int(used.sum())


def _between(a: float | None, b: float | None, w: float) -> float | None:
    return None if a is None or b is None else a + w * (b - a)


def _pose_between(a: Pose2, b: Pose2, w: float) -> Pose2:
    return Pose2(
        a.x + w * (b.x - a.x), a.y + w * (b.y - a.y), float(wrap_angle(a.yaw + w * wrap_angle(b.yaw - a.yaw)))
    )


def interpolate_frame(a: LabelFrame, b: LabelFrame, stamp_ns: int) -> LabelFrame:
    """The labels of two frames interpolated linearly to a stamp between theirs.

    A person in both frames is placed between their two positions; a person in one frame only is kept when
    that frame is the nearer in time (a track that begins or ends between them), where they were. When both
    frames have a robot pose and a person has odom-frame positions, the person is placed in the odom frame
    and brought into the base frame by the robot pose interpolated as well: someone standing still stays
    where they stand while the robot turns (in the base frame, a robot turning at 1 rad/s moves someone
    5 m away by 0.25 m in 50 ms); otherwise the base-frame positions are interpolated.

    The frame keeps the index, and each person the covariance, source, score and extra keys, of the nearer
    frame; boxes are left out (they belong to an image's time).
    """
    ta, tb = int(a.stamp_ns), int(b.stamp_ns)  # type: ignore[arg-type]
    w = 0.0 if tb == ta else min(max((stamp_ns - ta) / (tb - ta), 0.0), 1.0)
    near, far = (a, b) if w <= 0.5 else (b, a)
    pose = None
    if a.robot_pose is not None and b.robot_pose is not None:
        pose = _pose_between(a.robot_pose, b.robot_pose, w)
    others = {p.id: p for p in far.people}
    people = []
    for p in near.people:
        q = others.get(p.id)
        pa, pb = (p, q) if near is a else (q, p)
        if pa is not None and pb is not None:
            xo, yo = _between(pa.x_odom, pb.x_odom, w), _between(pa.y_odom, pb.y_odom, w)
            x, y = pa.x + w * (pb.x - pa.x), pa.y + w * (pb.y - pa.y)
        else:
            xo, yo, x, y = p.x_odom, p.y_odom, p.x, p.y
        if pose is not None and xo is not None and yo is not None:
            x, y = (float(v) for v in pose.inverse().apply(np.array([xo, yo])))
        people.append(LabelPerson(p.id, x, y, xo, yo, p.cov, p.source, None, p.score, p.extra))
    return LabelFrame(near.frame, tuple(people), stamp_ns, pose if pose is not None else near.robot_pose)


def align_frames(
    pred: LabelSet,
    gt: LabelSet,
    *,
    stamp_tolerance_ns: int = DEFAULT_STAMP_TOLERANCE_NS,
    interpolate_gap_ns: int | None = None,
) -> Alignment:
    """Align predicted frames with ground-truth frames (see the module doc for the rules).

    Args:
        pred: predicted labels.
        gt: ground truth.
        stamp_tolerance_ns: largest stamp difference for a non-exact match, ns (0: exact stamps only, then
            interpolation).
        interpolate_gap_ns: largest span of two predicted frames that a ground-truth frame between them is
            interpolated from, ns (None: 2.5 times the median spacing of the predicted stamps; 0: never).

    Raises:
        FrameAlignmentError: the ground truth has no frame, or no ground-truth frame has a prediction.
    """
    if stamp_tolerance_ns < 0 or (interpolate_gap_ns is not None and interpolate_gap_ns < 0):
        raise ValueError("stamp_tolerance_ns and interpolate_gap_ns must be >= 0")
    gname = gt.meta.get("path", "ground truth")
    pname = pred.meta.get("path", "predictions")
    if not gt.frames:
        raise FrameAlignmentError(f"{gname}: no frames to evaluate")
    if gt.has_stamps() and pred.has_stamps():
        mode = "stamp"
        gts = sorted(gt.frames, key=lambda f: (f.stamp_ns, f.frame))
        preds, made, used = _by_stamp(gt, pred, int(stamp_tolerance_ns), interpolate_gap_ns)
    else:
        mode = "index"
        gts = list(gt.frames)
        by_index = pred.by_frame()
        preds = [by_index.get(f.frame) for f in gts]
        made, used = 0, sum(p is not None for p in preds)
    matched = sum(p is not None for p in preds)
    if matched == 0:
        how = (
            f"no frame stamp within {stamp_tolerance_ns / 1e6:g} ms, none between two predicted frames"
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
        num_pred_unmatched=len(pred.frames) - used,
        num_interpolated=made,
    )


def _span(ls: LabelSet, mode: str) -> str:
    if not ls.frames:
        return "none"
    if mode == "stamp":
        s = sorted(int(f.stamp_ns) for f in ls.frames)  # type: ignore[arg-type]
        return f"stamps {s[0]}..{s[-1]} ns"
    return f"{ls.frames[0].frame}..{ls.frames[-1].frame}"
