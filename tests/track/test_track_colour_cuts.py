"""Colour cuts: a tracklet whose clothing colours change for good went on with someone else."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from studio.track import Observations
from studio.track.appearance import appearance_distance, appearance_matrix
from studio.track.colour_cuts import ColourCutConfig, colour_change, cut_colour_changes
from studio.track.offline import OfflineConfig, track_offline
from studio.track.ukf import UkfTrackerConfig

A = np.array([50.0, 10.0, 10.0, 40.0, 0.0, 0.0])
B = A + np.array([0.0, 30.0, 0.0, 0.0, 0.0, 0.0])  # 30 ΔE from A: another person, within the online gate
T0 = 1_700_000_000_000_000_000


def _colours(*runs, rng_seed=0):
    """Descriptors: ``(colour, count)`` runs one after the other, with 1.5 ΔE of noise."""
    rng = np.random.default_rng(rng_seed)
    return np.concatenate([c + rng.normal(0, 1.5, (n, 6)) for c, n in runs])


def test_the_change_point_is_where_the_colours_change():
    assert colour_change(_colours((A, 20), (B, 15)), ColourCutConfig()) == 20
    assert colour_change(_colours((A, 5), (B, 5)), ColourCutConfig()) == 5  # views on each side suffice


def test_a_few_views_at_either_end_are_cut_off_when_the_change_is_large():
    # someone seen twice before walking out through a door, the one who walked in seen on (simulated
    # moving seed 18 frame 150: two views, 36.7 ΔE)
    far = B + np.array([0.0, 20.0, 0.0, 0.0, 0.0, 0.0])  # 50 ΔE from A
    assert colour_change(_colours((A, 2), (far, 30)), ColourCutConfig()) == 2
    assert colour_change(_colours((far, 30), (A, 3)), ColourCutConfig()) == 30
    assert colour_change(_colours((A, 2), (far, 30)), ColourCutConfig(end_views=0)) is None


def test_crops_like_neither_part_next_to_the_change_take_no_side():
    # one person walks out of view as another walks in at that spot; the two crops between show both
    # (simulated moving seed 18 frames 668 and 672: 27.8 / 17.6 and 19.7 / 22.5 ΔE from the two parts)
    nearer_b = A + np.array([0.0, 20.0, 16.0, 0.0, 0.0, 0.0])  # 25.6 ΔE from A, 18.9 from B
    nearer_a = A + np.array([0.0, 10.0, 16.0, 0.0, 0.0, 0.0])  # 18.9 from A, 25.6 from B
    colours = _colours((A, 20), (nearer_b, 1), (nearer_a, 1), (B, 15))
    assert colour_change(colours, ColourCutConfig()) in (20, 21, 22)
    # crops like the *other* part still take sides, and here they block every split (as before)
    assert colour_change(_colours((A, 20), (B, 1), (A, 1), (B, 15)), ColourCutConfig()) is None


def test_a_track_on_three_people_is_cut_where_each_begins():
    # the largest change of the medians fell inside the middle person's views, which are like neither
    # part (held-out moving seed 22 frame 629): the cut moves to an end of them, the rest is cut again
    C = A + np.array([0.0, 15.0, 30.0, 0.0, 0.0, 0.0])  # 33.5 ΔE from A and from B
    cfg = ColourCutConfig()
    for seed in range(10):
        colours = _colours((A, 40), (C, 15), (B, 30), rng_seed=seed)
        m = colour_change(colours, cfg)
        assert m in (40, 55)
        rest = colour_change(colours[:m], cfg) if m == 55 else m + colour_change(colours[m:], cfg)
        assert {m, rest} == {40, 55}


@pytest.mark.parametrize(
    "runs",
    [
        ((A, 40),),  # one person
        ((A, 20), (A + np.array([0, 10, 0, 0, 0, 0]), 20)),  # the same person in other light
        ((A, 20), (B, 3), (A, 20)),  # a neighbour's colours for a few frames (a box paired wrongly)
        ((A, 4), (A + np.array([0, 20, 0, 0, 0, 0]), 30)),  # too few views before a change under 30 ΔE
        ((A, 1), (B + np.array([0, 20, 0, 0, 0, 0]), 30)),  # one view before a large change
        (
            (A + np.array([0, 40, 0, 0, 0, 0]), 1),
            (A, 1),
            (B + np.array([0, 20, 0, 0, 0, 0]), 30),
        ),  # two, unalike
    ],
)
def test_no_cut_without_a_lasting_change(runs):
    assert colour_change(_colours(*runs), ColourCutConfig()) is None


def test_no_cut_between_two_inconsistent_parts():
    rng = np.random.default_rng(1)
    mixed = A + rng.normal(0, 20, (40, 6))  # colours all over the place: nobody's in particular
    assert colour_change(mixed, ColourCutConfig(max_spread=8.0)) is None


def _walk(n=60, change=30, every=2):
    """One observation per frame walking along x at 1 m/s; colours A before frame ``change`` and B from
    it on (every ``every``-th frame described, as with a camera at a lower rate)."""
    out = []
    for i in range(n):
        app = (A if i < change else B).copy()
        if i % every:
            app[:] = np.nan
        out.append(
            Observations(
                T0 + i * 100_000_000,
                np.array([[0.1 * i, 0.0]]),
                np.eye(2)[None] * 0.0025,
                ("fused",),
                np.ones(1),
                app[None].astype(np.float32),
                np.arange(1),
            )
        )
    return out


def test_a_tracklet_is_cut_where_it_went_on_with_someone_else():
    obs = _walk()
    tracklets = {4: [(i, 0) for i in range(60)]}
    cut, pairs = cut_colour_changes(obs, tracklets)
    assert pairs == [(4, 5)]
    assert sorted(cut) == [4, 5]  # the first piece keeps the id, the later one gets a new one
    assert [i for i, _ in cut[4]] == list(range(29))  # halfway between the last A and the first B
    assert [i for i, _ in cut[5]] == list(range(29, 60))
    assert len(tracklets[4]) == 60  # the input is not modified
    same, pairs = cut_colour_changes(_walk(change=100), tracklets)
    assert pairs == []
    assert same == tracklets


def test_the_cut_goes_where_the_track_went_unobserved_between_the_two_people():
    # moving seed 11 of simulator version 6, frame 270: one person walked out of a door as another came
    # in; the track missed the frames between them, and the cut halfway between the last described
    # observation of the one and the first of the other gave the other's track two frames of the first
    obs = _walk(n=80, change=40, every=8)  # described: ..., 24, 32 (A); 40, 48, ... (B)
    hits = [(i, 0) for i in range(80) if not 38 <= i <= 39]  # the track saw nobody in frames 38-39
    cut, pairs = cut_colour_changes(obs, {4: hits})
    assert pairs == [(4, 5)]
    assert cut[4][-1][0] == 37
    assert cut[5][0][0] == 40  # halfway between frames 32 and 40 would be 36
    hits = [(i, 0) for i in range(80) if i not in (34, 37, 38)]  # two misses: the longer one decides
    cut, _ = cut_colour_changes(obs, {4: hits})
    assert cut[5][0][0] == 39


def test_stamp_jitter_and_dropped_frames_are_no_miss():
    # a real recording's frame stamps jitter by milliseconds and a sensor drops frames: without a missed
    # frame the cut stays halfway, and a miss still decides
    rng = np.random.default_rng(3)
    obs = [
        replace(o, stamp_ns=o.stamp_ns + int(rng.integers(-4_000_000, 4_000_000)))
        for o in _walk(n=80, change=40, every=8)
    ]
    cut, _ = cut_colour_changes(obs, {4: [(i, 0) for i in range(80)]})
    assert cut[5][0][0] == 36  # halfway between frames 32 and 40
    cut, _ = cut_colour_changes(obs, {4: [(i, 0) for i in range(80) if i != 38]})
    assert cut[5][0][0] == 39
    dropped = _walk(n=81, change=40, every=8)
    del dropped[37]  # the sensor dropped a frame: the stamps jump, the track missed nothing
    cut, _ = cut_colour_changes(dropped, {4: [(i, 0) for i in range(80)]})
    assert cut[5][0][0] == 36  # halfway between frames 32 and 39 (the B colours' first)


def test_the_cut_goes_where_the_track_jumped_from_one_person_to_the_other():
    # moving seed 50 of simulator version 6, frame 558: a track followed person 1 walking past person 4,
    # who stood 0.4 m behind them on the same bearing; person 1 was hidden and the track went on with person
    # 4, seen by the laser alone until person 4 walked off, 1.3 s and a 3-frame miss later. The cut at that
    # miss gave the track 10 frames of person 4: two identity switches
    obs = []
    for i in range(80):
        if i < 30:
            xy, app = (0.1 * i, 0.0), A  # A walks along x at 1 m/s, described every other frame
        else:
            xy, app = (3.0 + 0.1 * max(0, i - 47), 0.4), B  # B stands 0.4 m aside, then walks on
        described = (i < 30 and i % 2 == 0) or (i >= 50 and i % 2 == 0)
        obs.append(
            Observations(
                T0 + i * 100_000_000,
                np.array([xy]),
                np.eye(2)[None] * 0.0025,
                ("fused",),
                np.ones(1),
                (app if described else np.full(6, np.nan))[None].astype(np.float32),
                np.arange(1),
            )
        )
    hits = [(i, 0) for i in range(80) if not 46 <= i <= 48]  # the longest miss: frames 46-48
    cut, pairs = cut_colour_changes(obs, {4: hits})
    assert pairs == [(4, 5)]
    assert cut[4][-1][0] == 29
    assert cut[5][0][0] == 30
    cut, _ = cut_colour_changes(obs, {4: hits}, ColourCutConfig(jump_gain=0.0))  # the rule off
    assert cut[5][0][0] == 49
    cut, _ = cut_colour_changes(obs, {4: hits}, ColourCutConfig(jump_gain=0.5))  # a 0.4 m jump is no 0.5
    assert cut[5][0][0] == 49


def test_the_pieces_of_a_tracklet_cut_twice_are_paired_in_time_order():
    C = A + np.array([0.0, 0.0, 30.0, 0.0, 0.0, 0.0])
    obs = _walk(n=90, change=50)
    for i in range(70, 90, 2):  # a third person from frame 70 on
        obs[i] = replace(obs[i], appearance=C[None].astype(np.float32))
    cut, pairs = cut_colour_changes(obs, {2: [(i, 0) for i in range(90)]})
    assert len(cut) == 3
    firsts = {tid: h[0][0] for tid, h in cut.items()}
    assert [firsts[a] < firsts[b] for a, b in pairs] == [True, True]
    assert pairs[0][1] == pairs[1][0]  # the middle piece follows the first and precedes the last


def test_stitching_does_not_join_again_the_two_people_a_cut_separated():
    # colours 18 ΔE apart: within a motion link's 25 ΔE, so stitching alone joined the pieces again
    # (moving seeds 1-20 of simulator version 6: four such links, each between two people, one leaving
    # view as the other entered at the same spot)
    C = A + np.array([0.0, 18.0, 0.0, 0.0, 0.0, 0.0])
    assert 15.0 < appearance_distance(A.astype(np.float32), C.astype(np.float32)) < 25.0
    obs = [
        replace(o, appearance=C[None].astype(np.float32)) if i >= 30 and i % 2 == 0 else o
        for i, o in enumerate(_walk())
    ]
    base = OfflineConfig(
        tracker=UkfTrackerConfig(max_coast_s=1.0, appearance_weight=0.1, appearance_gate=40.0)
    )
    res = track_offline(obs, config=base)
    assert len(res.track_ids()) == 2


def test_offline_tracking_gives_the_one_who_took_over_a_track_of_their_own():
    # someone walks out of sight just as another walks on from where they were: one smooth path, and
    # colours close enough for the online association (under its 40 ΔE gate) but not for stitching
    obs = _walk()
    base = OfflineConfig(
        tracker=UkfTrackerConfig(max_coast_s=1.0, appearance_weight=0.1, appearance_gate=40.0)
    )
    assert len(track_offline(obs, config=replace(base, colour_cuts=None)).track_ids()) == 1
    res = track_offline(obs, config=base)
    assert len(res.track_ids()) == 2
    first = {p.track_id for f in res.frames[:25] for p in f.points}
    last = {p.track_id for f in res.frames[35:] for p in f.points}
    assert len(first) == len(last) == 1
    assert first != last


def test_a_tracklet_claims_the_described_detections_its_colours_turned_down():
    # the other person's colours are 60 ΔE from the first's, beyond the online association's 40 ΔE gate:
    # the track goes on through the other's undescribed detections (odd frames) and coasts over their
    # described ones (even frames), which nobody takes (moving seed 14 of simulator version 6, frame
    # 422); the tracklet then showed only the first person's colours, and nothing cut it
    far = A + np.array([0.0, 60.0, 0.0, 0.0, 0.0, 0.0])
    obs = [
        replace(o, appearance=far[None].astype(np.float32)) if i >= 30 and i % 2 == 0 else o
        for i, o in enumerate(_walk())
    ]
    base = OfflineConfig(
        tracker=UkfTrackerConfig(max_coast_s=1.0, appearance_weight=0.1, appearance_gate=40.0)
    )
    unclaimed = track_offline(obs, config=replace(base, claim=None))
    assert len(unclaimed.track_ids()) == 1
    assert not any(f.points and f.points[0].det_index >= 0 for f in unclaimed.frames[30::2])
    res = track_offline(obs, config=base)
    assert len(res.track_ids()) == 2
    ids = [{p.track_id for p in f.points} for f in res.frames]
    assert set().union(*ids[:29]) != set().union(*ids[31:])
    assert all(len(f.points) == 1 and f.points[0].det_index >= 0 for f in res.frames[30::2])  # claimed


def test_bad_options_are_refused():
    with pytest.raises(ValueError, match="positive"):
        ColourCutConfig(min_change=0.0)
    with pytest.raises(ValueError, match="positive"):
        ColourCutConfig(views=0)
    with pytest.raises(ValueError, match="end_views"):
        ColourCutConfig(end_views=-1)
    with pytest.raises(ValueError, match="jump_gain"):
        ColourCutConfig(jump_gain=-0.1)
    with pytest.raises(ValueError, match="jump_context_s"):
        ColourCutConfig(jump_context_s=0.0)


def _change_by_brute_force(colours, cfg):
    """The definition, split by split with numpy's medians: the split of largest change that passes."""

    def passing(splits, min_change):
        best = None
        for m in splits:
            before, after = colours[:m], colours[m:]
            meds = np.stack([np.median(before, axis=0), np.median(after, axis=0)])
            change = appearance_matrix(meds[:1], meds[1:])[0, 0]
            if change < min_change or (best is not None and change <= best[0]):
                continue
            d_b, d_a = appearance_matrix(before, meds), appearance_matrix(after, meds)
            if max(np.median(d_b[:, 0]), np.median(d_a[:, 1])) > cfg.max_spread:
                continue
            # the views next to the split that are like one part or the other (within min_change)
            end = [d for d in d_b if min(d) < cfg.min_change][-cfg.views :]
            start = [d for d in d_a if min(d) < cfg.min_change][: cfg.views]
            if not end or not start or any(d[0] > d[1] for d in end) or any(d[1] > d[0] for d in start):
                continue
            best = (change, m)
        return best

    n = len(colours)
    best = passing(range(cfg.views, n - cfg.views + 1), cfg.min_change)
    if best is not None:  # moved to an end of the views around it that are like neither part
        m = best[1]
        meds = np.stack([np.median(colours[:m], axis=0), np.median(colours[m:], axis=0)])
        like_neither = [min(d) >= cfg.min_change for d in appearance_matrix(colours, meds)]
        run = [k for k in range(n) if all(like_neither[min(k, m) : max(k, m - 1) + 1])]
        if run:
            lo, hi = min(run), max(run) + 1
            near = appearance_matrix(colours[lo:hi], meds).mean(axis=0)
            best = (best[0], hi if near[0] < near[1] else lo)
    if best is None:  # at either end, end_views to views - 1 descriptors when the change is twice as large
        ends = [
            m for k in range(cfg.end_views or cfg.views, cfg.views) if n - k >= cfg.views for m in (k, n - k)
        ]
        best = passing(ends, 2 * cfg.min_change)
    return None if best is None else best[1]


def test_the_change_point_is_the_definitions_on_random_sequences():
    rng = np.random.default_rng(3)
    C = A + np.array([0.0, 0.0, 25.0, 0.0, 10.0, 0.0])
    found = by_ends = 0
    for case in range(300):
        runs = [
            ([A, B, C][rng.integers(3)], int(rng.integers(1, 30)), float(rng.choice([1.0, 3.0, 8.0])))
            for _ in range(rng.integers(1, 4))
        ]
        if case % 2:  # a short run at one end, the end rule's case
            short = ([A, B + np.array([0, 20, 0, 0, 0, 0]), C][rng.integers(3)], int(rng.integers(1, 6)), 1.0)
            runs = [short, *runs] if case % 4 == 1 else [*runs, short]
        colours = np.concatenate([c + rng.normal(0, s, (n, 6)) for c, n, s in runs])
        colours = np.round(colours, int(rng.integers(0, 3)))  # rounding makes ties between splits
        cfg = ColourCutConfig(
            min_change=float(rng.choice([8.0, 15.0])),
            views=int(rng.choice([3, 5])),
            end_views=int(rng.choice([0, 1, 2])),
        )
        expected = _change_by_brute_force(colours, cfg)
        assert colour_change(colours, cfg) == expected
        found += expected is not None
        by_ends += expected != _change_by_brute_force(colours, replace(cfg, end_views=0))
    assert 40 < found < 260  # both outcomes were exercised
    assert by_ends > 10  # and the end rule decided in some


def test_running_medians_are_numpys():
    from studio.track.colour_cuts import _running_medians

    x = np.round(np.random.default_rng(4).normal(0, 5, (41, 6)), 0)  # ties and even lengths
    got = _running_medians(x)
    for m in range(1, 42):
        np.testing.assert_array_equal(got[m - 1], np.median(x[:m], axis=0))
