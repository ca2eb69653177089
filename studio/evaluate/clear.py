"""CLEAR MOT (Bernardin & Stiefelhagen 2008) with the exact semantics of ``motmetrics`` 1.4.

Per ground-truth frame:

1. a correspondence (object o ↔ hypothesis h) of an earlier frame is kept when both are present and
   still within the radius (objects in the order of the ground-truth frame);
2. the remaining objects and hypotheses are matched one-to-one (most pairs, then least total distance);
   a pair whose object was last matched to a different hypothesis is an *ID switch*;
3. unmatched objects are misses (FN), unmatched hypotheses false positives (FP).

MOTA = 1 − (FN + FP + IDSW) / (number of ground-truth appearances); MOTP is the mean Euclidean distance
of matched pairs in metres (lower is better); a fragmentation is a run of misses between two frames in
which the object is tracked; an object is mostly tracked (MT) when tracked in ≥ 80 % of its appearances,
mostly lost (ML) below 20 %, partially tracked (PT) otherwise; MT, PT and ML are fractions of the
ground-truth tracks and sum to 1.
"""

from __future__ import annotations

from collections.abc import Hashable
from dataclasses import dataclass, field

import numpy as np

from studio.evaluate.base import MetricResult, frame_arrays, safe_div
from studio.evaluate.matching import assign, distance_matrix
from studio.labels.base import LabelFrame

__all__ = ["ClearFrame", "ClearMOT", "ClearMOTResult"]

Key = tuple[Hashable, int]


@dataclass(frozen=True)
class ClearFrame:
    """CLEAR MOT events of one frame.

    Attributes:
        matches: ``(gt_id, pred_id, distance_m)`` of every matched pair (switches included).
        switches: ground-truth ids whose match changed hypothesis in this frame.
        fn_ids: ground-truth ids missed.
        fp_ids: predicted ids not matched.
    """

    matches: tuple[tuple[int, int, float], ...]
    switches: tuple[int, ...]
    fn_ids: tuple[int, ...]
    fp_ids: tuple[int, ...]


@dataclass(frozen=True)
class ClearMOTResult(MetricResult):
    """CLEAR MOT numbers (NaN where undefined: no ground truth, no match).

    Attributes:
        mota: 1 − (fn + fp + id_switches) / num_gt.
        motp: mean distance of matched pairs, metres.
        tp: matched pairs (including switches), fp, fn: counts.
        id_switches, fragmentations: counts.
        mt, pt, ml: fractions of ground-truth tracks (sum exactly 1; NaN without tracks).
        num_mt, num_pt, num_ml: the same as counts.
        num_gt: ground-truth appearances; num_pred: predicted appearances.
        num_gt_tracks, num_pred_tracks: distinct identities; num_frames: frames evaluated.
    """

    mota: float
    motp: float
    tp: int
    fp: int
    fn: int
    id_switches: int
    fragmentations: int
    mt: float
    pt: float
    ml: float
    num_mt: int
    num_pt: int
    num_ml: int
    num_gt: int
    num_pred: int
    num_gt_tracks: int
    num_pred_tracks: int
    num_frames: int


@dataclass
class _Track:
    appearances: int = 0
    tracked: int = 0
    seen_tracked: bool = False
    pending_miss: bool = False
    fragmentations: int = 0


@dataclass
class _State:
    corr: dict[Key, Key] = field(default_factory=dict)  # object → hypothesis of its last match
    tracks: dict[Key, _Track] = field(default_factory=dict)
    pred_ids: set[Key] = field(default_factory=set)
    tp: int = 0
    fp: int = 0
    fn: int = 0
    switches: int = 0
    dist_sum: float = 0.0
    num_pred: int = 0
    frames: int = 0


class ClearMOT:
    """CLEAR MOT accumulated frame by frame (``motmetrics`` semantics, Euclidean distances in metres)."""

    def __init__(self, *, radius: float = 0.2) -> None:
        if not radius > 0:
            raise ValueError(f"radius must be positive, got {radius}")
        self.radius = float(radius)
        self.reset()

    def reset(self) -> None:
        self._s = _State()

    def update(self, gt: LabelFrame, pred: LabelFrame | None, *, sequence: Hashable = 0) -> ClearFrame:
        """Add one frame; returns its events."""
        s = self._s
        gid, gxy = frame_arrays(gt)
        pid, pxy = frame_arrays(pred)
        okeys: list[Key] = [(sequence, int(i)) for i in gid]
        hkeys: list[Key] = [(sequence, int(i)) for i in pid]
        d = distance_matrix(gxy, pxy, radius=self.radius)
        n, m = d.shape
        o_done = np.zeros(n, dtype=bool)
        h_done = np.zeros(m, dtype=bool)
        matches: list[tuple[int, int, float]] = []
        switches: list[int] = []
        if n and m:
            # 1. keep earlier correspondences still within the radius
            hindex = {k: j for j, k in enumerate(hkeys)}
            for i, o in enumerate(okeys):
                h_prev = s.corr.get(o)
                j = -1 if h_prev is None else hindex.get(h_prev, -1)
                if j < 0 or h_done[j] or not np.isfinite(d[i, j]):
                    continue
                o_done[i] = h_done[j] = True
                matches.append((int(gid[i]), int(pid[j]), float(d[i, j])))
            # 2. match the rest; a changed correspondence is an ID switch
            rest = d.copy()
            rest[o_done, :] = np.nan
            rest[:, h_done] = np.nan
            rows, cols = assign(rest)
            for i, j in zip(rows.tolist(), cols.tolist(), strict=True):
                o, h = okeys[i], hkeys[j]
                if o in s.corr and s.corr[o] != h:
                    switches.append(int(gid[i]))
                s.corr[o] = h
                o_done[i] = h_done[j] = True
                matches.append((int(gid[i]), int(pid[j]), float(d[i, j])))
        # 3./4. misses and false positives; per-track bookkeeping
        for i, o in enumerate(okeys):
            t = s.tracks.setdefault(o, _Track())
            t.appearances += 1
            if o_done[i]:
                t.tracked += 1
                if t.pending_miss:
                    t.fragmentations += 1
                    t.pending_miss = False
                t.seen_tracked = True
            elif t.seen_tracked:
                t.pending_miss = True
        s.pred_ids.update(hkeys)
        s.tp += len(matches)
        s.switches += len(switches)
        s.fn += int(n - o_done.sum())
        s.fp += int(m - h_done.sum())
        s.dist_sum += sum(x[2] for x in matches)
        s.num_pred += m
        s.frames += 1
        return ClearFrame(
            matches=tuple(matches),
            switches=tuple(switches),
            fn_ids=tuple(int(gid[i]) for i in np.flatnonzero(~o_done)),
            fp_ids=tuple(int(pid[j]) for j in np.flatnonzero(~h_done)),
        )

    def compute(self) -> ClearMOTResult:
        s = self._s
        n_tracks = len(s.tracks)
        num_mt = num_pt = num_ml = 0
        for t in s.tracks.values():
            ratio = t.tracked / t.appearances
            if ratio >= 0.8:
                num_mt += 1
            elif ratio >= 0.2:
                num_pt += 1
            else:
                num_ml += 1
        num_gt = sum(t.appearances for t in s.tracks.values())
        if n_tracks:
            mt, pt = num_mt / n_tracks, num_pt / n_tracks
            ml = 1.0 - (mt + pt)  # exactly complements mt + pt (equals num_ml / n_tracks within 1 ulp)
        else:
            mt = pt = ml = float("nan")
        return ClearMOTResult(
            mota=1.0 - safe_div(s.fn + s.fp + s.switches, num_gt),
            motp=safe_div(s.dist_sum, s.tp),
            tp=s.tp,
            fp=s.fp,
            fn=s.fn,
            id_switches=s.switches,
            fragmentations=sum(t.fragmentations for t in s.tracks.values()),
            mt=mt,
            pt=pt,
            ml=ml,
            num_mt=num_mt,
            num_pt=num_pt,
            num_ml=num_ml,
            num_gt=num_gt,
            num_pred=s.num_pred,
            num_gt_tracks=n_tracks,
            num_pred_tracks=len(s.pred_ids),
            num_frames=s.frames,
        )
