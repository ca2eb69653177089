"""A laser leg pair made of one leg of each of two people close together goes to both, a leg each.

Two people walking side by side 0.45 m apart show four legs to the laser; when the outer two are missed,
the detector pairs the inner two and reports one person between them. The tracker then sees one
observation for two tracks: one of them coasts and the other is pulled 0.2 m off its person.
"""

from __future__ import annotations

import numpy as np
import pytest

from studio.track import Observations, UkfTracker, UkfTrackerConfig
from tests.track.legs_testdata import LEG_SIGMA, PAIR_SIGMA, T0, laser_frame


def frame(k: int, people: list[np.ndarray], pairs: list[tuple[np.ndarray, np.ndarray]]) -> Observations:
    """Observations at 10 Hz: ``people`` as they are, then each leg pair (its centre) with its two legs
    as alternative rows."""
    xy = [*people, *((a + b) / 2.0 for a, b in pairs)]
    sig = [PAIR_SIGMA] * len(xy)
    alt = [-1] * len(xy)
    for i, (a, b) in enumerate(pairs):
        xy += [a, b]
        sig += [LEG_SIGMA, LEG_SIGMA]
        alt += [len(people) + i] * 2
    return laser_frame(k, xy, sig, alt)


def walk_side_by_side(split: float | None, frames: int = 60) -> tuple[list[list], np.ndarray]:
    """Two people 0.45 m apart walking along x at 1 m/s; from frame 10 on, every other frame the laser
    sees only the inner legs (one of each person) and pairs them. Returns the estimates per frame and the
    true positions (frames, 2, 2)."""
    tracker = UkfTracker(config=UkfTrackerConfig(split_pair_separation_m=split))
    truth = np.zeros((frames, 2, 2))
    out = []
    for k in range(frames):
        x = 0.1 * k
        a, b = np.array([x, 0.0]), np.array([x, 0.45])
        truth[k] = a, b
        if k >= 10 and k % 2:
            obs = frame(
                k, [], [(a + np.array([0.0, 0.1]), b - np.array([0.0, 0.1]))]
            )  # a cross pair at y = 0.225
        else:
            obs = frame(k, [a, b], [])
        out.append(tracker.step(obs))
    return out, truth


def test_a_cross_pair_is_split_between_the_two_people():
    est, truth = walk_side_by_side(0.25)
    for k in range(11, 60, 2):  # the cross-pair frames
        assert len(est[k]) == 2
        assert all(e.det_index >= 0 for e in est[k])  # both tracks updated, by one leg each
    err = [
        min(np.hypot(*(e.xy - truth[k, 0])), np.hypot(*(e.xy - truth[k, 1])))
        for k in range(60)
        for e in est[k]
    ]
    assert max(err) < 0.12
    # each track keeps its person
    ids = {e.track_id: int(np.argmin(np.hypot(*(truth[k] - e.xy).T))) for k in (5, 59) for e in est[k]}
    assert len(set(ids.values())) == 2


def test_without_splitting_one_track_coasts_and_the_other_is_pulled():
    est, truth = walk_side_by_side(None)
    coasting = [sum(e.det_index < 0 for e in est[k]) for k in range(11, 60, 2)]
    assert min(coasting) == 1  # the premise of the test above
    err = [
        min(np.hypot(*(e.xy - truth[k, 0])), np.hypot(*(e.xy - truth[k, 1])))
        for k in range(60)
        for e in est[k]
    ]
    assert max(err) > 0.12


def test_people_passing_each_other_are_not_split():
    """Walking in opposite directions, their motion carries them through the frame of the cross pair."""
    tracker = UkfTracker(config=UkfTrackerConfig(split_pair_separation_m=0.25))
    for k in range(10):
        a, b = np.array([-1.0 + 0.1 * k, 0.0]), np.array([1.0 - 0.1 * k, 0.45])
        tracker.step(frame(k, [a, b], []))
    est = tracker.step(frame(10, [], [(np.array([0.0, 0.1]), np.array([0.0, 0.35]))]))
    assert sorted(e.det_index for e in est) == [-1, 0]


def test_a_persons_own_pair_is_not_split_with_a_track_next_to_it():
    """Tracks closer than the separation (a duplicate of one person) never share a pair."""
    tracker = UkfTracker(config=UkfTrackerConfig(split_pair_separation_m=0.25, birth_min_separation_m=0.0))
    for k in range(5):
        tracker.step(frame(k, [np.array([0.0, 0.0]), np.array([0.0, 0.2])], []))
    est = tracker.step(frame(5, [], [(np.array([0.0, -0.1]), np.array([0.0, 0.3]))]))
    assert sorted(e.det_index for e in est) == [-1, 0]  # the pair to one track, the other coasts


def test_legs_alone_are_never_observations():
    """A pair nobody tracks starts one track (at the pair), not three; a lone track takes the pair."""
    tracker = UkfTracker(config=UkfTrackerConfig(confirm_hits=1))
    est = tracker.step(frame(0, [], [(np.array([2.0, -0.1]), np.array([2.0, 0.1]))]))
    assert [e.det_index for e in est] == [0]
    est = tracker.step(frame(1, [], [(np.array([2.0, -0.1]), np.array([2.0, 0.1]))]))
    assert [e.det_index for e in est] == [0]
    np.testing.assert_allclose(est[0].xy, [2.0, 0.0], atol=0.02)


@pytest.mark.parametrize("alt", [[-1, 2], [-2, 0], [1, 0, 0], [-1, 0, 1]])
def test_alternative_rows_are_checked(alt):
    """An alternative row names a row of the frame that is not an alternative itself."""
    n = len(alt)
    with pytest.raises(ValueError, match="alt_of must be"):
        Observations(
            T0,
            np.arange(2 * n, dtype=float).reshape(n, 2),
            np.tile(np.eye(2) * 0.01, (n, 1, 1)),
            ("laser",) * n,
            np.ones(n),
            None,
            np.arange(n),
            np.array(alt),
        )
