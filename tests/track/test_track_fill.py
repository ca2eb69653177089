"""Gap filling: an observation nobody took, on a track's way through a gap, is that track's."""

from __future__ import annotations

import numpy as np
import pytest

from studio.track import Observations
from studio.track.fill import GapFillConfig, fill_gaps
from studio.track.offline import OfflineConfig, track_offline

A = np.array([50.0, 10.0, 10.0, 40.0, 0.0, 0.0], np.float32)
B = A + np.array([0.0, 30.0, 0.0, 0.0, 0.0, 0.0], np.float32)  # another person's colours
T0 = 1_700_000_000_000_000_000
DT = 100_000_000  # 10 Hz


def _frame(i, xy, colours=None, alt_of=None):
    xy = np.asarray(xy, float).reshape(-1, 2)
    n = len(xy)
    app = np.full((n, 6), np.nan, np.float32)
    for k, c in enumerate(colours or []):
        if c is not None:
            app[k] = c
    return Observations(
        T0 + i * DT,
        xy,
        np.repeat(np.eye(2)[None] * 0.0025, n, 0),
        ("fused",) * n,
        np.ones(n),
        app,
        np.arange(n),
        None if alt_of is None else np.asarray(alt_of, np.int64),
    )


def _standing(n=90, seen=(range(20), range(60, 90)), extra=None):
    """Someone standing at (3, 0), observed in the frames ``seen``; ``extra``: frame → more rows."""
    frames = []
    shown = set().union(*seen)
    for i in range(n):
        xy, col = ([[3.0, 0.0]], [A]) if i in shown else ([], [])
        if extra and i in extra:
            more_xy, more_col = extra[i]
            xy, col = xy + more_xy, col + more_col
        frames.append(_frame(i, xy if xy else np.zeros((0, 2)), col))
    return frames


def test_an_observation_on_the_way_through_a_gap_is_added():
    obs = _standing(extra={40: ([[3.1, 0.05]], [A])})
    tracks = {7: [(i, 0) for i in [*range(20), *range(60, 90)]]}
    out, n = fill_gaps(obs, tracks)
    assert n == 1
    assert (40, 0) in out[7]
    assert [i for i, _ in out[7]] == sorted(i for i, _ in out[7])
    assert len(tracks[7]) == 50  # the input is not modified


@pytest.mark.parametrize(
    ("xy", "colours", "why"),
    [
        ([[3.5, 0.0]], [A], "off the way"),
        ([[3.1, 0.0]], [B], "another person's colours"),
    ],
)
def test_an_observation_that_is_not_the_persons_stays_out(xy, colours, why):
    obs = _standing(extra={40: (xy, colours)})
    tracks = {7: [(i, 0) for i in [*range(20), *range(60, 90)]]}
    _, n = fill_gaps(obs, tracks)
    assert n == 0, why


def test_an_observation_without_colours_may_be_added():
    obs = _standing(extra={40: ([[3.1, 0.0]], [None])})
    tracks = {7: [(i, 0) for i in [*range(20), *range(60, 90)]]}
    assert fill_gaps(obs, tracks)[1] == 1


def test_an_observation_near_another_track_stays_out():
    # a second person walks past the spot in frame 40 and holds a detection there
    extra = {i: ([[3.0 + 0.1 * (i - 40), 0.25]], [B]) for i in range(30, 50)}
    extra[40] = ([[3.0, 0.25], [3.05, 0.0]], [B, A])
    obs = _standing(extra=extra)
    tracks = {
        7: [(i, 0) for i in [*range(20), *range(60, 90)]],
        8: [(i, 0) for i in range(30, 50)],  # the walker's is the first row (the standing one is unseen)
    }
    _, n = fill_gaps(obs, tracks)
    assert n == 0  # 0.25 m from the walker's detection: either's


def test_taken_observations_and_leg_rows_stay_out():
    obs = _standing(extra={40: ([[3.05, 0.0]], [A])})
    tracks = {7: [(i, 0) for i in [*range(20), *range(60, 90)]], 9: [(40, 0)]}
    assert fill_gaps(obs, tracks)[1] == 0  # another track holds it
    # a leg of a pair 1 m away: never an observation alone
    obs[40] = _frame(40, [[3.0, 1.0], [3.05, 0.0]], [A, A], alt_of=[-1, 0])
    assert fill_gaps(obs, {7: tracks[7]})[1] == 0


def test_a_gap_too_fast_or_too_long_is_not_searched():
    obs = _standing(extra={40: ([[3.0, 0.0]], [A])})
    far = [_frame(i, [[13.0 if i >= 60 else 3.0, 0.0]], [A]) if len(o.xy) else o for i, o in enumerate(obs)]
    far[40] = obs[40]
    tracks = {7: [(i, 0) for i in [*range(20), *range(60, 90)]]}
    assert fill_gaps(far, tracks)[1] == 0  # 10 m in 4 s: not a straight walk
    assert fill_gaps(obs, tracks, GapFillConfig(max_gap_s=3.0, path_max_gap_s=0.0))[1] == 0
    # longer than max_gap_s, the gap is searched along the way between its ends, up to path_max_gap_s
    assert fill_gaps(obs, tracks, GapFillConfig(max_gap_s=3.0))[1] == 1
    assert fill_gaps(obs, tracks, GapFillConfig(max_gap_s=3.0, path_max_gap_s=3.5))[1] == 0


def _waits_then_walks(extra):
    """Someone lost at (8, 0) at frame 19 who waited there until frame 150, then walked at 0.5 m/s to (10, 0),
    where they were found again at frame 190 (17 s later); ``extra``: frame → (xy, colours) nobody took."""
    frames = []
    for i in range(220):
        xy, col = [], []
        if i < 20:
            xy, col = [[8.0, 0.0]], [A]
        elif i >= 190:
            xy, col = [[10.0 + 0.05 * (i - 190), 0.0]], [A]
        if i in extra:
            xy, col = xy + extra[i][0], col + extra[i][1]
        frames.append(_frame(i, xy if xy else np.zeros((0, 2)), col))
    return frames, {7: [(i, 0) for i in [*range(20), *range(190, 220)]]}


def test_a_gap_longer_than_max_gap_s_takes_what_lies_along_the_way():
    # seen now and then while they waited (every 2 s, 5 cm off), and once while walking on
    seen = {i: ([[8.0, 0.05]], [None]) for i in range(30, 150, 20)} | {170: ([[9.0, 0.03]], [A])}
    obs, tracks = _waits_then_walks(seen)
    out, n = fill_gaps(obs, tracks)
    assert n == len(seen)
    assert {i for i, _ in out[7]} >= set(seen)
    # the straight path in time leaves the spot at 0.12 m/s: only the sighting 1.1 s into the gap lies near it
    assert fill_gaps(obs, tracks, GapFillConfig(max_gap_s=20.0))[1] == 1
    assert fill_gaps(obs, tracks, GapFillConfig(path_max_gap_s=0.0))[1] == 0


@pytest.mark.parametrize(
    ("frame", "xy", "colours", "why"),
    [
        (60, [[8.0, 0.3]], [None], "0.3 m off the way (path_radius 0.2)"),
        (25, [[9.9, 0.0]], [None], "where they were found, 0.6 s after they were lost: 1.9 m, too fast"),
        (185, [[8.1, 0.0]], [None], "where they were lost, 0.5 s before they were found 1.9 m away"),
        (60, [[8.5, 0.0]], [B], "another person's colours"),
    ],
)
def test_along_the_way_what_is_not_the_persons_stays_out(frame, xy, colours, why):
    obs, tracks = _waits_then_walks({frame: (xy, colours)})
    assert fill_gaps(obs, tracks)[1] == 0, why


def test_along_the_way_an_observation_near_another_track_stays_out():
    # someone else stands 0.5 m beside the spot for the whole gap, tracked
    extra = {i: ([[8.0, 0.5]], [B]) for i in range(20, 190)}
    extra[60] = ([[8.0, 0.5], [8.0, 0.05]], [B, None])
    obs, tracks = _waits_then_walks(extra)
    tracks[8] = [(i, 0) for i in range(20, 190)]
    assert fill_gaps(obs, tracks)[1] == 0


def test_config_is_checked():
    with pytest.raises(ValueError, match="positive"):
        GapFillConfig(radius=0)
    with pytest.raises(ValueError, match="positive"):
        GapFillConfig(clearance=-1.0)
    with pytest.raises(ValueError, match="appearance_views"):
        GapFillConfig(appearance_views=0)
    with pytest.raises(ValueError, match="path_"):
        GapFillConfig(path_max_gap_s=-1.0)
    with pytest.raises(ValueError, match="path_"):
        GapFillConfig(path_radius=0.0)


def test_offline_tracking_bridges_a_long_gap_through_a_lone_detection():
    """A person standing still, seen for 2 s, then once 2.1 s later, then again 1.5 s after that: the lone
    detection starts no track of its own, but it splits the 3.6 s gap into two that can be interpolated."""
    obs = _standing(seen=(range(20), range(56, 90)), extra={40: ([[3.02, 0.0]], [A])})
    with_fill = track_offline(obs)
    without = track_offline(obs, config=OfflineConfig(gap_fill=None))
    ids = {p.track_id for f in with_fill.frames for p in f.points}
    assert ids == {0}
    assert all(len(f.points) == 1 for f in with_fill.frames)  # every frame, gap included
    assert with_fill.frames[40].points[0].det_index == 0
    assert all(not without.frames[i].points for i in range(20, 56))  # 3.6 s: too long to interpolate
