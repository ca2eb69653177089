"""Identity-swap repair: two tracklets that exchanged people in an encounter get their tails back."""

from __future__ import annotations

import numpy as np
import pytest

from studio.track import Observations
from studio.track.offline import OfflineConfig, track_offline
from studio.track.swaps import SwapConfig, repair_swaps

RED = np.array([53.0, 80.0, 67.0, 40.0, 60.0, 50.0])
BLUE = np.array([32.0, 79.0, -108.0, 30.0, 20.0, -60.0])
T0 = 1_700_000_000_000_000_000


def _frames(n=60, meet=(20, 40), described=True, stride=2, rng_seed=0):
    """P (red) walks along y = +0.6, Q (blue) along y = -0.6; between ``meet`` frames they walk 0.2 m
    apart. Row 0 is always P, row 1 always Q."""
    rng = np.random.default_rng(rng_seed)
    out = []
    for i in range(n):
        gap = 0.1 if meet[0] <= i <= meet[1] else 0.6
        xy = np.array([[0.1 * i, gap], [0.1 * i, -gap]])
        app = np.stack([RED, BLUE]) + rng.normal(0, 1.5, (2, 6))
        if not described or i % stride:  # the camera describes every other frame
            app[:] = np.nan
        out.append(
            Observations(
                T0 + i * 100_000_000,
                xy,
                np.tile(np.eye(2) * 0.01, (2, 1, 1)),
                ("fused", "fused"),
                np.ones(2),
                app.astype(np.float32),
                np.arange(2),
            )
        )
    return out


def _rows(hits):
    return {r for _, r in hits}


def test_swapped_tails_are_exchanged_back():
    obs = _frames(stride=1)
    cut = 30  # the online tracker swapped people inside the encounter
    tracklets = {
        7: [(i, 0) for i in range(cut)] + [(i, 1) for i in range(cut, 60)],
        9: [(i, 1) for i in range(cut)] + [(i, 0) for i in range(cut, 60)],
    }
    fixed, swaps = repair_swaps(obs, tracklets)
    assert swaps == 1
    assert _rows(fixed[7]) == {0}
    assert _rows(fixed[9]) == {1}
    assert [i for i, _ in fixed[7]] == list(range(60))  # every frame kept, in order
    # with the camera on every other frame only, the frame next to the swap is undecided
    fixed, _ = repair_swaps(_frames(stride=2), tracklets)
    assert sum(r != 0 for _, r in fixed[7]) <= 1
    assert _rows(tracklets[7]) == {0, 1}  # the input is not modified


@pytest.mark.parametrize("described", [True, False])
def test_consistent_or_undescribed_tracklets_are_left_alone(described):
    obs = _frames(described=described)
    right = {1: [(i, 0) for i in range(60)], 2: [(i, 1) for i in range(60)]}
    assert repair_swaps(obs, right) == (right, 0)
    swapped = {1: [(i, 0) for i in range(30)] + [(i, 1) for i in range(30, 60)]}
    swapped[2] = [(i, 1) for i in range(30)] + [(i, 0) for i in range(30, 60)]
    _, n = repair_swaps(obs, swapped)
    assert n == (1 if described else 0)  # without colours nothing tells the swap apart


def test_people_who_never_come_close_are_not_an_encounter():
    obs = _frames(meet=(100, 100))  # always 1.2 m apart
    swapped = {1: [(i, 0) for i in range(30)] + [(i, 1) for i in range(30, 60)]}
    swapped[2] = [(i, 1) for i in range(30)] + [(i, 0) for i in range(30, 60)]
    assert repair_swaps(obs, swapped)[1] == 0


def test_track_offline_runs_the_repair_and_can_skip_it():
    """The two walkers close in by 0.5 m each in one frame: the online pass swaps them; the repair gives
    each final track one person (one det row) again, but for the frame of the jump. The motion-based
    re-decision of encounters is left out: walkers that jump 0.5 m in one frame and then walk 0.2 m apart
    in step give it nothing to go by (it may move a block of frames either way; colours are the swap
    repair's business)."""
    obs = _frames()

    def strays(res):
        out = []
        for tid in res.track_ids():
            rows = [
                p.det_index for f in res.frames for p in f.points if p.track_id == tid and p.det_index >= 0
            ]
            out.append(min(rows.count(0), rows.count(1)))
        return out

    # (the colour cuts, which would also catch this swap, are left out: this pins down the repair)
    on = track_offline(obs, config=OfflineConfig(encounters=None, colour_cuts=None))
    off = track_offline(obs, config=OfflineConfig(swaps=None, encounters=None, colour_cuts=None))
    assert len(on.track_ids()) == len(off.track_ids()) == 2
    assert max(strays(off)) >= 20  # swapped for the second half
    assert max(strays(on)) <= 1


def _bounce(sim, gap=(34, 41)):
    """P (red) and Q (blue) walk along x at 1 m/s, 2 m apart, and close in to 0.5 m around frame 50 as if
    they bounced off each other; in truth they crossed: the colours change lanes after frame 50. Neither
    is observed in the frames of ``gap``."""
    rng = np.random.default_rng(1)
    out = []
    for i in range(100):
        t = 0.1 * i
        half = 1.0 - 0.75 * np.exp(-((t - 5.0) ** 2) / 2.0)
        xy = np.array([[t, half], [t, -half]]) if not gap[0] <= i < gap[1] else np.zeros((0, 2))
        colours = np.stack([RED, BLUE] if i <= 50 else [BLUE, RED]) + rng.normal(0, 1.5, (2, 6))
        out.append(sim.points(T0 + i * 100_000_000, xy, "fused", colours))
    return out


def test_the_repair_also_judges_the_stitched_tracks(sim):
    """A gap just before the encounter cuts both tracklets there, leaving them too few described
    observations before it for the repair to judge; the stitched tracks have enough, and each ends with
    the colours it started with."""
    obs = _bounce(sim)
    res = track_offline(obs)
    assert len(res.track_ids()) == 2
    for tid in res.track_ids():
        colours = [
            obs[i].appearance[p.det_index]  # type: ignore[index]
            for i, f in enumerate(res.frames)
            for p in f.points
            if p.track_id == tid and p.det_index >= 0
        ]
        first, last = np.median(colours[:10], axis=0), np.median(colours[-10:], axis=0)
        assert np.allclose(first, last, atol=5.0), (tid, first, last)


def test_swap_config_is_checked():
    with pytest.raises(ValueError, match="positive"):
        SwapConfig(close_m=0.0)
    with pytest.raises(ValueError, match="positive"):
        SwapConfig(views=0)
