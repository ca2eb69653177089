"""Tracklet stitching tables: motion and appearance gates, global one-to-one links, chains."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from studio.track.stitch import StitchConfig, Tracklet, chain_links, link_cuts, stitch_links

S = 1_000_000_000
P = np.diag([0.003, 0.003, 0.05, 0.05])  # ~5 cm, ~0.2 m/s
RED = np.array([50.0, 60.0, 40.0, 30.0, 0.0, 0.0], np.float32)  # L*a*b* of a red shirt over dark trousers
BLUE = np.array([50.0, 10.0, -50.0, 30.0, 0.0, 0.0], np.float32)


def tl(tid, start_s, end_s, p_start, p_end, v=(1.0, 0.0), app=None, views=10) -> Tracklet:
    xs = np.array([*p_start, *v], float)
    xe = np.array([*p_end, *v], float)
    n = 0 if app is None else views
    return Tracklet(tid, round(start_s * S), round(end_s * S), xs, P, xe, P, app, app, app, n)


# A walks along +x at 1 m/s and ends at x = 0, t = 10 s; candidates B start after a gap.
A = tl(0, 5.0, 10.0, (-5.0, 0.0), (0.0, 0.0))
CASES = [
    ("on the predicted path", [A, tl(1, 11.5, 15.0, (1.5, 0.0), (5.0, 0.0))], [(0, 1)]),
    ("stopped in the gap", [A, tl(1, 11.5, 15.0, (0.3, 0.1), (0.3, 0.1), v=(0.0, 0.0))], [(0, 1)]),
    ("gap too long", [A, tl(1, 14.0, 15.0, (4.0, 0.0), (5.0, 0.0))], []),
    ("starts before A ends", [A, tl(1, 9.0, 15.0, (1.5, 0.0), (5.0, 0.0))], []),
    ("too far to walk", [A, tl(1, 11.0, 15.0, (0.0, 6.0), (4.0, 6.0))], []),
    ("off the predicted path", [A, tl(1, 11.0, 15.0, (-2.0, 3.0), (2.0, 3.0))], []),
    (
        "the closer of two candidates",
        [A, tl(1, 11.0, 15.0, (1.0, 0.0), (5.0, 0.0)), tl(2, 11.0, 15.0, (1.0, 1.5), (5.0, 1.5))],
        [(0, 1)],
    ),
]


@pytest.mark.parametrize(("name", "tracklets", "expected"), CASES, ids=[c[0] for c in CASES])
def test_motion_table(name, tracklets, expected):
    assert stitch_links(tracklets) == expected


def test_appearance_gate_and_cost():
    a = tl(0, 5.0, 10.0, (-5.0, 0.0), (0.0, 0.0), app=RED)
    same_path_blue = tl(1, 11.0, 15.0, (1.0, 0.0), (5.0, 0.0), app=BLUE)
    off_path_red = tl(2, 11.0, 15.0, (1.0, 1.2), (5.0, 1.2), app=RED)
    assert stitch_links([a, same_path_blue, off_path_red]) == [(0, 2)]
    assert stitch_links([a, same_path_blue]) == []
    # without descriptors motion alone decides
    no_app = [tl(0, 5.0, 10.0, (-5.0, 0.0), (0.0, 0.0)), tl(1, 11.0, 15.0, (1.0, 0.0), (5.0, 0.0))]
    assert stitch_links(no_app) == [(0, 1)]
    assert stitch_links([a, same_path_blue], config=StitchConfig(max_appearance=200.0)) == [(0, 1)]


def test_the_pieces_of_a_colour_cut_are_joined_again_only_when_their_colours_agree_closely():
    a = tl(0, 5.0, 10.0, (-5.0, 0.0), (0.0, 0.0), app=RED)
    near = RED + np.array([0.0, 0.0, 6.0, 0.0, 0.0, 0.0], np.float32)  # one person in other light
    off = RED + np.array([0.0, 0.0, 18.0, 0.0, 0.0, 0.0], np.float32)  # someone else, within 25 ΔE
    b_near = tl(1, 10.1, 15.0, (0.1, 0.0), (5.0, 0.0), app=near)
    b_off = tl(1, 10.1, 15.0, (0.1, 0.0), (5.0, 0.0), app=off)
    assert stitch_links([a, b_off]) == [(0, 1)]  # a motion link allows 25 ΔE
    assert stitch_links([a, b_off], cut=[(0, 1)]) == []
    assert stitch_links([a, b_near], cut=[(0, 1)]) == [(0, 1)]  # a cut through one person is undone
    # an undescribed piece of a cut is not joined again by motion alone
    bare = [tl(0, 5.0, 10.0, (-5.0, 0.0), (0.0, 0.0)), tl(1, 10.1, 15.0, (0.1, 0.0), (5.0, 0.0))]
    assert stitch_links(bare, cut=[(0, 1)]) == []


def test_a_re_identification_beats_a_motion_link_to_someone_in_other_colours():
    # A hides for 6.5 s and comes back where it was lost in its own colours (B); 1 s after A is lost,
    # someone else walks on from A's predicted position in clothes 16 ΔE away (X). Colours count as much
    # as motion does (appearance_weight 2): with weight 1 the smooth motion link to X won.
    a = tl(0, 5.0, 10.0, (-5.0, 0.0), (0.0, 0.0), app=RED)
    other = RED + np.array([0.0, 0.0, 16.0, 0.0, 0.0, 0.0], np.float32)
    x = tl(1, 11.0, 13.0, (1.0, 0.05), (3.0, 0.05), app=other)
    b = tl(2, 16.5, 20.0, (0.5, 0.0), (0.5, 0.0), v=(0.0, 0.0), app=RED + np.float32(1.0))
    assert stitch_links([a, x, b]) == [(0, 2)]
    assert stitch_links([a, x, b], config=StitchConfig(appearance_weight=1.0, unknown_appearance=0.5)) == [
        (0, 1)
    ]


def test_one_to_one_and_chains():
    # two walkers side by side 2 m apart, both hidden from 10 to 11 s, then again from 15 to 16 s
    parts = []
    for y, base in ((0.0, 0), (2.0, 10)):
        parts += [
            tl(base + 0, 5.0, 10.0, (-5.0, y), (0.0, y)),
            tl(base + 1, 11.0, 15.0, (1.0, y), (5.0, y)),
            tl(base + 2, 16.0, 20.0, (6.0, y), (10.0, y)),
        ]
    links = stitch_links(parts)
    assert sorted(links) == [(0, 1), (1, 2), (10, 11), (11, 12)]
    root = chain_links([p.track_id for p in parts], links)
    assert root == {0: 0, 1: 0, 2: 0, 10: 10, 11: 10, 12: 10}


def test_two_views_in_other_colours_refuse_a_motion_link():
    # a piece the camera saw twice, in colours far from those of the track it would continue (held-out
    # moving seed 37: person 0's two views 48 ΔE from person 5's track): no motion link; in its colours,
    # seen once (a crop may show a neighbour), or with the rule off, motion decides as before
    a = tl(0, 5.0, 10.0, (-5.0, 0.0), (0.0, 0.0), app=RED)
    for tracklets in (
        [a, tl(1, 11.0, 15.0, (1.0, 0.0), (5.0, 0.0), app=BLUE, views=2)],
        [
            tl(1, 0.0, 10.0, (-5.0, 0.0), (0.0, 0.0), app=BLUE, views=2),
            tl(0, 11.0, 15.0, (1.0, 0.0), (5.0, 0.0), app=RED),
        ],
    ):
        assert stitch_links(tracklets) == []
        assert stitch_links(tracklets, config=StitchConfig(few_views=0)) != []
    assert stitch_links([a, tl(1, 11.0, 15.0, (1.0, 0.0), (5.0, 0.0), app=RED, views=2)]) == [(0, 1)]
    assert stitch_links([a, tl(1, 11.0, 15.0, (1.0, 0.0), (5.0, 0.0), app=BLUE, views=1)]) == [(0, 1)]


def test_two_views_more_than_20_apart_refuse_a_motion_link():
    # held-out moving seed 22: a piece seen twice, 24 ΔE from the track it continues by motion (person 5
    # walking on where person 1 left view); the motion-link gate of described tracklets (25) let it join
    from studio.track.appearance import appearance_distance

    a = tl(0, 5.0, 10.0, (-5.0, 0.0), (0.0, 0.0), app=RED)
    other = RED + np.array([0.0, -23.0, 0.0, 0.0, 0.0, 0.0], np.float32)
    assert 20.0 < appearance_distance(RED, other) < 25.0
    piece = tl(1, 11.0, 15.0, (1.0, 0.0), (5.0, 0.0), app=other, views=2)
    assert stitch_links([a, piece]) == []
    assert stitch_links([a, piece], config=StitchConfig(few_max_appearance=25.0)) == [(0, 1)]
    # described by ten views the same colours are a motion link's, within max_appearance
    assert stitch_links([a, replace(piece, n_app=10)]) == [(0, 1)]
    with pytest.raises(ValueError, match="few_max_appearance"):
        StitchConfig(few_max_appearance=0.0)
    with pytest.raises(ValueError, match="walk_max_appearance"):
        StitchConfig(walk_max_appearance=0.0)


def test_unknown_appearance_does_not_beat_agreeing_colours():
    # A (red) ends; a laser tracklet without colours starts right on its path, a red one a little off it:
    # the red continuation wins, the laser tracklet may only follow the red one
    a = tl(0, 5.0, 10.0, (-5.0, 0.0), (0.0, 0.0), app=RED)
    laser = tl(1, 10.5, 11.0, (0.5, 0.0), (1.0, 0.0))
    red = tl(2, 11.0, 15.0, (1.1, 0.3), (5.0, 0.3), app=RED)
    assert (0, 2) in stitch_links([a, laser, red])
    # one crop is not enough to judge colours: such a tracklet counts as unknown (two in other colours
    # refuse the link since session 58: test_two_views_in_other_colours_refuse_a_motion_link)
    few = tl(3, 11.0, 15.0, (1.0, 0.0), (5.0, 0.0), app=BLUE, views=1)
    assert stitch_links([a, few]) == [(0, 3)]


def test_re_identification_after_a_long_absence():
    a = tl(0, 0.0, 10.0, (-5.0, 0.0), (0.0, 0.0), app=RED)
    back_red = tl(1, 30.0, 40.0, (4.0, 3.0), (0.0, 3.0), v=(-1.0, 0.0), app=RED + 2.0)
    back_blue = tl(2, 30.0, 40.0, (4.0, -3.0), (0.0, -3.0), v=(-1.0, 0.0), app=BLUE)
    assert stitch_links([a, back_red, back_blue]) == [(0, 1)]
    assert stitch_links([a, back_blue]) == []
    assert stitch_links([a, back_red], config=StitchConfig(reid_max_gap_s=0.0)) == []
    # two crops are not enough for colours (without them, only the position rule could join them)
    two_views = tl(3, 30.0, 40.0, (4.0, 3.0), (0.0, 3.0), app=RED, views=2)
    assert stitch_links([a, two_views], config=StitchConfig(lost_max_gap_s=0.0)) == []
    # too far to have walked there in the gap
    far = tl(4, 30.0, 40.0, (60.0, 0.0), (70.0, 0.0), app=RED)
    assert stitch_links([a, far]) == []


def test_of_two_returns_in_the_same_colours_the_sooner_one_continues():
    # A is lost at t = 10 s; someone in A's colours appears 5 s later, and someone in colours a shade
    # closer to A's a minute later (rooms seed 1: a walker lost for 4.7 s was joined to a piece of
    # themselves 65 s later, and the 4.7 s return started a second track of them)
    a = tl(0, 0.0, 10.0, (-5.0, 0.0), (0.0, 0.0), app=RED)
    soon = tl(1, 15.0, 90.0, (2.0, 3.0), (5.0, 3.0), app=RED + 1.5)  # still there when the late one comes
    late = tl(2, 75.0, 80.0, (2.0, -3.0), (5.0, -3.0), app=RED + 1.0)
    assert stitch_links([a, soon, late]) == [(0, 1)]
    # without the cost of time, the closer colours win
    assert stitch_links([a, soon, late], config=StitchConfig(reid_cost_per_min=0.0)) == [(0, 2)]
    # alone, the late one is still found again
    assert stitch_links([a, late]) == [(0, 2)]


def test_someone_hidden_for_long_is_found_again_near_where_they_were_lost():
    # no colours (a laser-only rig): A stands at the origin until t = 10 s, is hidden for 8 s, and a long
    # tracklet starts 0.8 m away; the limit there is lost_distance + lost_speed * 8 = 3 m
    still = (0.0, 0.0)
    a = tl(0, 0.0, 10.0, (0.0, 0.0), (0.0, 0.0), v=still)
    back = tl(1, 18.0, 30.0, (0.8, 0.0), (3.0, 0.0), v=still)
    assert stitch_links([a, back]) == [(0, 1)]
    # the nearer of two who appear
    farther = tl(2, 18.0, 30.0, (2.0, 1.0), (3.0, 1.0), v=still)
    assert stitch_links([a, farther, back]) == [(0, 1)]
    # not a short tracklet (clutter), not too far, not after too long, not when switched off
    assert stitch_links([a, replace(back, end_ns=round(19.0 * S))]) == []
    assert stitch_links([a, tl(3, 18.0, 30.0, (3.5, 0.0), (3.0, 0.0), v=still)]) == []
    assert stitch_links([a, back], config=StitchConfig(lost_max_gap_s=5.0)) == []
    # colours on both sides decide by themselves: different people are not joined
    red = replace(a, app=RED, app_start=RED, app_end=RED, n_app=10)
    blue = replace(back, app=BLUE, app_start=BLUE, app_end=BLUE, n_app=10)
    assert stitch_links([red, blue]) == []
    assert stitch_links([red, back]) == [(0, 1)]


def test_someone_found_again_where_they_were_lost_though_their_whole_colours_differ():
    # A stands 9 m away; for part of it a neighbour's colours got in, so A's colours as a whole are 15 ΔE
    # from B's, too much for a re-identification. Its colours at the end agree with B's at the start, and
    # B starts 0.3 m from where A was lost, 3.5 s later (beyond max_gap_s): the same person
    still = (0.0, 0.0)
    spoiled = RED + np.array([0, 0, 0, 0, 15, 0], np.float32)
    a = replace(tl(0, 0.0, 10.0, (9.0, 0.0), (9.0, 0.0), v=still, app=RED), app=spoiled, n_app=3)
    b = replace(tl(1, 13.5, 14.0, (9.0, 0.3), (9.0, 0.3), v=still, app=RED), n_app=3)  # 0.5 s: short
    assert stitch_links([a, b]) == [(0, 1)]
    # not where A was lost, not with other colours at the joint, not after more than lost_max_gap_s
    assert stitch_links([a, replace(b, x_start=np.array([12.0, 0.3, 0.0, 0.0]))]) == []
    other = RED + np.array([0, 0, 0, 0, 30, 0], np.float32)
    assert stitch_links([a, replace(b, app=other, app_start=other, app_end=other)]) == []
    assert stitch_links([a, b], config=StitchConfig(lost_max_gap_s=3.0)) == []


def test_two_people_are_not_joined_through_a_laser_tracklet():
    # red ends, a colourless laser tracklet bridges the gap by motion, blue starts where it ends: the laser
    # tracklet may continue one of them, but red and blue stay two people
    red = tl(0, 0.0, 10.0, (-5.0, 0.0), (0.0, 0.0), app=RED)
    laser = tl(1, 10.5, 12.0, (0.5, 0.0), (2.0, 0.0))
    blue = tl(2, 12.5, 20.0, (2.5, 0.0), (10.0, 0.0), app=BLUE)
    links = stitch_links([red, laser, blue])
    assert len(links) == 1
    assert links[0] in ((0, 1), (1, 2))


def test_undescribed_pieces_go_into_the_gap_of_a_re_identification_nearest_them():
    # a far person stands at (8, 0) from t = 10 s to 40 s: the camera describes them at the start and the
    # end, in between only the laser sees them (two colourless pieces); someone else in red left at (0, 5)
    # at t = 5 s and comes back there at t = 45 s
    still = (0.0, 0.0)
    a = tl(0, 0.0, 10.0, (8.0, 0.0), (8.0, 0.0), v=still, app=BLUE)
    u1 = tl(1, 14.0, 20.0, (8.1, 0.0), (8.1, 0.1), v=still)
    u2 = tl(2, 20.5, 30.0, (8.1, 0.1), (8.0, 0.0), v=still)
    c = tl(3, 35.0, 40.0, (8.0, 0.1), (8.0, 0.1), v=still, app=BLUE)
    red = tl(4, 0.0, 5.0, (0.0, 5.0), (0.0, 5.0), v=still, app=RED)
    red_back = tl(5, 45.0, 50.0, (0.0, 5.0), (0.0, 5.0), v=still, app=RED)
    links = stitch_links([a, u1, u2, c, red, red_back])
    assert links == [(0, 1), (1, 2), (2, 3), (4, 5)]
    # a piece elsewhere (4 m from both ends) stays out
    away = tl(6, 14.0, 20.0, (8.0, 4.0), (8.0, 4.0), v=still)
    assert stitch_links([a, away, c]) == [(0, 3)]


def test_a_piece_seen_twice_in_other_colours_away_from_the_ends_goes_into_no_gap():
    # blue is lost at (8, 0) and re-identified there 25 s later; a piece in between 2.5 m away was seen by
    # the camera twice, both times in red (moving seed 11: a second track on a neighbour 4 m from the gap's
    # ends, 46 ΔE from its colours, went into it and its 1 s came out as two switches): someone else, it
    # stays out
    still = (0.0, 0.0)
    a = tl(0, 0.0, 10.0, (8.0, 0.0), (8.0, 0.0), v=still, app=BLUE)
    c = tl(2, 35.0, 40.0, (8.0, 0.1), (8.0, 0.1), v=still, app=BLUE)
    piece = tl(1, 14.0, 16.0, (8.0, 2.5), (8.0, 2.5), v=still, app=RED, views=2)
    assert stitch_links([a, piece, c]) == [(0, 2)]
    # on the spot where blue was lost and found again it is blue, whatever two crops say (moving seed 50:
    # 4 s of the person standing there, seen twice 39 ΔE off); two crops in blue's colours, one crop
    # (perhaps of a neighbour) or the rule off: it goes in
    on_the_spot = tl(1, 14.0, 16.0, (8.1, 0.0), (8.1, 0.1), v=still, app=RED, views=2)
    for fits, config in (
        (on_the_spot, StitchConfig()),
        (replace(piece, app=BLUE, app_start=BLUE, app_end=BLUE), StitchConfig()),
        (replace(piece, n_app=1), StitchConfig()),
        (piece, StitchConfig(few_views=0)),
    ):
        assert stitch_links([a, fits, c], config=config) == [(0, 1), (1, 2)]


def test_a_described_piece_that_matched_no_one_goes_into_the_gap_of_a_re_identification():
    # blue walks away and is re-identified 25 s later; in between the camera saw them for a moment far
    # away (four noisy views, 15 ΔE from their colours: too far for a re-identification of its own, within
    # a motion link's colour gate), where blue was lost
    still = (0.0, 0.0)
    a = tl(0, 0.0, 10.0, (8.0, 0.0), (8.0, 0.0), v=still, app=BLUE)
    c = tl(2, 35.0, 40.0, (8.0, 0.1), (8.0, 0.1), v=still, app=BLUE)
    noisy_blue = BLUE + np.array([0.0, 0.0, 15.0, 0.0, 0.0, 0.0], np.float32)
    piece = tl(1, 14.0, 16.0, (8.1, 0.0), (8.1, 0.1), v=still, app=noisy_blue, views=4)
    assert stitch_links([a, piece, c]) == [(0, 1), (1, 2)]
    # seen in more crops than fill_max_views, its colours are no noise: someone else, the piece stays out
    assert stitch_links([a, replace(piece, n_app=10), c]) == [(0, 2)]
    assert stitch_links([a, piece, c], config=StitchConfig(fill_max_views=0)) == [(0, 2)]
    # someone in red there is someone else: the piece stays out
    assert stitch_links([a, replace(piece, app=RED, app_start=RED, app_end=RED), c]) == [(0, 2)]


def test_a_chain_of_described_pieces_goes_into_the_gap_of_a_re_identification():
    # blue is lost at (13.4, 0) and re-identified 21.7 s later; in between they were seen as two pieces
    # linked to each other: the first in three crops that partly showed a neighbour (12 ΔE off as a whole),
    # the second in thirteen (2 ΔE off). A → C wins the re-identification (its colours match best); the chain
    # goes into its gap, where the person was
    still = (0.0, 0.0)
    a = tl(0, 20.0, 45.7, (10.0, 0.0), (13.4, 0.0), v=still, app=BLUE)
    off = lambda d: BLUE + np.array([0.0, 0.0, d, 0.0, 0.0, 0.0], np.float32)  # noqa: E731
    p1 = tl(1, 50.3, 54.2, (14.5, 2.3), (14.0, 1.95), v=still, app=off(12.0), views=3)
    p2 = tl(2, 55.2, 59.3, (14.2, 1.86), (15.2, -0.7), v=still, app=off(2.0), views=13)
    c = tl(3, 67.4, 90.0, (13.2, -0.8), (1.6, 2.6), v=still, app=BLUE)
    assert stitch_links([a, p1, p2, c]) == [(0, 1), (1, 2), (2, 3)]
    # the well-described piece 12 ΔE off is someone else: the chain stays out
    p2_other = replace(p2, app=off(12.0), app_start=off(12.0), app_end=off(12.0))
    assert stitch_links([a, p1, p2_other, c]) == [(0, 3), (1, 2)]
    # only undescribed pieces when fill_max_views is 0
    assert stitch_links([a, p1, p2, c], config=StitchConfig(fill_max_views=0)) == [(0, 3), (1, 2)]


def test_a_re_identified_chain_is_a_track_not_a_piece_of_another_gap():
    # two people in the same colours, both lost and found again: the one found inside the other's gap is
    # a track of their own, not a piece of the other
    a0 = tl(0, 0.0, 10.0, (8.0, 0.0), (8.0, 0.0), v=(5.0, 0.0), app=BLUE)
    a1 = tl(1, 11.0, 15.0, (8.5, 1.0), (8.5, 1.0), v=(0.0, 5.0), app=BLUE)
    c1 = tl(2, 25.0, 38.0, (8.5, 1.0), (8.5, 1.0), v=(0.0, 5.0), app=BLUE)
    c0 = tl(3, 40.0, 50.0, (8.0, 0.2), (8.0, 0.2), v=(5.0, 0.0), app=BLUE)
    assert stitch_links([a0, a1, c1, c0]) == [(0, 3), (1, 2)]


def test_an_undescribed_piece_goes_into_the_gap_it_continues_by_motion():
    # two people wait at one spot and are both re-identified much later; a colourless piece starts 2.4 s
    # after red left, where red was walking to, but nearer where blue (gone for 6.4 s) stood: it continues red
    red = tl(0, 0.0, 10.0, (4.0, 0.4), (2.0, 2.4), v=(-0.3, 0.3), app=RED)
    red_back = tl(1, 50.0, 60.0, (1.2, 4.6), (1.2, 4.6), v=(0.0, 0.0), app=RED)
    blue = tl(2, 0.0, 6.0, (1.1, 3.8), (1.1, 3.8), v=(0.0, 0.0), app=BLUE)
    blue_back = tl(3, 45.0, 55.0, (1.3, 4.2), (1.3, 4.2), v=(0.0, 0.0), app=BLUE)
    piece = tl(4, 12.4, 13.4, (1.2, 3.2), (1.0, 4.1), v=(-0.3, 0.3))
    assert stitch_links([red, red_back, blue, blue_back, piece]) == [(0, 4), (2, 3), (4, 1)]
    # without the motion link (red left 6 s before it), the piece goes where its joints are shortest
    red_early = tl(0, 0.0, 6.4, (4.0, 0.4), (2.0, 2.4), v=(-0.3, 0.3), app=RED)
    assert stitch_links([red_early, red_back, blue, blue_back, piece]) == [(0, 1), (2, 4), (4, 3)]


def test_a_piece_that_continues_one_end_by_motion_goes_into_the_gap_however_far_the_other_end():
    # blue, 10 m away, is lost; 2 s later a colourless piece goes on from where they were for 2 s; blue is
    # re-identified 20 s after that, 13.6 m away (a walk at 0.7 m/s): the piece is blue's
    a = tl(0, 0.0, 14.3, (3.3, -2.0), (13.16, -0.02), v=(-0.05, 0.02), app=BLUE)
    piece = tl(1, 16.3, 18.2, (13.17, -0.03), (13.16, 0.28), v=(0.0, 0.1))
    c = tl(2, 38.1, 45.0, (0.29, 4.59), (-0.5, 4.7), v=(-0.6, 0.0), app=BLUE)
    assert stitch_links([a, piece, c]) == [(0, 1), (1, 2)]
    # without the motion link (the piece starts 5 s after blue left) both joints must be short
    late = tl(1, 19.3, 21.0, (13.17, -0.03), (13.16, 0.28), v=(0.0, 0.1))
    assert stitch_links([a, late, c]) == [(0, 2)]
    # nor where the other end is farther than a walk
    assert stitch_links([a, piece, replace(c, x_start=np.array([-40.0, 4.59, -0.6, 0.0]))]) == [(0, 2)]


def with_hits(t: Tracklet, stamps_s: np.ndarray, xy: np.ndarray) -> Tracklet:
    """``t`` with forward-filtered states at its observations (velocity from the path)."""
    v = np.gradient(xy, stamps_s, axis=0)
    x = np.column_stack([xy, v])
    return replace(
        t, hit_ns=np.round(stamps_s * S).astype(np.int64), x_hit=x, P_hit=np.repeat(P[None], len(x), 0)
    )


def test_a_tracklet_whose_tail_left_its_person_is_continued_by_the_one_that_took_over():
    # A walks along +x at 1 m/s from t = 0; from t = 8 s its tail follows clutter off to the side (y = 1),
    # while B picks the person up at t = 8.2 s on A's path
    ts = np.arange(0.0, 10.01, 0.1)
    path = np.column_stack([ts - 5.0, np.where(ts < 8.0, 0.0, np.minimum(ts - 8.0, 1.0))])
    a = with_hits(tl(0, 0.0, 10.0, path[0], path[-1], v=(0.0, 0.0), app=RED), ts, path)
    b = tl(1, 8.2, 15.0, (3.2, 0.0), (10.0, 0.0), app=RED)
    assert stitch_links([a, b]) == [(0, 1)]
    # not without the states along A, not when B starts too early, not off A's path
    assert stitch_links([replace(a, hit_ns=None), b]) == []
    assert stitch_links([a, b], config=StitchConfig(max_overlap_s=1.0)) == []
    assert stitch_links([a, tl(2, 8.2, 15.0, (3.2, 2.5), (10.0, 2.5), app=RED)]) == []


def test_a_tracklet_whose_last_observations_were_a_neighbours_is_continued_from_before_them():
    # A walks along +x at 1 m/s; its last 0.3 s (from t = 7.7 s) are a neighbour's, who walks off along
    # +y from (2.7, 0.4); B picks the person up at t = 8.1 s on A's path, after A's last observation
    ts = np.arange(0.0, 8.01, 0.1)
    path = np.column_stack([ts - 5.0, np.where(ts < 7.65, 0.0, 0.4 + 3.0 * (ts - 7.7))])
    a = with_hits(tl(0, 0.0, 8.0, path[0], path[-1], v=(0.0, 3.0), app=RED), ts, path)
    b = tl(1, 8.1, 15.0, (3.1, 0.0), (10.0, 0.0), app=RED)
    links = stitch_links([a, b])
    assert links == [(0, 1)]
    # B goes on from A's last observation on the person (t = 7.6 s): the later ones are given up
    assert link_cuts([a, b], links) == {1: round(7.6 * S)}
    assert stitch_links([a, b], config=StitchConfig(tail_back_s=0.0)) == []
    # a plain continuation gives nothing up
    straight = np.column_stack([ts - 5.0, 0.0 * ts])
    plain = with_hits(tl(0, 0.0, 8.0, (-5.0, 0.0), (3.0, 0.0), app=RED), ts, straight)
    assert link_cuts([plain, b], stitch_links([plain, b])) == {}


def test_a_piece_that_overlaps_an_end_of_the_gap_goes_into_it():
    # blue walks along +x and is lost at (8, 0), t = 10 s; a colourless piece of them began 0.1 s before (the
    # online pass had two tracks on blue for a frame) and walks on to (12, 0), t = 14 s; blue is
    # re-identified at (12.3, 0) 20 s later
    ts = np.arange(0.0, 10.01, 0.1)
    path = np.column_stack([ts - 2.0, 0.0 * ts])
    a = with_hits(tl(0, 0.0, 10.0, (-2.0, 0.0), (8.0, 0.0), app=BLUE), ts, path)
    tp = np.arange(9.9, 14.01, 0.1)
    walk = np.column_stack([tp - 2.0, 0.0 * tp])
    piece = with_hits(tl(1, 9.9, 14.0, walk[0], walk[-1]), tp, walk)
    still = (0.0, 0.0)
    c = tl(2, 34.0, 40.0, (12.3, 0.0), (12.3, 0.0), v=still, app=BLUE)
    assert stitch_links([a, piece, c]) == [(0, 1), (1, 2)]
    # a piece that starts elsewhere as blue is lost is someone else's
    away = with_hits(tl(1, 9.9, 14.0, (7.9, 3.0), (12.0, 3.0)), tp, walk + np.array([0.0, 3.0]))
    assert stitch_links([a, away, c]) == [(0, 2)]
    # and one that starts before blue was ever seen is not a piece of blue's gap
    early = with_hits(tl(1, -1.0, 14.0, (-3.0, 0.0), walk[-1]), np.r_[-1.0, tp], np.r_[[[-3.0, 0.0]], walk])
    assert (0, 1) not in stitch_links([a, early, c])


def test_a_piece_that_runs_past_the_return_goes_into_the_gap_where_the_return_meets_it():
    # blue stands at (8, 0) and is lost at t = 10 s; a colourless piece of them runs from 14 s to 30 s; the
    # re-identified track begins at 28 s on a passer-by at (9, 0) and goes on with blue from 29 s: where the
    # piece ends, the re-identified track is where the piece is
    still = (0.0, 0.0)
    a = tl(0, 0.0, 10.0, (8.0, 0.0), (8.0, 0.0), v=still, app=BLUE)
    tp = np.arange(14.0, 30.01, 0.1)
    piece = with_hits(
        tl(1, 14.0, 30.0, (8.0, 0.0), (8.0, 0.0), v=still), tp, np.tile([8.0, 0.0], (len(tp), 1))
    )
    tc = np.arange(28.0, 40.01, 0.1)
    xc = np.column_stack([np.where(tc < 29.0, 9.0, 8.05), 0.0 * tc])
    c = with_hits(tl(2, 28.0, 40.0, (9.0, 0.0), (8.05, 0.0), v=still, app=BLUE), tc, xc)
    assert stitch_links([a, piece, c]) == [(0, 1), (1, 2)]
    # where the re-identified track is elsewhere as the piece ends, the piece stays out
    far = with_hits(c, tc, xc + np.array([0.0, 2.0]))
    far = replace(far, x_start=far.x_start + np.array([0.0, 2.0, 0.0, 0.0]))
    assert stitch_links([a, piece, far]) == [(0, 2)]


def test_a_second_track_on_someone_goes_into_no_one_elses_gap():
    # blue is lost at (8, 0), t = 10 s, and re-identified there at t = 35 s; a colourless piece stands at
    # (8.1, 0) from 14 s to 20 s, as in the test above, but red stands 0.2 m beside it all that time: the
    # piece is a second track on red (born on one of red's legs), not a piece of blue
    still = (0.0, 0.0)
    a = tl(0, 0.0, 10.0, (8.0, 0.0), (8.0, 0.0), v=still, app=BLUE)
    c = tl(3, 35.0, 40.0, (8.0, 0.1), (8.0, 0.1), v=still, app=BLUE)
    tp = np.arange(14.0, 20.01, 0.1)
    piece = with_hits(
        tl(1, 14.0, 20.0, (8.1, 0.0), (8.1, 0.0), v=still), tp, np.tile([8.1, 0.0], (len(tp), 1))
    )
    tr = np.arange(12.0, 22.01, 0.1)
    red = with_hits(
        tl(2, 12.0, 22.0, (8.1, 0.2), (8.1, 0.2), v=still, app=RED), tr, np.tile([8.1, 0.2], (len(tr), 1))
    )
    assert stitch_links([a, piece, c, red]) == [(0, 3)]
    # red 0.5 m away (someone walking beside the lost person) leaves the piece to blue's gap, and so does
    # red beside it for less than half of its observations, or the check switched off
    apart = with_hits(red, tr, np.tile([8.1, 0.5], (len(tr), 1)))
    assert stitch_links([a, piece, c, apart]) == [(0, 1), (1, 3)]
    brief = with_hits(red, tr, np.column_stack([np.full(len(tr), 8.1), np.where(tr < 16.5, 0.2, 3.0)]))
    assert stitch_links([a, piece, c, brief]) == [(0, 1), (1, 3)]
    assert stitch_links([a, piece, c, red], config=StitchConfig(beside_m=0.0)) == [(0, 1), (1, 3)]
    # beside an end of the gap itself (blue's return begins 0.1 s into a 2 s piece) it still goes in
    tq, tb = np.arange(18.0, 20.01, 0.1), np.arange(18.1, 40.01, 0.1)
    short = with_hits(
        tl(1, 18.0, 20.0, (8.1, 0.0), (8.1, 0.0), v=still), tq, np.tile([8.1, 0.0], (len(tq), 1))
    )
    back = tl(3, 18.1, 40.0, (8.1, 0.2), (8.1, 0.2), v=still, app=BLUE)
    back = with_hits(back, tb, np.tile([8.1, 0.2], (len(tb), 1)))
    assert stitch_links([a, short, back]) == [(0, 1), (1, 3)]


def test_a_piece_continued_by_motion_at_both_ends_fills_the_gap_though_its_colours_changed():
    # blue stands at (8, 0) while the robot drives past a desk between them: the camera sees blue's
    # trousers behind the desk top for 9 s (a piece in sixteen views whose colours are 29 ΔE off), and the
    # pieces before and after are joined by their colours across it. The piece takes over 0.8 s after blue
    # was lost, where blue stood, and blue's return 0.3 s after it ends, where it stood: motion links at
    # both ends, colours set aside (simulated ``moving`` seed 66, person 6; two switches)
    still = (0.0, 0.0)
    desk = BLUE + np.array([0.0, 0.0, 0.0, 0.0, 5.0, 28.0], np.float32)
    a = tl(0, 0.0, 10.0, (8.0, 0.0), (8.0, 0.0), v=still, app=BLUE)
    c = tl(2, 20.0, 30.0, (8.1, 0.2), (8.1, 0.2), v=still, app=BLUE)
    piece = tl(1, 10.8, 19.7, (8.05, 0.1), (8.05, 0.1), v=still, app=desk, views=16)
    assert stitch_links([a, piece, c]) == [(0, 1), (1, 2)]
    # it begins 4 s after blue was lost, or blue comes back 4 s after it ends: no motion link there
    # (someone else may have stepped in)
    assert stitch_links([a, replace(piece, start_ns=14 * S), c]) == [(0, 2)]
    assert stitch_links([a, replace(piece, end_ns=16 * S), c]) == [(0, 2)]
    # blue comes back 3 m from where the piece ended, 0.3 s later: no walk
    far = tl(2, 20.0, 30.0, (8.0, 3.1), (8.0, 3.1), v=still, app=BLUE)
    assert stitch_links([a, piece, far]) == [(0, 2)]
    # someone else in a red shirt steps in where blue vanished and vanishes where blue comes back: seen in
    # 125 views 41 ΔE off, that is no spoiled view of blue (held-out seed 97, a 29 s piece of person 0 in
    # person 1's 34 s gap: seven switches more)
    red = BLUE + np.array([0.0, 41.0, 0.0, 0.0, 0.0, 0.0], np.float32)
    other = replace(piece, app=red, n_app=125)
    assert stitch_links([a, other, c]) == [(0, 2)]
    assert stitch_links([a, other, c], config=StitchConfig(walk_max_appearance=45.0)) == [(0, 1), (1, 2)]
    assert stitch_links([a, replace(other, n_app=5), c]) == [(0, 1), (1, 2)]  # a few noisy crops: as before


@pytest.mark.parametrize(
    "field", ["reid_max_gap_s", "reid_cost_per_min", "lost_max_gap_s", "few_views", "beside_m"]
)
def test_negative_stitch_options_are_refused(field):
    with pytest.raises(ValueError, match="must not be"):
        StitchConfig(**{field: -1.0})
