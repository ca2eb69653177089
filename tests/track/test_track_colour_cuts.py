"""Colour cuts: a tracklet whose clothing colours change for good went on with someone else."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from studio.track import Observations
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


@pytest.mark.parametrize(
    "runs",
    [
        ((A, 40),),  # one person
        ((A, 20), (A + np.array([0, 10, 0, 0, 0, 0]), 20)),  # the same person in other light
        ((A, 20), (B, 3), (A, 20)),  # a neighbour's colours for a few frames (a box paired wrongly)
        ((A, 4), (B, 30)),  # too few views before the change
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
    cut, n = cut_colour_changes(obs, tracklets)
    assert n == 1
    assert sorted(cut) == [4, 5]  # the first piece keeps the id, the later one gets a new one
    assert [i for i, _ in cut[4]] == list(range(29))  # halfway between the last A and the first B
    assert [i for i, _ in cut[5]] == list(range(29, 60))
    assert len(tracklets[4]) == 60  # the input is not modified
    same, n = cut_colour_changes(_walk(change=100), tracklets)
    assert n == 0
    assert same == tracklets


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


def test_bad_options_are_refused():
    with pytest.raises(ValueError, match="positive"):
        ColourCutConfig(min_change=0.0)
    with pytest.raises(ValueError, match="positive"):
        ColourCutConfig(views=0)
