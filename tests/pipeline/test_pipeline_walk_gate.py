"""Without a camera a track must walk somewhere (``LabelOptions.min_walk_m``): chair and table legs that a
moving robot sees too briefly for the static map to judge stand still, and a track that hops between them
does so across gaps. Offline the whole track counts: someone who walks in and then stands is kept for all
of it."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from studio.detect.laser.base import KIND_PAIR, LaserDetections
from studio.geometry.se import Pose2
from studio.pipeline import LabelOptions
from studio.pipeline.label import fuse_all, longest_walk, track_all
from studio.pipeline.perceive import PerceptionFrame

HZ = 10
N = 60  # 6 s
STANDS = np.array([3.0, 2.5])  # someone (or a chair) who never moves


def _walker(k: int) -> np.ndarray:
    """Walks 2 m along x in the first 2 s (1 m/s), then stands."""
    return np.array([1.0 + min(k, 2 * HZ) / HZ, -1.0])


def _stamp(k: int) -> int:
    return k * 1_000_000_000 // HZ


def _frames() -> list[PerceptionFrame]:
    no_points = (np.zeros((1, 2)), np.zeros((0, 2), np.float32), np.zeros(1, np.int32), np.zeros((1, 3)))
    frames = []
    for k in range(N):
        xy = np.array([_walker(k), STANDS])
        laser = LaserDetections(
            xy, np.full(2, 0.8), np.full(2, KIND_PAIR), np.full(2, 0.2), (np.zeros(0, int), np.zeros(0, int))
        )
        frames.append(PerceptionFrame(k, _stamp(k), Pose2(), None, None, laser, np.full(2, 0.3), *no_points))
    return frames


def _labelled(options: LabelOptions) -> tuple[int, int]:
    """Frames in which the walker / the one who stands is labelled."""
    frames = _frames()
    fused = fuse_all(frames, None, options)
    labels, _ = track_all(frames, fused, options, has_camera=False)
    near = [[float(np.min([np.hypot(p.x - c[0], p.y - c[1]) for p in lf.people], initial=9.0))
             for c in (_walker(lf.frame), STANDS)] for lf in labels]  # fmt: skip
    return sum(d[0] < 0.2 for d in near), sum(d[1] < 0.2 for d in near)


def test_without_a_camera_a_track_that_never_walks_is_dropped() -> None:
    walker, stands = _labelled(replace(LabelOptions(sources="laser"), static_filter=False))
    assert walker == N  # kept throughout, also the 4 s it stood
    assert stands == 0


def test_zero_turns_the_gate_off() -> None:
    walker, stands = _labelled(replace(LabelOptions(sources="laser"), static_filter=False, min_walk_m=0.0))
    assert walker == N
    assert stands == N


@pytest.mark.parametrize("bad", [-0.5, float("nan"), float("inf")])
def test_a_negative_or_nan_walk_is_refused(bad: float) -> None:
    with pytest.raises(ValueError, match="min_walk_m"):
        LabelOptions(min_walk_m=bad)


def _obs(xy: np.ndarray, stamps_s: np.ndarray) -> list[tuple[int, float, float]]:
    return [(int(t * 1e9), float(x), float(y)) for t, (x, y) in zip(stamps_s, xy, strict=True)]


def test_longest_walk_is_the_diameter_of_the_longest_stretch() -> None:
    t = np.arange(30) / HZ
    xy = np.column_stack([np.linspace(0.0, 2.0, 30), np.zeros(30)])
    assert longest_walk(_obs(xy, t)) == pytest.approx(2.0, abs=0.1)
    # the same way with a 1 s gap in the middle: two stretches of about 1 m
    t_gap = np.where(np.arange(30) < 15, t, t + 1.0)
    assert longest_walk(_obs(xy, t_gap)) == pytest.approx(1.0, abs=0.15)


def test_hops_between_places_across_gaps_are_no_walk() -> None:
    """Three chair legs metres apart, each held for a second, a second's gap between them."""
    rng = np.random.default_rng(0)
    places = np.array([[0.0, 0.0], [3.0, 1.0], [1.0, 4.0]])
    xy = np.concatenate([p + rng.normal(0.0, 0.03, (10, 2)) for p in places])
    t = np.concatenate([2.0 * i + np.arange(10) / HZ for i in range(3)])
    assert longest_walk(_obs(xy, t)) < 0.2


def test_jumping_between_two_legs_every_frame_is_no_walk() -> None:
    """A track that takes one of two chair legs 0.4 m apart in each frame, mostly the first."""
    pick = np.array([0, 0, 1, 0, 0, 0, 1, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0])
    xy = np.array([[0.0, 0.0], [0.4, 0.0]])[pick]
    assert longest_walk(_obs(xy, np.arange(20) / HZ)) < 0.1


def test_fewer_observations_than_the_median_window_walk_nowhere() -> None:
    xy = np.array([[0.0, 0.0], [1.0, 0.0], [2.0, 0.0], [3.0, 0.0]])
    assert longest_walk(_obs(xy, np.arange(4) / HZ)) == 0.0


def _labelled_with_occupied(walker_occ: float, stands_occ: float) -> tuple[int, int]:
    """As :func:`_labelled` (laser only), with the static map's occupied share at each detection set."""
    options = replace(LabelOptions(sources="laser"), static_filter=False)
    frames = _frames()
    occupied = np.array([walker_occ, stands_occ])
    fused = [replace(fr, occupied=occupied) for fr in fuse_all(frames, None, options)]
    labels, _ = track_all(frames, fused, options, has_camera=False)
    near = [[float(np.min([np.hypot(p.x - c[0], p.y - c[1]) for p in lf.people], initial=9.0))
             for c in (_walker(lf.frame), STANDS)] for lf in labels]  # fmt: skip
    return sum(d[0] < 0.2 for d in near), sum(d[1] < 0.2 for d in near)


def test_a_walk_over_places_seen_half_occupied_is_no_walk() -> None:
    """Furniture that a moving robot's beams graze from some places and hit from others looks half occupied
    to the static map; a track that "walks" over such places (hopping from one table leg to the next) did
    not walk. A walk through places seen free counts as before; no share known (NaN) counts too."""
    assert _labelled_with_occupied(0.1, 0.1) == (N, 0)
    assert _labelled_with_occupied(float("nan"), 0.1) == (N, 0)
    assert _labelled_with_occupied(0.5, 0.1) == (0, 0)


def test_a_leg_of_a_split_pair_is_where_its_pair_was() -> None:
    """A leg the tracker took from a split pair (a row past the observations) counts as on the pair's
    place: a track on the legs of a pair on half-occupied places walks no more than one on the pair."""
    from studio.track.base import TrackFrame, TrackPoint, TrackResult

    frames = []
    no_points = (np.zeros((1, 2)), np.zeros((0, 2), np.float32), np.zeros(1, np.int32), np.zeros((1, 3)))
    for k in range(N):
        xy = _walker(k)[None]
        legs = np.array([[xy[0] + [0.0, 0.1], xy[0] - [0.0, 0.1]]])
        laser = LaserDetections(xy, [0.8], [KIND_PAIR], [0.2], (np.zeros(0, int),), legs=legs)
        frames.append(PerceptionFrame(k, _stamp(k), Pose2(), None, None, laser, np.full(1, 0.3), *no_points))
    options = replace(LabelOptions(sources="laser"), static_filter=False, recover_radius=0.0)

    def taking(row: int, occupied: float) -> int:
        def tracker(observations: list, config: object = None) -> TrackResult:
            assert observations[0].alt_of is not None
            assert len(observations[0].xy) == 3  # the pair and its two legs
            return TrackResult(
                tuple(
                    TrackFrame(o.stamp_ns, (TrackPoint(0, o.xy[row], np.eye(2) * 0.01, row),))
                    for o in observations
                )
            )

        fused = [replace(fr, occupied=np.array([occupied])) for fr in fuse_all(frames, None, options)]
        labels, _ = track_all(frames, fused, options, has_camera=False, tracker=tracker)
        return sum(len(lf.people) for lf in labels)

    assert taking(0, 0.1) == taking(1, 0.1) == N
    assert taking(0, 0.5) == taking(1, 0.5) == 0


def test_a_recovered_cluster_is_judged_by_the_occupied_share_of_its_points() -> None:
    """Where a track coasted, the scan points at its place become an observation (``recover_missed``); the
    walk gate judges that place by the static map's occupied share of those points, as it judges a
    detection (session 63: on leg_tracker's ``negative_2.bag`` at 0.5° beams, clusters recovered along the
    edge of furniture made a 2 s "walk" of 1.4 m and kept a false track for 40 s)."""
    from studio.track.base import TrackFrame, TrackPoint, TrackResult

    ring = 0.08 * np.array([[np.cos(a), np.sin(a)] for a in np.linspace(0.0, np.pi, 6)])
    frames = []
    for k in range(N):
        pts = (_walker(k) + ring).astype(np.float32)
        laser = LaserDetections(np.zeros((0, 2)), np.zeros(0), np.zeros(0, int), np.zeros(0), ())
        frames.append(
            PerceptionFrame(
                k, _stamp(k), Pose2(), None, None, laser, np.zeros(0), np.zeros((1, 2)), pts,
                np.array([len(pts)], np.int32), np.zeros((1, 3)),
            )
        )  # fmt: skip
    options = replace(LabelOptions(sources="laser"), static_filter=False)

    def tracker(observations: list, config: object = None) -> TrackResult:
        """Coasts along the walker (first pass), then takes what was recovered there."""
        return TrackResult(
            tuple(
                TrackFrame(o.stamp_ns, (TrackPoint(0, _walker(k), np.eye(2) * 0.01, len(o.xy) - 1),))
                for k, o in enumerate(observations)
            )
        )

    def labelled(share: float) -> int:
        fused = [
            replace(fr, occupied=np.zeros(0), scan_occupied=np.full(len(fr.scan_points), share, np.float16))
            for fr in fuse_all(frames, None, options)
        ]
        labels, used = track_all(frames, fused, options, has_camera=False, tracker=tracker)
        assert all(len(fr.observations) == 1 for fr in used)  # each frame's cluster was recovered
        for fr in used:
            assert fr.occupied is not None
            assert fr.occupied[0] == pytest.approx(share, abs=1e-3)
        return sum(len(lf.people) for lf in labels)

    assert labelled(0.1) == N
    assert labelled(0.5) == 0
