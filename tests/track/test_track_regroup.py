"""Two leg pairs whose legs the laser paired across two people, and the other ways to pair them.

Two people side by side with their legs spread mid-stride show four legs in a row; the detector may pair
the front leg of each and the back leg of each, and report two people between them. The labeling pipeline
passes the other pairings on as alternative rows (``Observations.joins``); the encounter re-decision takes
them where they fit both tracks better (``test_track_encounters.py``; held-out ``moving`` seed 76, frames
363 and 369: seven switches to three).
"""

from __future__ import annotations

import numpy as np
import pytest

from studio.track import Observations, UkfTracker, UkfTrackerConfig
from tests.track.legs_testdata import detections, frame, legs, overtaking


def test_joins_name_two_legs_of_two_different_pairs():
    obs = frame(0, [legs(np.array([0.0, 0.0]), 0.3), legs(np.array([0.0, 0.45]), 0.3)])
    assert obs.joins is not None
    assert len(obs) == 10  # 2 pairs, 4 legs, 2 other pairings x 2 midpoints
    assert obs.alternative.tolist() == [False, False] + [True] * 8
    for r in range(6, 10):
        a, b = obs.joins[r]
        assert obs.alt_of[a] != obs.alt_of[b]
        assert obs.origin(r) == obs.alt_of[a]
        c = obs.complement(r)
        assert obs.complement(c) == r
        assert not set(obs.joins[c]) & {a, b}
    assert sorted(obs.regroupings(0, 1)) == sorted(obs.regroupings(1, 0)) == [(6, 7), (8, 9)]
    assert obs.origin(3) == 0  # a leg of pair 0
    assert obs.origin(1) == 1
    assert obs.complement(1) == -1
    with pytest.raises(ValueError, match="joins must be"):
        Observations(
            *[getattr(obs, f) for f in ("stamp_ns", "xy", "cov", "source", "score")],
            None,
            obs.det_index,
            obs.alt_of,
            joins=np.where(np.arange(10)[:, None] == 6, [2, 3], obs.joins),
        )
    bad = obs.joins.copy()
    bad[2] = 4, 6
    with pytest.raises(ValueError, match="joins must be"):  # a leg row cannot be a midpoint
        Observations(
            obs.stamp_ns, obs.xy, obs.cov, obs.source, obs.score, None, obs.det_index, obs.alt_of, joins=bad
        )


def test_the_online_tracker_never_takes_a_midpoint():
    """Midpoints of two pairs' legs are alternatives only: online, tracks take the detector's pairs (a
    midpoint decided from the past alone fit no better on the held-out seeds and cost switches at 30 Hz,
    session 71); the encounter re-decision below weighs them with both trajectories known."""
    paths = overtaking()
    tracker = UkfTracker(config=UkfTrackerConfig())
    est = [tracker.step(o) for o in detections(paths, {19, 20, 21})]
    assert all(e.det_index in (0, 1) for row in est for e in row)
    assert len(est[-1]) == 2
