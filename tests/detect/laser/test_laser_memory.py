"""Leg pairing over time (``LegMemory``): whose leg is whose where the legs of two people stand in a row."""

from __future__ import annotations

from itertools import pairwise

import numpy as np
import pytest
from laser_synth import cast

from studio.detect.laser import KIND_LEG, KIND_PAIR
from studio.detect.laser.classical import ClassicalLaserDetector, LegMemory

R = 0.06  # leg radius


def _memory(xy: list[tuple[float, float]], partner: list[int]) -> LegMemory:
    return LegMemory(np.array(xy, float), np.array(partner))


def test_legs_paired_last_scan_are_together_and_a_new_leg_is_free() -> None:
    memory = _memory([(3.0, 2.0), (3.0, 2.2)], [1, 0])
    # the same two legs moved 5 cm, and a new leg beside them
    apart, together = memory.relations(np.array([[3.05, 2.0], [3.05, 2.2], [3.0, 1.74]]), 0.2)
    assert together[0, 1]
    assert together[1, 0]
    assert together.sum() == 2
    assert not apart.any()


def test_legs_seen_together_unpaired_stay_apart() -> None:
    # a single leg, and a leg whose partner is now hidden: both seen last scan, never paired together
    memory = _memory([(3.0, 1.74), (3.0, 2.0), (3.0, 2.2)], [-1, 2, 1])
    apart, together = memory.relations(np.array([[3.0, 1.78], [3.0, 1.98]]), 0.2)
    assert apart[0, 1]
    assert apart[1, 0]
    assert not together.any()
    # a leg not seen last scan (nothing within the radius) is free to pair with a leg whose partner is gone
    apart, _ = memory.relations(np.array([[3.0, 1.98], [3.0, 2.6]]), 0.2)
    assert not apart.any()


def test_each_leg_is_at_most_one_leg_of_the_last_scan() -> None:
    # two legs now near one leg of last scan: only the nearer one is that leg, the other is new
    memory = _memory([(3.0, 2.0), (5.0, 0.0)], [-1, -1])
    apart, _ = memory.relations(np.array([[3.0, 2.05], [3.0, 1.9], [5.0, 0.05]]), 0.2)
    assert apart[0, 2]
    assert not apart[1, 2]
    assert not apart[0, 1]
    assert not apart.diagonal().any()


def test_no_memory_without_a_radius_or_legs() -> None:
    memory = _memory([(3.0, 2.0), (3.0, 2.2)], [-1, -1])
    assert not memory.relations(np.array([[3.0, 2.0], [3.0, 2.2]]), 0.0)[0].any()
    assert memory.relations(np.zeros((0, 2)), 0.2)[0].shape == (0, 0)
    empty = LegMemory(np.zeros((0, 2)), np.zeros(0, np.int64))
    assert not empty.relations(np.array([[3.0, 2.0], [3.0, 2.2]]), 0.2)[0].any()


WALL = [(6.0, -5.0, 6.0, 5.0)]


def _scenes(x0: float) -> list[list[tuple[float, float, float]]]:
    """Person B (legs 0.2 m apart) stands at y = 0; person A steps in beside, one leg seen 0.2 m from B's
    inner leg; then B's outer leg is hidden (by a third person, a bag...): two legs 0.2 m apart, one of
    each."""
    b = [(x0, -0.1, R), (x0, 0.1, R)]
    a = (x0, -0.3, R)
    return [b, [a, *b], [a, b[0]], [a, b[0]]]


@pytest.mark.parametrize("robot_dx", [0.0, 0.3])
def test_the_scans_before_keep_two_people_from_pairing_across(robot_dx: float) -> None:
    det = ClassicalLaserDetector()
    memory = None
    found = []
    for k, circles in enumerate(_scenes(3.0)):
        # the robot drives away; the scans are in its own frame, the memory in the odometry frame
        origin = (-k * robot_dx, 0.0)
        pts, valid = cast(circles=circles, walls=WALL, origin=origin)
        to_fixed = np.array([[1.0, 0.0, origin[0]], [0.0, 1.0, origin[1]], [0.0, 0.0, 1.0]])
        people, memory = det.detect_remembering(pts, valid=valid, memory=memory, to_fixed=to_fixed)
        found.append((people.kind.tolist(), people.xy[:, 1] if len(people) else np.zeros(0)))
        # without the memory, the last scans pair A's leg with B's inner leg: one person between the two
        alone = det.detect(pts, valid=valid)
        if k >= 2:
            assert alone.kind.tolist() == [KIND_PAIR]
    assert found[0][0] == [KIND_PAIR]
    assert found[1][0] == [KIND_PAIR, KIND_LEG]
    np.testing.assert_allclose(found[1][1][0], 0.0, atol=0.03)  # B stays B, A is a single leg
    for kinds, y in found[2:]:
        assert kinds == [KIND_LEG, KIND_LEG]
        assert np.abs(np.sort(y) - [-0.3, -0.1]).max() < 0.05


def test_a_person_whose_legs_come_back_is_paired_again() -> None:
    det = ClassicalLaserDetector()
    memory = None
    kinds = []
    for circles in ([(3.0, 0.0, R)], [(3.0, 0.0, R), (3.0, 0.25, R)], [(3.0, 0.0, R), (3.0, 0.25, R)]):
        pts, valid = cast(circles=circles, walls=WALL)
        people, memory = det.detect_remembering(pts, valid=valid, memory=memory)
        kinds.append(people.kind.tolist())
    assert kinds == [[KIND_LEG], [KIND_PAIR], [KIND_PAIR]]


def test_memory_off_is_the_scan_alone() -> None:
    det = ClassicalLaserDetector(memory_radius=0.0)
    memory = None
    for circles in _scenes(3.0):
        pts, valid = cast(circles=circles, walls=WALL)
        people, memory = det.detect_remembering(pts, valid=valid, memory=memory)
        alone = det.detect(pts, valid=valid)
        np.testing.assert_array_equal(people.kind, alone.kind)
        np.testing.assert_allclose(people.xy, alone.xy)


@pytest.mark.parametrize(
    "legs_after",
    [
        [(3.0, -0.45, R), (3.0, -0.25, R), (3.0, 0.25, R), (3.0, 0.45, R)],  # all four legs
        [(3.0, -0.25, R), (3.0, 0.25, R), (3.0, 0.4, R)],  # one more: B's own
    ],
)
def test_a_pair_across_two_people_is_undone_when_their_other_legs_show(legs_after) -> None:
    # first scan: one leg of each of two people 0.5 m apart (the others hidden): paired across them; the
    # next scans show more of their legs: own pairs, though the pair across was kept in memory
    det = ClassicalLaserDetector()
    pts, valid = cast(circles=[(3.0, -0.25, R), (3.0, 0.25, R)], walls=WALL)
    first, memory = det.detect_remembering(pts, valid=valid, memory=None)
    assert first.kind.tolist() == [KIND_PAIR]  # the premise
    ys = [c[1] for c in legs_after]
    own = {(a + b) / 2.0 for a, b in pairwise(ys)}
    for _ in range(2):
        pts, valid = cast(circles=legs_after, walls=WALL)
        people, memory = det.detect_remembering(pts, valid=valid, memory=memory)
        pairs = people.xy[people.kind == KIND_PAIR, 1]
        assert len(pairs) == len(legs_after) // 2
        assert all(min(abs(y - c) for c in own) < 0.03 for y in pairs)
        assert not np.any(np.abs(pairs) < 0.1)  # nothing between the two


def test_legs_too_far_apart_to_pair_last_scan_are_not_kept_apart() -> None:
    # a long stride: 0.7 m between the legs, unpaired for their distance alone; then 0.4 m
    memory = _memory([(3.0, 0.0), (3.0, 0.7)], [-1, -1])
    apart, _ = memory.relations(np.array([[3.0, 0.1], [3.0, 0.5]]), 0.2, (0.1, 0.6))
    assert not apart.any()
    apart, _ = memory.relations(np.array([[3.0, 0.1], [3.0, 0.5]]), 0.2)  # any distance counts
    assert apart[0, 1]
    det = ClassicalLaserDetector()
    kinds = []
    for gap in (0.7, 0.45, 0.3):
        pts, valid = cast(circles=[(3.0, 0.0, R), (3.0, gap, R)], walls=WALL)
        people, memory = det.detect_remembering(pts, valid=valid, memory=None if gap == 0.7 else memory)
        kinds.append(people.kind.tolist())
    assert kinds == [[KIND_LEG, KIND_LEG], [KIND_PAIR], [KIND_PAIR]]
