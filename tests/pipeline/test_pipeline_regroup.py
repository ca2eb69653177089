"""The tracker is given the other ways to pair the legs of two leg pairs side by side
(``Observations.joins``): the laser detector may have paired a leg of each of two people."""

from __future__ import annotations

import numpy as np
import pytest

from studio.fuse.base import PersonObservations
from studio.geometry.se import Pose2
from studio.pipeline.base import FrameResult
from studio.pipeline.label import _to_odom

A = np.array([[3.0, 0.15], [3.0, -0.15]])  # someone mid-stride 3 m ahead
B = np.array([[3.45, 0.2], [3.45, -0.1]])  # someone beside them
FAR = np.array([[6.0, 2.0], [6.0, 2.3]])  # a third person far from both


def _frame(pairs: list[np.ndarray], pose: Pose2) -> FrameResult:
    n = len(pairs)
    obs = PersonObservations(
        np.array([p.mean(axis=0) for p in pairs]),
        np.tile(np.eye(2) * 0.05**2, (n, 1, 1)),
        np.linspace(0.9, 0.5, n),
        ("laser",) * n,
        ("laser-only",) * n,
        np.full((n, 4), np.nan),
        np.full(n, -1),
        np.arange(n),
    )
    return FrameResult(0, 0, pose, obs, legs=np.array(pairs))


def test_two_pairs_side_by_side_come_with_their_other_pairings():
    pose = Pose2(1.0, -2.0, 0.5)
    obs = _to_odom(_frame([A, B, FAR], pose), None, 0.11)
    assert obs.joins is not None
    assert len(obs) == 3 + 6 + 4  # pairs, legs, two other pairings of A and B
    mids = np.flatnonzero(obs.joins[:, 0] >= 0)
    assert obs.alternative[mids].all()
    assert not obs.alternative[:3].any()
    assert sorted(obs.regroupings(0, 1)) == [(9, 10), (11, 12)]
    assert obs.regroupings(0, 2) == []
    for r in mids:
        la, lb = obs.joins[r]
        assert {int(obs.alt_of[la]), int(obs.alt_of[lb])} == {0, 1}
        np.testing.assert_allclose(obs.xy[r], (obs.xy[la] + obs.xy[lb]) / 2)
        assert obs.source[r] == "laser"
        assert obs.score[r] == pytest.approx(0.7)  # the lower of A's and B's
    expected = pose.apply(
        np.array([(A[0] + B[0]) / 2, (A[1] + B[1]) / 2, (A[0] + B[1]) / 2, (A[1] + B[0]) / 2])
    )
    np.testing.assert_allclose(np.sort(obs.xy[mids], axis=0), np.sort(expected, axis=0))


def test_pairs_whose_legs_cannot_pair_the_other_way_come_alone():
    wide = np.array([[3.0, 0.3], [3.0, -0.3]])  # legs 0.6 m apart: one leg of B is 0.65 m from one of them
    obs = _to_odom(_frame([wide, B + np.array([0.2, 0.0]), FAR], Pose2()), None, 0.11)
    assert obs.joins is None
    assert len(obs) == 9
