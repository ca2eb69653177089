from __future__ import annotations

import numpy as np
import pytest
from laser_synth import cast

from studio.detect.laser import KIND_BLOB, KIND_LEG, KIND_PAIR, LaserDetections, LaserDetectorError
from studio.detect.laser.classical import LEG_MODEL, ClassicalLaserDetector, LegModel, leg_basis
from studio.detect.laser.segment import FEATURE_NAMES


def _legs(xy, scores, kinds=None, width=0.12):
    n = len(xy)
    kinds = [KIND_LEG] * n if kinds is None else kinds
    return LaserDetections(
        np.array(xy, float),
        np.array(scores, float),
        np.array(kinds),
        np.full(n, width / 2.0),
        tuple(np.array([i]) for i in range(n)),
    )


@pytest.mark.parametrize(
    ("xy", "scores", "kinds", "expected"),
    [
        # two legs 0.3 m apart → one pair at the midpoint
        ([[2.0, 0.15], [2.0, -0.15]], [0.8, 0.7], None, [(KIND_PAIR, 2.0, 0.0)]),
        # too far apart → two single legs
        ([[2.0, 0.5], [2.0, -0.5]], [0.8, 0.7], None, [(KIND_LEG, 2.0, 0.5), (KIND_LEG, 2.0, -0.5)]),
        # too close → two single legs
        ([[2.0, 0.02], [2.0, -0.02]], [0.8, 0.7], None, [(KIND_LEG, 2.0, 0.02), (KIND_LEG, 2.0, -0.02)]),
        # three legs: the best pair wins, the third stays single
        (
            [[2.0, 0.0], [2.0, 0.25], [2.0, 0.7]],
            [0.9, 0.9, 0.5],
            None,
            [(KIND_PAIR, 2.0, 0.125), (KIND_LEG, 2.0, 0.7)],
        ),
        # two people side by side (legs 0.2 m apart, 0.56 m between them): two pairs, even when their inner
        # legs look more leg-like — greedy pairing by score made one person in the middle and two halves
        (
            [[4.0, -0.38], [4.0, -0.18], [4.0, 0.18], [4.0, 0.38]],
            [0.6, 0.95, 0.95, 0.6],
            None,
            [(KIND_PAIR, 4.0, -0.28), (KIND_PAIR, 4.0, 0.28)],
        ),
        # with as many pairs either way, the higher total score and then the closer legs win
        (
            [[2.0, 0.0], [2.0, 0.25], [2.0, 0.55]],
            [0.9, 0.9, 0.9],
            None,
            [(KIND_PAIR, 2.0, 0.125), (KIND_LEG, 2.0, 0.55)],
        ),
        # a leg below the leg threshold is dropped
        ([[2.0, 0.15], [2.0, -0.15]], [0.8, 0.1], None, [(KIND_LEG, 2.0, 0.15)]),
        # a blob is a person on its own and is never paired
        (
            [[3.0, 0.0], [3.0, 0.3]],
            [0.8, 0.8],
            [KIND_BLOB, KIND_LEG],
            [(KIND_LEG, 3.0, 0.3), (KIND_BLOB, 3.0, 0.0)],
        ),
        ([], [], None, []),
    ],
)
def test_pairing_table(xy, scores, kinds, expected):
    det = ClassicalLaserDetector(hidden_leg_offset=0.0)  # positions of single legs: see the next test
    legs = _legs(xy, scores, kinds) if xy else LaserDetections.empty(with_segments=True)
    people = det.people(legs)
    got = sorted(
        (int(k), round(float(x), 3), round(float(y), 3))
        for k, (x, y) in zip(people.kind, people.xy, strict=True)
    )
    assert got == sorted((k, round(x, 3), round(y, 3)) for k, x, y in expected)
    assert np.all((people.scores >= 0) & (people.scores <= 1))


def test_pairing_of_a_large_clutter_group_stays_greedy_and_disjoint():
    rng = np.random.default_rng(3)
    xy = np.stack([np.linspace(1.0, 4.0, 14), 0.3 * np.sin(np.arange(14))], 1)  # 14 legs in one chain
    people = ClassicalLaserDetector(hidden_leg_offset=0.0).people(_legs(xy, rng.uniform(0.4, 0.9, 14)))
    used = np.concatenate(list(people.segments))  # every leg in one person exactly
    assert sorted(used.tolist()) == list(range(14))


def test_single_leg_person_lies_behind_the_leg_along_the_beam():
    det = ClassicalLaserDetector(hidden_leg_offset=0.05)
    single = det.people(_legs([[3.0, 4.0]], [0.8]), origin=(0.0, 0.0))
    np.testing.assert_allclose(single.xy[0], [3.0 * 1.01, 4.0 * 1.01])  # 5 m → 5.05 m on the same ray
    from_side = det.people(_legs([[3.0, 4.0]], [0.8]), origin=(3.0, 0.0))
    np.testing.assert_allclose(from_side.xy[0], [3.0, 4.05])
    pair = det.people(_legs([[2.0, 0.15], [2.0, -0.15]], [0.8, 0.7]))
    np.testing.assert_allclose(pair.xy[0], [2.0, 0.0])  # pairs are not moved


@pytest.mark.parametrize("rng", [1.0, 2.5, 4.0])
def test_leg_position_is_the_leg_axis_not_the_lit_surface(rng):
    r = 0.06
    pts, valid = cast(circles=[(rng, 0.3, r)], walls=[(8.0, -5.0, 8.0, 5.0)])
    legs = ClassicalLaserDetector().legs(pts, valid=valid)
    k = int(np.argmin(np.hypot(legs.xy[:, 0] - rng, legs.xy[:, 1] - 0.3)))
    err = np.hypot(legs.xy[k, 0] - rng, legs.xy[k, 1] - 0.3)
    surface = np.nanmean(pts[valid & (np.hypot(pts[:, 0] - rng, pts[:, 1] - 0.3) < 2 * r)], axis=0)
    assert err < 0.02
    assert err < 0.5 * np.hypot(surface[0] - rng, surface[1] - 0.3)


@pytest.mark.parametrize("dist", [0.7, 1.2, 1.8])
def test_noisy_legs_near_the_scanner_stay_legs(dist):
    """Two legs 0.7–1.8 m away seen by a 0.25° scanner with 12 mm range noise (common 2D lidars): the dense
    returns zigzag by more than their spacing. Before the outline was averaged for the jaggedness and
    turning features, the leg model called such legs clutter (simulated people within 1.5 m: 9–17 % found)."""
    rng = np.random.default_rng(int(dist * 10))
    found = []
    for _ in range(20):
        pts, valid = cast(circles=[(dist, 0.1, 0.06), (dist, -0.1, 0.06)], walls=[(6.0, -5.0, 6.0, 5.0)],
                          step_deg=0.25)  # fmt: skip
        r = np.hypot(pts[:, 0], pts[:, 1])
        with np.errstate(invalid="ignore"):
            pts = pts * ((r + rng.normal(0.0, 0.012, len(r))) / r)[:, None]
        people = ClassicalLaserDetector().detect(pts, valid=valid)
        d = np.hypot(people.xy[:, 0] - dist - 0.04, people.xy[:, 1]) if len(people) else np.array([9.0])
        found.append(bool(np.any((d < 0.15) & (people.scores >= 0.3))))
    assert np.mean(found) >= 0.9


@pytest.mark.parametrize(
    ("step_deg", "coarse"), [(0.25, False), (0.35, False), (0.4, True), (0.5, True), (1.0, True)]
)
def test_the_beam_step_picks_the_leg_model(step_deg, coarse):
    """Scans with beams 0.38° apart or more are scored by the coarse model, finer ones by the fine model."""
    n = len(LEG_MODEL.coef)
    flat = {"mean": (0.0,) * n, "std": (1.0,) * n, "coef": (1e-9,) * n}
    det = ClassicalLaserDetector(model=LegModel(**flat, bias=-5.0), coarse_model=LegModel(**flat, bias=5.0))
    pts, valid = cast(
        circles=[(2.0, 0.1, 0.06), (2.0, -0.1, 0.06)], walls=[(6.0, -5.0, 6.0, 5.0)], step_deg=step_deg
    )
    scores = det.legs(pts, valid=valid).scores
    assert scores.size
    assert np.all((scores > 0.5) == coarse)


def test_coarse_beams_keep_legs_that_the_fine_model_drops():
    """Two legs 2–3 m away seen by a 1° scanner (low-cost lidars) with 1 cm range noise have 3–4 returns each:
    the coarse model keeps them, the model fitted on 0.35° beams mostly does not."""
    rng = np.random.default_rng(3)
    found = {True: [], False: []}
    for dist in np.linspace(1.5, 2.5, 11):
        pts, valid = cast(circles=[(dist, 0.1, 0.06), (dist, -0.1, 0.06)], walls=[(6.0, -5.0, 6.0, 5.0)],
                          step_deg=1.0)  # fmt: skip
        r = np.hypot(pts[:, 0], pts[:, 1])
        with np.errstate(invalid="ignore"):
            pts = pts * ((r + rng.normal(0.0, 0.01, len(r))) / r)[:, None]
        for coarse in (True, False):
            det = ClassicalLaserDetector(coarse_step_deg=0.38 if coarse else 90.0)
            people = det.detect(pts, valid=valid)
            d = np.hypot(people.xy[:, 0] - dist - 0.04, people.xy[:, 1]) if len(people) else np.array([9.0])
            found[coarse].append(bool(np.any((d < 0.15) & (people.scores >= det.leg_min_score))))
    assert np.mean(found[True]) >= 0.8
    assert np.mean(found[True]) > np.mean(found[False]) + 0.3


def test_people_without_segments():
    legs = _legs([[2.0, 0.15], [2.0, -0.15]], [0.8, 0.7])
    people = ClassicalLaserDetector().people(LaserDetections(legs.xy, legs.scores, legs.kind, legs.radius))
    assert len(people) == 1
    assert people.segments is None


def test_a_pair_carries_its_two_legs():
    """What the tracker needs to split a pair made of one leg of each of two people."""
    det = ClassicalLaserDetector(hidden_leg_offset=0.05)
    people = det.people(_legs([[2.0, 0.15], [2.0, -0.15], [4.0, 1.0]], [0.8, 0.7, 0.9]))
    pair, single = np.flatnonzero(people.kind == KIND_PAIR)[0], np.flatnonzero(people.kind == KIND_LEG)[0]
    np.testing.assert_allclose(sorted(people.legs[pair].tolist()), [[2.0, -0.15], [2.0, 0.15]])
    assert np.isnan(people.legs[single]).all()
    moved = people.transformed(np.array([[1.0, 0.0, 1.0], [0.0, 1.0, 0.0], [0, 0, 1]]))
    np.testing.assert_allclose(moved.legs[pair], people.legs[pair] + [1.0, 0.0])
    assert people.select([pair]).legs.shape == (1, 2, 2)


def test_pair_scores_above_single_leg():
    det = ClassicalLaserDetector()
    pair = det.people(_legs([[2.0, 0.15], [2.0, -0.15]], [0.7, 0.7]))
    single = det.people(_legs([[2.0, 0.15]], [0.7]))
    assert pair.scores[0] > single.scores[0]


def test_two_legs_and_a_wall_give_one_person():
    pts, valid = cast(
        circles=[(2.0, 0.15, 0.06), (2.05, -0.15, 0.06)],
        walls=[(4.0, -3.0, 4.0, 3.0)],
    )
    det = ClassicalLaserDetector()
    people = det.detect(pts, valid=valid).above(0.5)
    assert len(people) == 1
    assert people.kind[0] == KIND_PAIR
    np.testing.assert_allclose(people.xy[0], [2.0, 0.0], atol=0.08)
    legs = det.legs(pts, valid=valid)
    wall = np.flatnonzero(legs.xy[:, 0] > 3.5)
    assert legs.scores[wall].max() < 0.5


def test_missing_beams_on_a_leg_keep_one_segment():
    pts, valid = cast(circles=[(2.0, 0.15, 0.06), (2.0, -0.15, 0.06)], walls=[(4.0, -3.0, 4.0, 3.0)])
    on_legs = np.flatnonzero(valid & (np.hypot(*np.nan_to_num(pts).T) < 2.5))
    valid = valid.copy()
    valid[on_legs[::2]] = False  # every other return on the legs is missing
    legs = ClassicalLaserDetector().legs(pts, valid=valid)
    assert (np.hypot(*legs.xy.T) < 2.5).sum() == 2


def test_detect_scans_merges_overlapping_scanners():
    circles = [(2.0, 0.15, 0.06), (2.0, -0.15, 0.06)]
    walls = [(4.0, -3.0, 4.0, 3.0)]
    a, va = cast(circles=circles, walls=walls, origin=(0.0, 0.0))
    # second laser 0.5 m to the left, facing forward: its points moved into the common frame
    b, vb = cast(circles=circles, walls=walls, origin=(0.0, 0.5))
    b = b + np.array([0.0, 0.5])
    det = ClassicalLaserDetector()
    merged = det.detect_scans([(a, va, (0.0, 0.0)), (b, vb, (0.0, 0.5))]).above(0.5)
    assert len(merged) == 1
    np.testing.assert_allclose(merged.xy[0], [2.0, 0.0], atol=0.08)
    assert merged.segments is not None
    assert merged.segments[0].max() >= len(a)


def test_bad_input():
    det = ClassicalLaserDetector()
    with pytest.raises(LaserDetectorError):
        det.detect(np.zeros((5, 3)))
    with pytest.raises(LaserDetectorError):
        ClassicalLaserDetector(pair_min=0.7, pair_max=0.6)
    assert len(det.detect(np.full((10, 2), np.nan))) == 0
    assert leg_basis(np.zeros((0, len(FEATURE_NAMES)))).shape[0] == 0
