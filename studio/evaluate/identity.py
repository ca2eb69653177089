"""Identity metrics IDF1, IDP, IDR (Ristani et al. 2016) with a global min-cost identity matching.

Each ground-truth identity is paired with at most one predicted identity for the whole sequence, so as to
maximise IDTP, the number of frames in which paired identities are both present and within the radius.
IDFN = ground-truth appearances − IDTP, IDFP = predicted appearances − IDTP,
IDP = IDTP / (IDTP + IDFP), IDR = IDTP / (IDTP + IDFN), IDF1 = 2 IDTP / (num_gt + num_pred).
"""

from __future__ import annotations

from collections import Counter
from collections.abc import Hashable
from dataclasses import dataclass

import numpy as np
from scipy.optimize import linear_sum_assignment

from studio.evaluate.base import MetricResult, frame_arrays, safe_div
from studio.evaluate.matching import distance_matrix
from studio.labels.base import LabelFrame

__all__ = ["Identity", "IdentityResult"]

Key = tuple[Hashable, int]


@dataclass(frozen=True)
class IdentityResult(MetricResult):
    """IDF1 and its parts (NaN where undefined).

    Attributes:
        idf1, idp, idr: ratios in [0, 1].
        idtp, idfp, idfn: counts of appearances.
        pairs: the identity pairing ``((gt_id, pred_id), ...)`` (for a single sequence; ids of every
            sequence otherwise, without the sequence name).
    """

    idf1: float
    idp: float
    idr: float
    idtp: int
    idfp: int
    idfn: int
    pairs: tuple[tuple[int, int], ...]


class Identity:
    """IDF1 / IDP / IDR accumulated frame by frame."""

    def __init__(self, *, radius: float = 0.2) -> None:
        if not radius > 0:
            raise ValueError(f"radius must be positive, got {radius}")
        self.radius = float(radius)
        self.reset()

    def reset(self) -> None:
        self._gt: Counter[Key] = Counter()
        self._pred: Counter[Key] = Counter()
        self._co: Counter[tuple[Key, Key]] = Counter()

    def update(self, gt: LabelFrame, pred: LabelFrame | None, *, sequence: Hashable = 0) -> None:
        gid, gxy = frame_arrays(gt)
        pid, pxy = frame_arrays(pred)
        okeys = [(sequence, int(i)) for i in gid]
        hkeys = [(sequence, int(i)) for i in pid]
        self._gt.update(okeys)
        self._pred.update(hkeys)
        d = distance_matrix(gxy, pxy, radius=self.radius)
        for i, j in zip(*np.nonzero(np.isfinite(d)), strict=True):
            self._co[(okeys[i], hkeys[j])] += 1

    def compute(self) -> IdentityResult:
        num_gt = sum(self._gt.values())
        num_pred = sum(self._pred.values())
        pairs: list[tuple[int, int]] = []
        idtp = 0
        if self._co:
            orow = {k: r for r, k in enumerate(sorted({o for o, _ in self._co}, key=repr))}
            hcol = {k: c for c, k in enumerate(sorted({h for _, h in self._co}, key=repr))}
            w = np.zeros((len(orow), len(hcol)))
            for (o, h), n in self._co.items():
                w[orow[o], hcol[h]] = n
            rows, cols = linear_sum_assignment(w, maximize=True)
            okeys = list(orow)
            hkeys = list(hcol)
            for r, c in zip(rows.tolist(), cols.tolist(), strict=True):
                if w[r, c] > 0:
                    idtp += int(w[r, c])
                    pairs.append((okeys[r][1], hkeys[c][1]))
        idfn, idfp = num_gt - idtp, num_pred - idtp
        return IdentityResult(
            idf1=safe_div(2 * idtp, num_gt + num_pred),
            idp=safe_div(idtp, idtp + idfp),
            idr=safe_div(idtp, idtp + idfn),
            idtp=idtp,
            idfp=idfp,
            idfn=idfn,
            pairs=tuple(sorted(pairs)),
        )
