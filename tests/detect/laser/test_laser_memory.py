"""Leg pairing over time (``LegMemory``): whose leg is whose where the legs of two people stand in a row."""

from __future__ import annotations

from itertools import pairwise

import numpy as np
import pytest
from laser_synth import cast

from studio.detect.laser import KIND_LEG, KIND_PAIR, LaserDetectorError
from studio.detect.laser.classical import ClassicalLaserDetector, LegMemory

R = 0.06  # leg radius


def _scan_memory(*scans: tuple[list[tuple[float, float]], list[tuple[int, int]]]) -> LegMemory:
    """The memory after scans given as (leg positions, pairs their own pairing made), range 0.1–0.6 m."""
    memory = LegMemory.empty()
    for xy, pairs in scans:
        a = np.array(xy, float)
        was = memory.follow(a, 0.2)
        gap = np.hypot(*(a[:, None] - a[None]).transpose(2, 0, 1))
        joined = np.zeros((len(a), len(a)), bool)
        for i, j in pairs:
            joined[i, j] = joined[j, i] = True
        memory = memory.after(a, was, (gap >= 0.1) & (gap <= 0.6), joined)
    return memory


def test_legs_are_followed_one_to_one_within_the_radius() -> None:
    memory = _scan_memory(([(3.0, 2.0), (5.0, 0.0)], []))
    was = memory.follow(np.array([[3.0, 2.05], [3.0, 1.9], [5.0, 0.05], [8.0, 0.0]]), 0.2)
    # the nearer of two legs near (3, 2) is that leg, the other and the one at (8, 0) are new
    assert was.tolist() == [0, -1, 1, -1]


def test_legs_mostly_paired_are_together_mostly_apart_are_apart() -> None:
    # three legs in a row for three scans, each scan pairing the outer two... of B, A's leg alone
    xy = [(3.0, 1.8), (3.0, 2.0), (3.0, 2.2)]
    memory = _scan_memory((xy, [(1, 2)]), (xy, [(1, 2)]), (xy, [(0, 1)]), (xy, [(1, 2)]))
    apart, together = memory.relations(memory.follow(np.array(xy), 0.2), min_seen=2.0, share=0.3)
    assert together[1, 2]
    assert together[2, 1]
    assert apart[0, 1]
    assert not apart[1, 2]
    assert not together[0, 1]
    # seen too rarely: no word either way
    short = _scan_memory((xy, [(1, 2)]))
    apart, together = short.relations(short.follow(np.array(xy), 0.2), min_seen=2.0, share=0.3)
    assert not apart.any()
    assert not together.any()


def test_counts_fade_and_count_only_legs_that_could_have_paired() -> None:
    far = [(3.0, 0.0), (3.0, 0.7)]  # a long stride: too far apart to pair
    memory = _scan_memory((far, []), (far, []), (far, []))
    assert not memory.relations(memory.follow(np.array(far), 0.2), min_seen=0.5, share=0.3)[0].any()
    near = [(3.0, 0.0), (3.0, 0.3)]
    memory = _scan_memory(*([(near, [])] * 3), *([(near, [(0, 1)])] * 20))
    apart, together = memory.relations(memory.follow(np.array(near), 0.2), min_seen=2.0, share=0.3)
    assert together[0, 1]  # the three scans apart faded away
    assert not apart[0, 1]


WALL = [(6.0, -5.0, 6.0, 5.0)]


def _scenes(x0: float) -> list[list[tuple[float, float, float]]]:
    """Person B (legs 0.2 m apart) stands at y = 0; person A steps in beside, one leg seen 0.25 m from B's
    inner leg, for three scans; then B's outer leg is hidden (by a third person, a bag...) for two: two
    legs 0.25 m apart, one of each."""
    b = [(x0, -0.1, R), (x0, 0.1, R)]
    a = (x0, -0.35, R)
    return [b, [a, *b], [a, *b], [a, *b], [a, b[0]], [a, b[0]]]


@pytest.mark.parametrize("robot_dx", [0.0, 0.15])
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
        if k >= 4:
            assert alone.kind.tolist() == [KIND_PAIR]
    assert found[0][0] == [KIND_PAIR]
    for kinds, y in found[1:4]:
        assert kinds == [KIND_PAIR, KIND_LEG]
        np.testing.assert_allclose(y[0], 0.0, atol=0.03)  # B stays B, A is a single leg
    for kinds, y in found[4:]:
        assert kinds == [KIND_LEG, KIND_LEG]
        assert np.abs(np.sort(y) - [-0.35, -0.1]).max() < 0.05


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


@pytest.mark.parametrize(
    "bad",
    [{"memory_radius": -0.1}, {"memory_keep": -0.2}, {"memory_min_seen": 0.0}, {"memory_share": 0.5}],
)
def test_bad_memory_settings_are_refused(bad) -> None:
    with pytest.raises(LaserDetectorError, match="memory_"):
        ClassicalLaserDetector(**bad)
