"""Ray-cast scans for the pipeline tests."""

from __future__ import annotations

import numpy as np


def scan(circles: list[tuple[float, float, float]]) -> np.ndarray:
    """``(720, 3)`` float32 beams of a scanner at the origin (0.5° apart), z = 0.3, inf → NaN."""
    ang = np.deg2rad(np.arange(720) * 0.5 - 180.0)
    d = np.stack([np.cos(ang), np.sin(ang)], 1)
    best = np.full(len(ang), np.inf)
    for cx, cy, r in circles:
        b = d @ np.array([cx, cy])
        disc = b**2 - (cx**2 + cy**2 - r**2)
        t = b - np.sqrt(np.where(disc >= 0, disc, np.nan))
        best = np.fmin(best, np.where((disc >= 0) & (t > 0), t, np.inf))
    rng = np.where(np.isfinite(best), best, np.nan)
    pts = np.zeros((len(ang), 3), np.float32)
    pts[:, :2] = d * rng[:, None]
    pts[:, 2] = 0.3
    return pts
