"""Gating and assignment: Mahalanobis gates, global (Hungarian) and greedy nearest neighbour."""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray
from scipy.optimize import linear_sum_assignment
from scipy.stats import chi2

__all__ = ["chi2_gate", "gnn_assign", "greedy_assign", "mahalanobis_costs"]

FloatArray = NDArray[np.float64]


def chi2_gate(prob: float, dof: int = 2) -> float:
    """The squared Mahalanobis distance that contains ``prob`` of a Gaussian with ``dof`` dimensions."""
    if not 0.0 < prob < 1.0:
        raise ValueError(f"gate probability must be in (0, 1), got {prob}")
    return float(chi2.ppf(prob, dof))


def mahalanobis_costs(
    z_pred: FloatArray, Pz: FloatArray, z: FloatArray, R: FloatArray
) -> tuple[FloatArray, FloatArray]:
    """Squared Mahalanobis distances and log-determinants of the innovation covariances.

    Args:
        z_pred: (T, 2) predicted measurements of T tracks, metres; or (T, N, 2), one per observation (each
            predicted to the time the observation was measured).
        Pz: (T, 2, 2) their covariances without measurement noise, m²; or (T, N, 2, 2).
        z: (N, 2) observations, metres.
        R: (N, 2, 2) observation covariances, m².

    Returns:
        ``d2`` (T, N) and ``logdet`` (T, N) of ``S = Pz[t] + R[n]``; ``d2 + logdet`` is the negative
        log-likelihood of the pair up to a constant.
    """
    T, N = len(z_pred), len(z)
    if T == 0 or N == 0:
        return np.zeros((T, N)), np.zeros((T, N))
    if z_pred.ndim == 2:
        z_pred, Pz = z_pred[:, None, :], Pz[:, None, :, :]
    S = Pz + R[None, :, :, :]  # (T, N, 2, 2)
    y = z[None, :, :] - z_pred  # (T, N, 2)
    a, b, c = S[..., 0, 0], 0.5 * (S[..., 0, 1] + S[..., 1, 0]), S[..., 1, 1]
    det = a * c - b * b
    d2 = (c * y[..., 0] ** 2 - 2.0 * b * y[..., 0] * y[..., 1] + a * y[..., 1] ** 2) / det
    return d2, np.log(det)


def gnn_assign(
    cost: FloatArray, allowed: NDArray[np.bool_], *, miss_cost: float | None = None
) -> list[tuple[int, int]]:
    """Global nearest neighbour: the one-to-one assignment of rows to columns among the allowed pairs.

    Hungarian algorithm (``scipy.optimize.linear_sum_assignment``). Without ``miss_cost`` the assignment
    first maximises the number of allowed pairs, then minimises their total cost. With ``miss_cost`` every
    row and every column left unassigned costs ``miss_cost`` and the total is minimised, so a pair is only
    made when it is cheaper than leaving both alone (one good pair beats two poor ones).

    Args:
        cost: (T, N) costs (any real values; with ``miss_cost``, costs of allowed pairs).
        allowed: (T, N) which pairs pass the gate.
        miss_cost: cost of an unassigned row or column, or None.

    Returns:
        ``(row, column)`` pairs, sorted by row.
    """
    if cost.size == 0 or not allowed.any():
        return []
    T, N = cost.shape
    if miss_cost is None:
        # Shift the allowed costs to [0, span]; a forbidden pair costs more than any set of allowed ones,
        # so the optimum has the most allowed pairs and, among those, the least total cost.
        lo = float(cost[allowed].min())
        span = float(cost[allowed].max()) - lo
        big = (span + 1.0) * (min(T, N) + 1)
        c = np.where(allowed, cost - lo, big)
    else:
        # Augmented square problem: row t may take its own "miss" column, column n its own "miss" row.
        big = 2.0 * (abs(miss_cost) + float(np.abs(cost[allowed]).max()) + 1.0) * (T + N)
        c = np.full((T + N, N + T), big)
        c[:T, :N] = np.where(allowed, cost, big)
        c[np.arange(T), N + np.arange(T)] = miss_cost
        c[T + np.arange(N), np.arange(N)] = miss_cost
        c[T:, N:] = 0.0
    rows, cols = linear_sum_assignment(c)
    return sorted(
        (int(r), int(k)) for r, k in zip(rows, cols, strict=True) if r < T and k < N and allowed[r, k]
    )


def greedy_assign(dist: FloatArray, gate: float) -> list[tuple[int, int]]:
    """Plain greedy nearest neighbour: repeatedly take the closest free pair within ``gate``.

    Args:
        dist: (T, N) distances (e.g. Euclidean, metres).
        gate: largest allowed distance.

    Returns:
        ``(row, column)`` pairs, sorted by row.
    """
    if dist.size == 0:
        return []
    order = np.argsort(dist, axis=None, kind="stable")
    used_r: set[int] = set()
    used_c: set[int] = set()
    pairs = []
    for flat in order:
        r, k = divmod(int(flat), dist.shape[1])
        if dist[r, k] > gate:
            break
        if r in used_r or k in used_c:
            continue
        used_r.add(r)
        used_c.add(k)
        pairs.append((r, k))
    return sorted(pairs)
