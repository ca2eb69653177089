"""Distance matrices and one-to-one assignment shared by every metric.

Conventions (docs/evaluation.md):

* distances are Euclidean, metres, between ``(x, y)`` positions in the base frame;
* a pair can match when ``d² <= radius²`` (a distance exactly equal to the radius matches);
* an assignment first maximises the number of matched pairs, then minimises the sum of their distances
  (the same semantics as ``motmetrics`` with its scipy solver, so that both give identical matchings).
"""

from __future__ import annotations

import numpy as np
from scipy.optimize import linear_sum_assignment

__all__ = ["assign", "distance_matrix"]


def distance_matrix(gt_xy: np.ndarray, pred_xy: np.ndarray, *, radius: float) -> np.ndarray:
    """Euclidean distances between ground truth and predictions, NaN where a pair cannot match.

    Args:
        gt_xy: ground-truth positions, shape (N, 2), metres.
        pred_xy: predicted positions, shape (M, 2), metres.
        radius: match radius, metres; pairs with ``d² > radius²`` get NaN.

    Returns:
        Distances, shape (N, M), metres (NaN beyond the radius).
    """
    a = np.asarray(gt_xy, dtype=np.float64).reshape(-1, 2)
    b = np.asarray(pred_xy, dtype=np.float64).reshape(-1, 2)
    if a.shape[0] == 0 or b.shape[0] == 0:
        return np.zeros((a.shape[0], b.shape[0]))
    d2 = np.sum((a[:, None, :] - b[None, :, :]) ** 2, axis=-1)
    d2[d2 > radius**2] = np.nan
    return np.sqrt(d2)


def assign(cost: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """One-to-one assignment on a cost matrix whose NaN / inf entries are forbidden pairs.

    The result has the largest possible number of pairs and, among those, the smallest total cost:
    forbidden entries are replaced by a constant larger than any sum of allowed costs before calling
    :func:`scipy.optimize.linear_sum_assignment`, and pairs on forbidden entries are dropped afterwards.

    Args:
        cost: shape (N, M); NaN or inf marks a pair that must not be matched.

    Returns:
        ``(rows, cols)``: int arrays of equal length K <= min(N, M), the matched pairs.
    """
    c = np.asarray(cost, dtype=np.float64)
    empty = np.zeros(0, dtype=np.int64)
    if c.size == 0:
        return empty, empty
    valid = np.isfinite(c)
    if not valid.any():
        return empty, empty
    if valid.all():
        filled = c
    else:
        r = min(c.shape)
        big = np.abs(c[valid]).max() + 1.0
        filled = np.where(valid, c, 2.0 * r * big + 1.0)
    rows, cols = linear_sum_assignment(filled)
    keep = valid[rows, cols]
    return rows[keep].astype(np.int64), cols[keep].astype(np.int64)
