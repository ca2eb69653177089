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
    assert fill_gaps(obs, tracks, GapFillConfig(max_gap_s=3.0))[1] == 0


def test_config_is_checked():
    with pytest.raises(ValueError, match="positive"):
        GapFillConfig(radius=0)
    with pytest.raises(ValueError, match="positive"):
        GapFillConfig(clearance=-1.0)
    with pytest.raises(ValueError, match="appearance_views"):
        GapFillConfig(appearance_views=0)


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
