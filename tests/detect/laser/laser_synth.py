"""Synthetic 2D laser scans for the laser detector tests: ray casting against circles and wall segments."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np


def cast(
    *,
    circles: Sequence[tuple[float, float, float]] = (),
    walls: Sequence[tuple[float, float, float, float]] = (),
    origin: tuple[float, float] = (0.0, 0.0),
    yaw: float = 0.0,
    fov_deg: float = 270.0,
    step_deg: float = 0.35,
    max_range: float = 10.0,
) -> tuple[np.ndarray, np.ndarray]:
    """One scan: points ``(M, 2)`` in the laser frame (NaN where no return) and the valid mask.

    ``circles`` are ``(x, y, radius)`` and ``walls`` ``(x1, y1, x2, y2)`` in the world frame; the laser sits
    at ``origin`` with heading ``yaw``.
    """
    half = np.radians(fov_deg) / 2.0
    ang = np.arange(-half, half + 1e-9, np.radians(step_deg))
    d = np.stack([np.cos(ang + yaw), np.sin(ang + yaw)], axis=1)
    o = np.asarray(origin, dtype=float)
    best = np.full(ang.size, np.inf)
    for cx, cy, r in circles:
        oc = o - np.array([cx, cy])
        b = d @ oc
        disc = b**2 - (oc @ oc - r * r)
        t = -b - np.sqrt(np.where(disc >= 0, disc, np.nan))
        with np.errstate(invalid="ignore"):
            best = np.where((disc >= 0) & (t > 0) & (t < best), t, best)
    for x1, y1, x2, y2 in walls:
        p, q = np.array([x1, y1]), np.array([x2, y2])
        e = q - p
        den = d[:, 0] * (-e[1]) - d[:, 1] * (-e[0])
        rhs = p - o
        with np.errstate(divide="ignore", invalid="ignore"):
            t = (rhs[0] * (-e[1]) - rhs[1] * (-e[0])) / den
            s = (d[:, 0] * rhs[1] - d[:, 1] * rhs[0]) / den
        ok = np.isfinite(t) & (t > 0) & (s >= 0) & (s <= 1) & (t < best)
        best = np.where(ok, t, best)
    valid = best <= max_range
    pts = np.stack([best * np.cos(ang), best * np.sin(ang)], axis=1)
    pts[~valid] = np.nan
    return pts, valid
