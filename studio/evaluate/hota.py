"""HOTA (Luiten et al. 2021) for positions, with the conventions of TrackEval's reference implementation.

Similarity of a ground-truth / predicted pair at distance ``d`` (metres): ``S = max(0, 1 − d / radius)``.
For each threshold α in 0.05, 0.10, …, 0.95:

* per frame, pairs are chosen once by a Hungarian assignment that maximises ``A(o, h) · S`` where
  ``A`` is the global alignment of the two identities over the sequence; a chosen pair is a true positive
  at α when ``S ≥ α`` (so a pair at ``d ≥ radius`` never is, and α = 0.05 means ``d ≤ 0.95 radius``);
* DetA = TP / (TP + FN + FP); AssA = mean over TPs of TPA / (TPA + FNA + FPA) of the TP's identity pair;
  LocA = mean similarity of the TPs; HOTA = √(DetA · AssA).

Reported values are means over the 19 thresholds. Edge cases follow TrackEval: a ratio with an empty
denominator counts it as 1 (so DetA = AssA = 0 without TP), and LocA is 1 without TP.
"""

from __future__ import annotations

from collections import Counter, defaultdict
from collections.abc import Hashable
from dataclasses import dataclass

import numpy as np
from scipy.optimize import linear_sum_assignment

from studio.evaluate.base import MetricResult, frame_arrays
from studio.labels.base import LabelFrame

__all__ = ["ALPHAS", "HOTA", "HOTAResult", "similarity_matrix"]

ALPHAS = np.arange(0.05, 0.99, 0.05)  # the 19 thresholds 0.05 … 0.95 (same floats as TrackEval)
_EPS = float(np.finfo(float).eps)

Key = tuple[Hashable, int]


def similarity_matrix(gt_xy: np.ndarray, pred_xy: np.ndarray, *, radius: float) -> np.ndarray:
    """``max(0, 1 − d / radius)`` for every pair, shape (N, M); ``d`` Euclidean in metres."""
    a = np.asarray(gt_xy, dtype=np.float64).reshape(-1, 2)
    b = np.asarray(pred_xy, dtype=np.float64).reshape(-1, 2)
    d = np.sqrt(np.sum((a[:, None, :] - b[None, :, :]) ** 2, axis=-1))
    return np.maximum(0.0, 1.0 - d / radius)


@dataclass(frozen=True)
class HOTAResult(MetricResult):
    """HOTA and its parts, each the mean over the α thresholds (``*_alpha``: per threshold, shape (19,)).

    Attributes:
        hota, deta, assa, loca: higher is better, in [0, 1].
        detre, detpr, assre, asspr: detection / association recall and precision.
        alphas: the thresholds, shape (19,).
    """

    hota: float
    deta: float
    assa: float
    loca: float
    detre: float
    detpr: float
    assre: float
    asspr: float
    alphas: np.ndarray
    hota_alpha: np.ndarray
    deta_alpha: np.ndarray
    assa_alpha: np.ndarray
    loca_alpha: np.ndarray


class HOTA:
    """HOTA accumulated frame by frame; the work happens in :meth:`compute` (it needs whole tracks)."""

    def __init__(self, *, radius: float = 0.2) -> None:
        if not radius > 0:
            raise ValueError(f"radius must be positive, got {radius}")
        self.radius = float(radius)
        self.reset()

    def reset(self) -> None:
        self._frames: list[tuple[list[Key], list[Key], np.ndarray]] = []
        self._gt_count: Counter[Key] = Counter()
        self._pred_count: Counter[Key] = Counter()
        self._potential: defaultdict[tuple[Key, Key], float] = defaultdict(float)

    def update(self, gt: LabelFrame, pred: LabelFrame | None, *, sequence: Hashable = 0) -> None:
        gid, gxy = frame_arrays(gt)
        pid, pxy = frame_arrays(pred)
        okeys = [(sequence, int(i)) for i in gid]
        hkeys = [(sequence, int(i)) for i in pid]
        sim = similarity_matrix(gxy, pxy, radius=self.radius)
        self._frames.append((okeys, hkeys, sim))
        self._gt_count.update(okeys)
        self._pred_count.update(hkeys)
        if sim.size:
            # similarity normalised like an IoU between the two identities' soft matches in this frame
            denom = sim.sum(0)[None, :] + sim.sum(1)[:, None] - sim
            ok = denom > _EPS
            soft = np.zeros_like(sim)
            soft[ok] = sim[ok] / denom[ok]
            for i, j in zip(*np.nonzero(soft), strict=True):
                self._potential[(okeys[i], hkeys[j])] += float(soft[i, j])

    def compute(self) -> HOTAResult:
        n_alpha = len(ALPHAS)
        num_gt = sum(self._gt_count.values())
        num_pred = sum(self._pred_count.values())
        oidx = {k: i for i, k in enumerate(self._gt_count)}
        hidx = {k: j for j, k in enumerate(self._pred_count)}
        gt_count = np.array([self._gt_count[k] for k in oidx], dtype=float)
        pred_count = np.array([self._pred_count[k] for k in hidx], dtype=float)
        align = np.zeros((len(oidx), len(hidx)))
        for (o, h), v in self._potential.items():
            i, j = oidx[o], hidx[h]
            align[i, j] = v / (gt_count[i] + pred_count[j] - v)
        mo: list[np.ndarray] = []
        mh: list[np.ndarray] = []
        ms: list[np.ndarray] = []
        for okeys, hkeys, sim in self._frames:
            if not okeys or not hkeys:
                continue
            oi = np.array([oidx[k] for k in okeys])
            hj = np.array([hidx[k] for k in hkeys])
            score = align[np.ix_(oi, hj)] * sim
            rows, cols = linear_sum_assignment(score, maximize=True)
            mo.append(oi[rows])
            mh.append(hj[cols])
            ms.append(sim[rows, cols])
        o_all = np.concatenate(mo) if mo else np.zeros(0, dtype=int)
        h_all = np.concatenate(mh) if mh else np.zeros(0, dtype=int)
        s_all = np.concatenate(ms) if ms else np.zeros(0)
        tp = np.zeros(n_alpha)
        loc = np.zeros(n_alpha)
        assa, assre, asspr = np.zeros(n_alpha), np.zeros(n_alpha), np.zeros(n_alpha)
        for a, alpha in enumerate(ALPHAS):
            keep = s_all >= alpha - _EPS
            tp[a] = keep.sum()
            loc[a] = s_all[keep].sum()
            if not keep.any():
                continue
            pairs, counts = np.unique(
                np.stack([o_all[keep], h_all[keep]], axis=1), axis=0, return_counts=True
            )
            c = counts.astype(float)
            go, ph = gt_count[pairs[:, 0]], pred_count[pairs[:, 1]]
            assa[a] = np.sum(c * c / np.maximum(1.0, go + ph - c)) / max(1.0, tp[a])
            assre[a] = np.sum(c * c / np.maximum(1.0, go)) / max(1.0, tp[a])
            asspr[a] = np.sum(c * c / np.maximum(1.0, ph)) / max(1.0, tp[a])
        fn = num_gt - tp
        fp = num_pred - tp
        deta = tp / np.maximum(1.0, tp + fn + fp)
        detre = tp / np.maximum(1.0, tp + fn)
        detpr = tp / np.maximum(1.0, tp + fp)
        loca = np.maximum(1e-10, loc) / np.maximum(1e-10, tp)
        hota = np.sqrt(deta * assa)
        return HOTAResult(
            hota=float(hota.mean()),
            deta=float(deta.mean()),
            assa=float(assa.mean()),
            loca=float(loca.mean()),
            detre=float(detre.mean()),
            detpr=float(detpr.mean()),
            assre=float(assre.mean()),
            asspr=float(asspr.mean()),
            alphas=ALPHAS.copy(),
            hota_alpha=hota,
            deta_alpha=deta,
            assa_alpha=assa,
            loca_alpha=loca,
        )
