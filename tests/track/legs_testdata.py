"""Leg pairs as the labeling pipeline gives them to the tracker, for the tracking tests: two people side by
side whose legs the laser detector may pair across them (``Observations.alt_of``, ``Observations.joins``)."""

from __future__ import annotations

import itertools

import numpy as np

from studio.track import Observations

T0 = 1_700_000_000_000_000_000
PAIR_SIGMA, LEG_SIGMA = 0.05, 0.11


def frame(k: int, pairs: list[np.ndarray]) -> Observations:
    """Observations at 10 Hz of leg pairs ``pairs`` (each ``(2, 2)``, its two legs): the pairs' centres,
    their legs (``alt_of``), then for every two pairs whose legs can pair the other ways (each two legs
    within 0.6 m) the midpoints of those pairings (``joins``)."""
    n = len(pairs)
    xy = [p.mean(axis=0) for p in pairs] + [leg for p in pairs for leg in p]
    sig = [PAIR_SIGMA] * n + [LEG_SIGMA] * 2 * n
    alt = [-1] * n + [i for i in range(n) for _ in range(2)]
    joins = [(-1, -1)] * 3 * n
    for a, b in itertools.combinations(range(n), 2):
        for lb in (0, 1):
            couple = [(0, lb), (1, 1 - lb)]
            if all(np.hypot(*(pairs[a][x] - pairs[b][y])) <= 0.6 for x, y in couple):
                for x, y in couple:
                    xy.append((pairs[a][x] + pairs[b][y]) / 2)
                    sig.append(PAIR_SIGMA)
                    alt.append(-1)
                    joins.append((n + 2 * a + x, n + 2 * b + y))
    return laser_frame(k, xy, sig, alt, np.array(joins, np.int64) if len(xy) > 3 * n else None)


def laser_frame(
    k: int, xy: list[np.ndarray], sig: list[float], alt: list[int], joins: np.ndarray | None = None
) -> Observations:
    """Frame ``k`` at 10 Hz of laser observations at ``xy`` with standard errors ``sig``, ``alt_of`` rows
    ``alt`` and ``joins``."""
    m = len(xy)
    return Observations(
        T0 + k * 100_000_000,
        np.array(xy).reshape(-1, 2),
        np.array([s**2 * np.eye(2) for s in sig]).reshape(-1, 2, 2),
        ("laser",) * m,
        np.ones(m),
        None,
        np.arange(m),
        np.array(alt, np.int64) if m else None,
        joins=joins,
    )


def legs(centre: np.ndarray, stride: float) -> np.ndarray:
    """A walker's two legs, ``stride`` metres apart along x."""
    return centre + np.array([[stride / 2, 0.0], [-stride / 2, 0.0]])


def overtaking(n: int = 40) -> np.ndarray:
    """A walks +x along y = 0 at 1.2 m/s and overtakes B, walking +x along y = 0.45 at 0.4 m/s, at frame
    20: ``(n, 2, 2)`` positions."""
    t = np.arange(n) * 0.1
    a = np.c_[-2.4 + 1.2 * t, np.zeros(n)]
    b = np.c_[-0.8 + 0.4 * t, np.full(n, 0.45)]
    return np.stack([a, b], axis=1)


def detections(paths: np.ndarray, crossed: set[int]) -> list[Observations]:
    """Both walkers' leg pairs in every frame; in the frames ``crossed`` the detector paired the front leg
    of each and the back leg of each."""
    out = []
    for k, (a, b) in enumerate(paths):
        la, lb = legs(a, 0.3), legs(b, 0.3)
        pairs = [np.array([la[0], lb[0]]), np.array([la[1], lb[1]])] if k in crossed else [la, lb]
        out.append(frame(k, pairs))
    return out
