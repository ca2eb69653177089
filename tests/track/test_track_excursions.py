"""Excursions: a few observations a track held on someone else's way are taken from it."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from studio.track import Observations
from studio.track.excursions import ExcursionConfig, detach_excursions
from studio.track.offline import OfflineConfig

T0 = 1_700_000_000_000_000_000
DT = 100_000_000  # 10 Hz


def _frames(rows_per_frame):
    out = []
    for i, rows in enumerate(rows_per_frame):
        xy = np.asarray(rows, float).reshape(-1, 2)
        n = len(xy)
        out.append(
            Observations(
                T0 + i * DT,
                xy,
                np.repeat(np.eye(2)[None] * 0.0025, n, 0),
                ("laser",) * n,
                np.ones(n),
                np.full((n, 6), np.nan, np.float32),
                np.arange(n),
                None,
            )
        )
    return out


def _walker_and_stander(n=30, grab=(14, 15), stander_seen=True):
    """Row 0: someone walking along y = 0 at 1 m/s; row 1: someone standing at (1.8, 0.45). Track 1 (the
    walker's) holds row 0 except in the frames ``grab``, where it holds the stander's row 1."""
    rows = []
    for i in range(n):
        walker = [0.4 + 0.1 * i, 0.0]
        rows.append([walker, [1.8, 0.45]] if stander_seen or i in grab else [walker])
    obs = _frames(rows)
    walker_hits = [(i, 1 if i in grab else 0) for i in range(n)]
    stander_hits = [(i, 1) for i in range(n) if i not in grab and stander_seen]
    return obs, {1: walker_hits, 2: stander_hits}


def test_a_short_run_on_someone_elses_way_is_taken():
    obs, tracks = _walker_and_stander()
    out, n = detach_excursions(obs, tracks)
    assert n == 2
    assert (14, 1) not in out[1]
    assert (15, 1) not in out[1]
    assert len(out[1]) == 28
    assert out[2] == tracks[2]
    assert len(tracks[1]) == 30  # the input is not modified


def test_a_hit_off_the_line_with_nobody_near_stays():
    # a turn or the detector's error
    obs, tracks = _walker_and_stander(grab=(14,), stander_seen=False)
    _, n = detach_excursions(obs, {1: tracks[1]})
    assert n == 0


def test_a_run_longer_than_max_hits_is_not_taken():
    obs, tracks = _walker_and_stander(grab=tuple(range(10, 20)))
    out, _ = detach_excursions(obs, tracks)
    # its ends may go (each is off the line from the walker to the stander), its middle stays
    assert all((i, 1) in out[1] for i in range(12, 18))


def test_a_hit_close_to_the_line_stays():
    obs, tracks = _walker_and_stander()
    # the deviation threshold above the stander's 0.45 m offset: nothing is off the line by that much
    _, n = detach_excursions(obs, tracks, ExcursionConfig(deviation=0.5))
    assert n == 0


def test_a_span_longer_than_max_s_stays():
    obs, tracks = _walker_and_stander()
    _, n = detach_excursions(obs, tracks, ExcursionConfig(max_s=0.2))
    assert n == 0


def test_offline_config_can_skip_it():
    assert OfflineConfig().excursions == ExcursionConfig()
    assert OfflineConfig(excursions=None).excursions is None


@pytest.mark.parametrize(
    "kw",
    [
        {"deviation": 0.0},
        {"max_hits": 0},
        {"max_s": -1.0},
        {"velocity_s": 0.0},
        {"stood_s": -1.0},
        {"stood_speed": -0.1},
        {"colour_margin": -1.0},
        {"colour_views": 0},
    ],
)
def test_bad_config(kw):
    with pytest.raises(ValueError, match="must be"):
        ExcursionConfig(**kw)


def _hand_over(n=30, grab=(18, 19), walker_leaves=20, stander_from=21):
    """Row 0: someone walking along y = 0 at 1 m/s until frame ``walker_leaves``; row 1: someone standing at
    (2.5, 0.4) from frame 18 on. Track 1 (the walker's) holds row 0, and row 1 in the frames ``grab`` at
    its end; track 2 (the stander's) holds row 1 from ``stander_from`` on."""
    rows = []
    for i in range(n):
        row = [[0.4 + 0.1 * i, 0.0]] if i < walker_leaves and i not in grab else []
        if i >= 18:
            row.append([2.5, 0.4])
        rows.append(row)
    obs = _frames(rows)
    walker_hits = [(i, 0) for i in range(walker_leaves) if i not in grab] + [
        (i, len(rows[i]) - 1) for i in grab
    ]
    walker_hits.sort()
    stander_hits = [(i, len(rows[i]) - 1) for i in range(stander_from, n)]
    return obs, {1: walker_hits, 2: stander_hits}


def test_a_tail_on_the_person_whose_track_goes_on_is_taken():
    obs, tracks = _hand_over()
    out, n = detach_excursions(obs, tracks)
    assert n == 2
    assert out[1] == tracks[1][:-2]
    assert out[2] == tracks[2]
    # and without the rule, or without the track that goes on, it stays
    _, n = detach_excursions(obs, tracks, ExcursionConfig(ends=False))
    assert n == 0
    _, n = detach_excursions(obs, {1: tracks[1]})
    assert n == 0


def test_a_tail_on_the_tracks_own_way_stays():
    # the walker is seen to the end; the stander's track starts right after
    obs, tracks = _hand_over(grab=())
    _, n = detach_excursions(obs, tracks)
    assert n == 0


def test_a_head_on_the_person_whose_track_ended_is_taken():
    # in reversed time: the stander's track ends, then the walker's begins on the stander's spot
    rows = []
    for i in range(30):
        row = [[2.5, 0.4]] if i <= 12 else []
        if i >= 11:
            row.append([0.4 + 0.1 * (40 - i), 0.0])
        rows.append(row)
    obs = _frames(rows)
    stander = [(i, 0) for i in range(11)]
    walker = [(11, 0), (12, 0)] + [(i, len(rows[i]) - 1) for i in range(13, 30)]
    out, n = detach_excursions(obs, {1: walker, 2: stander})
    assert n == 2
    assert out[1] == walker[2:]
    assert out[2] == stander


def _passer_by(stander_speed=0.0):
    """Row 0: someone walking along y = 0 at 1 m/s until frame 24; row 1: someone standing at (2.5, 0.4)
    (or walking there at ``stander_speed`` m/s along x), seen in frames 0-9 and from frame 60 on. Track 1
    (the walker's) holds row 0, then row 1 in frames 24-27, after the stander was lost for 1.5 s; track 2
    (the stander's) holds row 1 in frames 0-9 and again from frame 60 (re-identified)."""
    grab = range(24, 28)
    rows = []
    for i in range(80):
        row = [[0.4 + 0.1 * i, 0.0]] if i < 24 else []
        if i < 10 or i in grab or i >= 60:
            row.append([2.5 + stander_speed * 0.1 * min(i - 9, 0), 0.4])
        rows.append(row)
    obs = _frames(rows)
    walker = [(i, 0) for i in range(24)] + [(i, 0) for i in grab]
    stander = [(i, len(rows[i]) - 1) for i in range(80) if i < 10 or i >= 60]
    return obs, {1: walker, 2: stander}


def test_a_tail_on_someone_who_stood_where_they_were_lost_is_taken():
    # held-out moving seed 26, frames 326-363: the stander is lost while the walker passes, and the
    # walker's track takes their next detections for its last ones; the stander's track goes on 3.3 s later
    obs, tracks = _passer_by()
    out, n = detach_excursions(obs, tracks)
    assert n == 4
    assert out[1] == tracks[1][:-4]
    assert out[2] == tracks[2]
    # not without the rule, not when the stander was lost longer before, not when they were walking
    for cfg in (ExcursionConfig(stood_s=0.0), ExcursionConfig(stood_s=1.0)):
        _, n = detach_excursions(obs, tracks, cfg)
        assert n == 0
    obs, tracks = _passer_by(stander_speed=0.5)
    _, n = detach_excursions(obs, tracks)
    assert n == 0


A = np.array([50.0, 10.0, 10.0, 40.0, 0.0, 0.0], np.float32)
B = A + np.array([0.0, 30.0, 0.0, 0.0, 0.0, 0.0], np.float32)  # 30 ΔE from A: another person


def _turn_and_take(first_colours=A):
    """Someone walks along y = 0 at 1 m/s (track 2, colours A) until frame 10, then turns and walks up x = 1
    (frames 13-16), where track 1 begins; track 1 then goes on with someone else walking down x = 0.4 from
    frame 17 (colours B). Track 1's first hit has ``first_colours`` (None: undescribed)."""
    rows = [[[0.1 * i, 0.0]] for i in range(11)] + [[], []]
    rows += [[[1.0, 0.8 + 0.1 * (i - 13)]] for i in range(13, 17)]
    rows += [[[0.4, 1.5 - 0.1 * (i - 17)]] for i in range(17, 41)]
    colours = {i: A if i <= 10 else B for i in [*range(0, 11, 2), *range(17, 41, 2)]}
    if first_colours is not None:
        colours[13] = first_colours
    obs = _frames(rows)
    obs = [replace(o, appearance=colours[i][None]) if i in colours else o for i, o in enumerate(obs)]
    return obs, {1: [(i, 0) for i in range(13, 41)], 2: [(i, 0) for i in range(11)]}


def test_a_head_in_the_colours_of_the_track_that_ended_is_taken():
    # simulated moving seed 12 frame 464: the person turned after their track ended, so the head lies
    # nearer the track's own path than their predicted way; its one described hit has their colours
    obs, tracks = _turn_and_take()
    out, n = detach_excursions(obs, tracks)
    assert n == 4
    assert out[1] == tracks[1][4:]
    assert out[2] == tracks[2]
    # not without the rule; not when the head shows the track's own colours, or none, or a crop like
    # nobody (20 ΔE from A, 50 from B: half hidden, or two people in one box)
    _, n = detach_excursions(obs, tracks, ExcursionConfig(colour_margin=0.0))
    assert n == 0
    for colours in (B, None, A - np.array([0.0, 20.0, 0.0, 0.0, 0.0, 0.0], np.float32)):
        obs, tracks = _turn_and_take(colours)
        _, n = detach_excursions(obs, tracks)
        assert n == 0


def test_two_tracks_along_one_path_keep_their_ends():
    # one walker's path split in two tracks (as a colour cut leaves them): each end lies on both tracks'
    # ways, closer to neither
    obs = _frames([[[0.1 * i, 0.0]] for i in range(30)])
    tracks = {1: [(i, 0) for i in range(15)], 2: [(i, 0) for i in range(15, 30)]}
    _, n = detach_excursions(obs, tracks)
    assert n == 0
