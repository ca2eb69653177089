"""Tracklet stitching across gaps: re-join a person's track that the online tracker split.

A tracklet A that ends at ``t1`` may continue as a tracklet B that starts at ``t2`` with
``0 < t2 - t1 <= max_gap_s``. The pair is allowed when

* motion agrees: the constant-velocity bridge is consistent. With ``e`` the mean of the distances between
  A's end predicted forward to ``t2`` and B's start, and B's start predicted backward to ``t1`` and A's end,
  ``e <= n_sigma·σ + max_accel_speed·gap`` (σ from both estimates' covariances; ``max_accel_speed`` is the
  largest velocity change a person makes unseen, m/s) and the straight distance is walkable:
  ``|B.start - A.end| <= n_sigma·σ + max_speed·gap``;
* appearance agrees (when both carry a descriptor): Bhattacharyya distance ``<= max_appearance``.

The cost of an allowed pair is ``e / gate + appearance_weight · d_app / max_appearance``; ends are matched to
starts one-to-one by the Hungarian algorithm with a cost for leaving an end or a start unlinked, and chains
(A → B → C) follow.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from studio.track.appearance import bhattacharyya_distance
from studio.track.gnn import gnn_assign

__all__ = ["StitchConfig", "Tracklet", "chain_links", "stitch_links"]

FloatArray = NDArray[np.float64]


@dataclass(frozen=True)
class Tracklet:
    """What stitching needs to know about one tracklet.

    Attributes:
        track_id: its id.
        start_ns, end_ns: stamps of its first and last observation, ns.
        x_start, x_end: (4,) (smoothed) states ``[px, py, vx, vy]`` there (m, m/s).
        P_start, P_end: (4, 4) their covariances.
        app_start, app_end: (D,) appearance descriptors near its start / end, or None.
    """

    track_id: int
    start_ns: int
    end_ns: int
    x_start: FloatArray
    P_start: FloatArray
    x_end: FloatArray
    P_end: FloatArray
    app_start: NDArray[np.float32] | None = None
    app_end: NDArray[np.float32] | None = None


@dataclass(frozen=True)
class StitchConfig:
    """Options of :func:`stitch_links`.

    Attributes:
        max_gap_s: longest gap bridged, seconds.
        n_sigma: how many standard deviations of the estimates the gates allow.
        max_accel_speed: largest unseen change of velocity, m/s (2 = a walker turning back).
        max_speed: fastest walking speed, m/s.
        max_appearance: largest Bhattacharyya distance of a link (when both sides have descriptors).
        appearance_weight: weight of the appearance term in the cost.
        miss_cost: cost of leaving a tracklet end or start unlinked; links are chosen to minimise the total,
            so one good link beats two poor ones that conflict with it.
    """

    max_gap_s: float = 3.0
    n_sigma: float = 3.0
    max_accel_speed: float = 2.0
    max_speed: float = 2.5
    max_appearance: float = 0.5
    appearance_weight: float = 1.0
    miss_cost: float = 1.5

    def __post_init__(self) -> None:
        if self.max_gap_s <= 0 or self.max_appearance <= 0:
            raise ValueError("max_gap_s and max_appearance must be positive")


def _pair_cost(a: Tracklet, b: Tracklet, cfg: StitchConfig) -> float | None:
    gap = (b.start_ns - a.end_ns) * 1e-9
    if not 0.0 < gap <= cfg.max_gap_s:
        return None
    pa, va, pb, vb = a.x_end[:2], a.x_end[2:], b.x_start[:2], b.x_start[2:]
    e = 0.5 * (np.hypot(*(pb - (pa + va * gap))) + np.hypot(*(pa - (pb - vb * gap))))
    lam = lambda M: float(np.linalg.eigvalsh(M)[-1])  # noqa: E731 - largest eigenvalue
    var_pos = lam(a.P_end[:2, :2]) + lam(b.P_start[:2, :2])
    var = var_pos + 0.5 * gap**2 * (lam(a.P_end[2:, 2:]) + lam(b.P_start[2:, 2:]))
    gate = cfg.n_sigma * np.sqrt(var) + cfg.max_accel_speed * gap
    if e > gate or np.hypot(*(pb - pa)) > cfg.n_sigma * np.sqrt(var_pos) + cfg.max_speed * gap:
        return None
    cost = e / gate
    if a.app_end is not None and b.app_start is not None:
        d = bhattacharyya_distance(a.app_end, b.app_start)
        if d > cfg.max_appearance:
            return None
        cost += cfg.appearance_weight * d / cfg.max_appearance
    return cost


def stitch_links(tracklets: list[Tracklet], *, config: StitchConfig | None = None) -> list[tuple[int, int]]:
    """Decide which tracklet continues which.

    Returns:
        ``(id_a, id_b)`` links: B continues A. Every id is at most once an ``id_a`` and once an ``id_b``.
    """
    cfg = config or StitchConfig()
    n = len(tracklets)
    cost = np.zeros((n, n))
    allowed = np.zeros((n, n), dtype=bool)
    for i, a in enumerate(tracklets):
        for j, b in enumerate(tracklets):
            if i != j:
                c = _pair_cost(a, b, cfg)
                if c is not None:
                    cost[i, j], allowed[i, j] = c, True
    return [
        (tracklets[i].track_id, tracklets[j].track_id)
        for i, j in gnn_assign(cost, allowed, miss_cost=cfg.miss_cost)
    ]


def chain_links(ids: list[int], links: list[tuple[int, int]]) -> dict[int, int]:
    """Map every tracklet id to the id of the first tracklet of its chain."""
    prev = {b: a for a, b in links}
    root: dict[int, int] = {}
    for i in ids:
        r = i
        while r in prev:
            r = prev[r]
        root[i] = r
    return root
