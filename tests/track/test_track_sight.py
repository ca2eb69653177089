"""What the scanners saw empty (:mod:`studio.track.sight`), and the motion links it refuses."""

from __future__ import annotations

import numpy as np
import pytest

from studio.track.sight import ScanView, Sight, scan_view
from studio.track.stitch import StitchConfig, Tracklet, stitch_links

S = 1_000_000_000
P = np.diag([0.003, 0.003, 0.05, 0.05])


def fan(origin=(0.0, 0.0), wall_m=6.0, step_deg=0.25, fov=(-135.0, 135.0), legs=(), hole=None):
    """The beam ends of one scan: a round wall ``wall_m`` from ``origin``, stopped short by leg discs
    ``(x, y, radius)``; beams in ``hole`` (deg, deg) returned nothing (NaN)."""
    o = np.asarray(origin, float)
    ang = np.deg2rad(np.arange(fov[0], fov[1] + 1e-9, step_deg))
    d = np.c_[np.cos(ang), np.sin(ang)]
    r = np.full(len(ang), wall_m)
    for x, y, rad in legs:
        c = np.array([x, y]) - o
        t = d @ c
        h2 = rad**2 - (c @ c - t**2)
        hit = (h2 > 0) & (t > 0)
        r = np.where(hit, np.minimum(r, t - np.sqrt(np.maximum(h2, 0))), r)
    ends = o + d * r[:, None]
    if hole is not None:
        inside = (np.rad2deg(ang) >= hole[0]) & (np.rad2deg(ang) <= hole[1])
        ends[inside] = np.nan
    return ends, o


def test_a_scanner_without_a_range_limit_is_stored_without_overflow():
    """A scan whose range_max is unknown (NaN or none) has free beams out to float32's largest range:
    stored as 60 km, with no numpy overflow warning on the user's console."""
    import warnings

    with warnings.catch_warnings():
        warnings.simplefilter("error")
        view = scan_view([fan(wall_m=float(np.finfo(np.float32).max))])
    assert view is not None
    seen = view.ranges[np.isfinite(view.ranges)]
    assert len(seen) >= 268  # the 270° the fan covers
    assert np.all(seen == np.float16(6.0e4))
    assert view.sees_empty(np.array([50.0, 0.0]))


def test_a_place_the_beams_went_through_is_seen_empty():
    view = scan_view([fan()])
    assert view is not None
    assert view.ranges.shape == (1, 360)
    assert view.ranges.dtype == np.float16
    assert view.sees_empty(np.array([2.0, 0.0]))
    assert view.sees_empty(np.array([0.0, -4.0]))
    assert not view.sees_empty(np.array([5.8, 0.0]))  # at the wall: a beam stopped there
    assert not view.sees_empty(np.array([7.0, 0.0]))  # behind the wall: hidden
    assert not view.sees_empty(np.array([-3.0, 0.0]))  # behind the scanner, outside its field of view
    assert not view.sees_empty(np.array([0.3, 0.0]))  # too near the scanner to judge


def test_a_person_a_dropout_and_a_second_scanner():
    legs = [(3.0, 0.1, 0.06), (3.0, -0.1, 0.06)]
    view = scan_view([fan(legs=legs)])
    assert not view.sees_empty(np.array([3.0, 0.0]))  # the person stops the beams
    assert not view.sees_empty(np.array([4.5, 0.0]))  # and hides what is behind them
    assert view.sees_empty(np.array([3.0, 1.0]))  # beside them the beams went through
    holed = scan_view([fan(hole=(20.0, 40.0))])
    assert not holed.sees_empty(np.array([3 * np.cos(np.deg2rad(30)), 3 * np.sin(np.deg2rad(30))]))
    # one scanner seeing a place empty is enough
    two = scan_view([fan(legs=legs), fan(origin=(3.0, -3.0), fov=(0.0, 180.0))])
    assert two.origins.shape == (2, 2)
    assert two.sees_empty(np.array([4.5, 0.0]))
    assert scan_view([]) is None


def test_clear_seconds_counts_the_frames_a_straight_walk_was_seen_empty():
    # 10 Hz frames; the scanner at the origin sees to a wall 6 m off, but not behind a pillar at (1, 1):
    # from x = 2 it hides y > ~1.2 (bearings 45° ± 12°, half a person's width more)
    stamps = [round(0.1 * k * S) for k in range(31)]
    pillar = [(1.0, 1.0, 0.3)]
    views = [scan_view([fan(legs=pillar)]) for _ in stamps]
    sight = Sight(stamps, views)
    # a walk from (2, 3) to (2, -3) over 3 s, frames 1-29 in between: hidden for its first ~0.9 s
    t = sight.clear_seconds(np.array([2.0, 3.0]), 0, np.array([2.0, -3.0]), 3 * S)
    assert 1.8 <= t <= 2.2
    # a walk that stays behind the pillar is never seen
    assert sight.clear_seconds(np.array([2.0, 1.6]), 0, np.array([2.0, 3.0]), 3 * S) == 0.0
    # frames without a view see nothing; a frame vouches for at most 0.25 s
    blind = Sight(stamps, [None] * len(stamps))
    assert not blind
    assert blind.clear_seconds(np.array([2.0, 3.0]), 0, np.array([2.0, -3.0]), 3 * S) == 0.0
    sparse = Sight([0, 2 * S, 3 * S], [views[0]] * 3)
    assert sparse.clear_seconds(np.array([2.0, -1.0]), -S, np.array([2.0, -1.0]), 4 * S) == pytest.approx(
        0.75
    )
    with pytest.raises(ValueError, match="one view"):
        Sight([0, 1], [views[0]])


def test_the_walk_leaves_and_arrives_at_the_given_velocities():
    # the scanner at the origin sees up to a wall at x = 3; a walk from (2, -1) to (2, 1) in 2 s is seen
    # empty all the way when straight, but one that leaves towards +x and comes back bows behind the wall
    ends = np.array([[3.0, y] for y in np.linspace(-6.0, 6.0, 2000)])
    view = scan_view([(ends, np.zeros(2))])
    stamps = [round(0.1 * k * S) for k in range(21)]
    sight = Sight(stamps, [view] * len(stamps))
    a, b = np.array([2.0, -1.0]), np.array([2.0, 1.0])
    straight = sight.clear_seconds(a, 0, b, 2 * S)
    assert straight == pytest.approx(1.9)
    assert sight.clear_seconds(a, 0, b, 2 * S, np.array([0.0, 1.0]), np.array([0.0, 1.0])) == straight
    bowed = sight.clear_seconds(a, 0, b, 2 * S, np.array([3.0, 1.0]), np.array([-3.0, 1.0]))
    assert bowed < 0.8


def tracklet(tid, start_s, end_s, p_start, p_end, v):
    xs, xe = np.array([*p_start, *v], float), np.array([*p_end, *v], float)
    return Tracklet(tid, round(start_s * S), round(end_s * S), xs, P, xe, P)


def test_a_motion_link_through_places_seen_empty_is_refused():
    # A walks towards +x and is lost at (1, 0); B starts 1.5 s later at (2.5, 0), on A's way
    a = tracklet(0, 0.0, 5.0, (-4.0, 0.0), (1.0, 0.0), (1.0, 0.0))
    b = tracklet(1, 6.5, 10.0, (2.5, 0.0), (6.0, 0.0), (1.0, 0.0))
    stamps = [round(0.1 * k * S) for k in range(101)]
    # the scanner at (1.5, -3) saw that way empty in every frame (beams to the wall 6 m off)
    empty = Sight(stamps, [scan_view([fan(origin=(1.5, -3.0), fov=(0.0, 180.0))])] * len(stamps))
    # ... or a person stood in it, between the scanner and the way, hiding it
    hidden = Sight(
        stamps,
        [scan_view([fan(origin=(1.5, -3.0), fov=(0.0, 180.0), legs=[(1.75, -1.5, 0.4)])])] * len(stamps),
    )
    assert stitch_links([a, b]) == [(0, 1)]
    assert stitch_links([a, b], sight=empty) == []
    assert stitch_links([a, b], sight=hidden) == [(0, 1)]
    assert stitch_links([a, b], sight=empty, config=StitchConfig(seen_empty_s=0.0)) == [(0, 1)]
    # a gap shorter than seen_empty_s is not judged
    b_soon = tracklet(1, 5.4, 10.0, (1.4, 0.0), (6.0, 0.0), (1.0, 0.0))
    assert stitch_links([a, b_soon], sight=empty) == [(0, 1)]


def test_a_view_is_left_behind_when_observations_change_frame():
    from studio.geometry.se import Pose2
    from studio.track.base import Observations

    view = scan_view([fan()])
    o = Observations(
        0,
        np.zeros((1, 2)),
        np.eye(2)[None] * 0.01,
        ("laser",),
        np.ones(1),
        None,
        np.zeros(1, np.int64),
        view=view,
    )
    assert o.view is view
    assert o.transformed(Pose2(1.0, 0.0, 0.5)).view is None


@pytest.mark.parametrize("field", ["seen_empty_s", "hidden_min_duration_s", "hidden_max_error"])
def test_negative_sight_options_are_refused(field):
    with pytest.raises(ValueError, match="must not be negative"):
        StitchConfig(**{field: -1.0})


def test_view_is_compact():
    view = ScanView(np.zeros((2, 2)), np.full((2, 360), np.nan, np.float16))
    assert not view.sees_empty(np.array([2.0, 0.0]))  # nothing known


def test_someone_who_walked_on_hidden_is_found_again_where_the_walk_leads():
    # A walks along +x at 1 m/s and is lost at (0, 0) at t = 10 s; B starts 5 s later at (5, 0), walking
    # on: too far for "found again where lost" (1 m + 0.25 m/s x 5 s) and both too short for it (1 s)
    a = tracklet(0, 9.0, 10.0, (-1.0, 0.0), (0.0, 0.0), (1.0, 0.0))
    b = tracklet(1, 15.0, 16.0, (5.0, 0.0), (6.0, 0.0), (1.0, 0.0))
    stamps = [round(0.1 * k * S) for k in range(201)]
    # a scanner at (2.5, -3) behind a wall 1 m around it never sees the way; without the wall it sees it empty
    walled = Sight(stamps, [scan_view([fan(origin=(2.5, -3.0), wall_m=1.0, fov=(0.0, 180.0))])] * len(stamps))
    open_ = Sight(stamps, [scan_view([fan(origin=(2.5, -3.0), fov=(0.0, 180.0))])] * len(stamps))
    assert stitch_links([a, b]) == []
    assert stitch_links([a, b], sight=walled) == [(0, 1)]
    assert stitch_links([a, b], sight=open_) == []
    # 2 m off where A's and B's velocities say the walk leads, it is no such link
    b_off = tracklet(1, 15.0, 16.0, (5.0, 2.0), (6.0, 2.0), (1.0, 0.0))
    assert stitch_links([a, b_off], sight=walled) == []
    # half a second is the shortest tracklet that may make one; hidden_max_error 0 switches it off
    a_short = tracklet(0, 9.7, 10.0, (-0.3, 0.0), (0.0, 0.0), (1.0, 0.0))
    assert stitch_links([a_short, b], sight=walled) == []
    assert stitch_links([a, b], sight=walled, config=StitchConfig(hidden_max_error=0.0)) == []


def test_someone_who_walked_on_hidden_and_stopped_is_found_again_on_the_way():
    # A walks along +x at 1 m/s and is lost at (0, 0) at t = 10 s; B stands at (2.5, 0) from 15 s: the
    # person walked on behind the wall and stopped halfway along where A's walk leads. Too far for "found
    # again where lost" (1 m + 0.25 m/s x 5 s); A's walk at its velocity would end 2.5 m further on
    a = tracklet(0, 9.0, 10.0, (-1.0, 0.0), (0.0, 0.0), (1.0, 0.0))
    stamps = [round(0.1 * k * S) for k in range(201)]
    walled = Sight(stamps, [scan_view([fan(origin=(2.5, -3.0), wall_m=1.0, fov=(0.0, 180.0))])] * len(stamps))
    stopped = tracklet(1, 15.0, 16.0, (2.5, 0.0), (2.5, 0.0), (0.0, 0.0))
    assert stitch_links([a, stopped], sight=walled) == [(0, 1)]
    # 2 m beside the way, or back behind where A was lost, is not on it
    beside = tracklet(1, 15.0, 16.0, (2.5, 2.0), (2.5, 2.0), (0.0, 0.0))
    behind = tracklet(1, 15.0, 16.0, (-2.5, 0.0), (-2.5, 0.0), (0.0, 0.0))
    assert stitch_links([a, beside], sight=walled) == []
    assert stitch_links([a, behind], sight=walled) == []
