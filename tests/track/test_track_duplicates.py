"""Two tracks that follow one person, a leg each, are merged; two people who walk side by side are not."""

from __future__ import annotations

import numpy as np
import pytest

from studio.track.base import Observations
from studio.track.duplicates import DuplicateConfig, merge_duplicates
from studio.track.offline import OfflineConfig

STEP_NS = 25_000_000  # a 40 Hz scanner
LEG = np.array([0.0, 0.12])  # a leg from the middle of the pair


def _frame(k: int, people: list[np.ndarray], legs: bool = True) -> Observations:
    """Frame ``k``: each person's leg pair (a row) and, with ``legs``, its two legs (alternative rows)."""
    xy, alt = [], []
    for p in people:
        xy.append(p)
        alt.append(-1)
    if legs:
        for j, p in enumerate(people):
            xy += [p + LEG, p - LEG]
            alt += [j, j]
    n = len(xy)
    return Observations(
        k * STEP_NS,
        np.array(xy),
        np.tile(np.eye(2) * 0.01, (n, 1, 1)),
        ("laser",) * n,
        np.ones(n),
        None,
        np.arange(n),
        np.array(alt) if legs else None,
    )


def test_two_tracks_on_one_person_s_legs_become_one() -> None:
    walker = [np.array([1.0 + 0.035 * k, 2.0]) for k in range(60)]
    obs = [_frame(k, [walker[k]]) for k in range(60)]
    # track 1 followed the person alone for 20 frames; from frame 20 on, tracks 1 and 2 each took a leg
    # (the split of a pair between two tracks), and in some frames only one of them was observed
    one = [(k, 0) for k in range(20)] + [(k, 1) for k in range(20, 60) if k % 7]
    two = [(k, 2) for k in range(20, 60) if k % 5]
    out, merges = merge_duplicates(obs, {1: one, 2: two})
    assert merges == [(1, 2)]
    assert list(out) == [1]
    rows = dict(out[1])
    assert sorted(rows) == [k for k in range(60) if k != 35]  # every frame one of the two had
    shared = [k for k in range(20, 60) if k % 7 and k % 5]
    assert all(rows[k] == 0 for k in shared)  # where both held a leg: the pair itself
    assert rows[28] == 2  # only track 2 held it (28 % 7 == 0): its leg


def test_two_people_side_by_side_keep_their_tracks() -> None:
    a = [np.array([1.0 + 0.035 * k, 2.0]) for k in range(60)]
    b = [p + np.array([0.0, 0.45]) for p in a]
    obs = []
    for k in range(60):
        if k % 4 == 0:  # the laser paired a leg of each: one pair between them, split between the tracks
            mid = 0.5 * (a[k] + b[k])
            obs.append(_frame(k, [mid]))
        else:
            obs.append(_frame(k, [a[k], b[k]]))
    ta = [(k, 1 if k % 4 == 0 else 0) for k in range(60)]
    tb = [(k, 2 if k % 4 == 0 else 1) for k in range(60)]
    out, merges = merge_duplicates(obs, {1: ta, 2: tb})
    assert merges == []
    assert out == {1: ta, 2: tb}


def test_a_duplicate_s_hits_outside_the_common_span_stay_a_track_of_their_own() -> None:
    walker = [np.array([0.035 * k, 0.0]) for k in range(50)]
    obs = [_frame(k, [walker[k]]) for k in range(50)]
    one = [(k, 1) for k in range(30)]
    two = [(k, 2) for k in range(10, 30)] + [(k, 0) for k in range(30, 50)]
    out, merges = merge_duplicates(obs, {1: one, 2: two})
    assert merges == [(2, 1)]  # track 2 has more observations: it keeps the person
    assert [k for k, _ in out[2]] == list(range(10, 50))
    assert [k for k, _ in out[1]] == list(range(10))  # before track 2 began


def _alone(k: int, xy: np.ndarray) -> Observations:
    """Frame ``k`` with one observation (a single leg, or a person the laser saw alone)."""
    return _frame(k, [xy], legs=False)


def test_two_tracks_that_hold_one_person_in_turn_become_one() -> None:
    # one person walks along x; from frame 20 on the detector finds one leg a frame, 0.4 m apart in the
    # stride, and two tracks take them in turn: never both observed, always within a stride of each other
    walker = [np.array([0.035 * k, 0.0]) for k in range(60)]
    step = np.array([0.2, 0.0])
    obs = [_alone(k, walker[k] if k < 20 else walker[k] + (step if k % 2 else -step)) for k in range(60)]
    one = [(k, 0) for k in range(60) if k < 20 or k % 2]
    two = [(k, 0) for k in range(20, 56) if k % 2 == 0]
    out, merges = merge_duplicates(obs, {1: one, 2: two})
    assert merges == [(1, 2)]
    assert [k for k, _ in out[1]] == [k for k in range(60) if k not in (56, 58)]  # all either held
    # off (in_turn_m 0), or two people 0.8 m apart seen in turn: two tracks
    assert merge_duplicates(obs, {1: one, 2: two}, DuplicateConfig(in_turn_m=0.0))[1] == []
    side = [
        _alone(k, walker[k] + (np.array([0.0, 0.8]) if k % 2 == 0 and k >= 20 else 0.0)) for k in range(60)
    ]
    assert merge_duplicates(side, {1: one, 2: two})[1] == []


def test_too_few_shared_frames_are_no_proof() -> None:
    walker = [np.array([0.035 * k, 0.0]) for k in range(30)]
    obs = [_frame(k, [walker[k]]) for k in range(30)]
    one = [(k, 1) for k in range(30)]
    two = [(k, 2) for k in range(21, 30)]  # nine shared frames
    assert merge_duplicates(obs, {1: one, 2: two})[1] == []
    assert merge_duplicates(obs, {1: one, 2: two}, DuplicateConfig(min_shared=9))[1] == [(1, 2)]


def test_the_config_is_checked_and_on_by_default() -> None:
    with pytest.raises(ValueError, match="min_shared"):
        DuplicateConfig(min_shared=0)
    with pytest.raises(ValueError, match="max_apart_share"):
        DuplicateConfig(max_apart_share=1.0)
    with pytest.raises(ValueError, match="in_turn_m"):
        DuplicateConfig(in_turn_m=-0.1)
    assert OfflineConfig().duplicates == DuplicateConfig()
