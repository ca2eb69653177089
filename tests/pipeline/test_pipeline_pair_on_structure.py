"""A person whose one visible leg stands next to a table leg: the classical detector pairs the two and puts
the person between them. Once the static-world map knows the table leg, the detector runs again on that
frame without it and the person is where their leg is."""

from __future__ import annotations

import numpy as np
import pytest
from raycast import scan

import studio.pipeline.label as label
from studio.detect.laser import KIND_PAIR, get_laser_detector
from studio.geometry.se import Pose2
from studio.pipeline import LabelOptions
from studio.pipeline.label import fuse_all
from studio.pipeline.perceive import PerceptionFrame, compact_beams, detect_again

TABLE_LEG = (2.0, 0.5, 0.05)  # x, y, radius: as thick as a person's leg at scan height
PILLAR = (6.0, 0.0, 1.5)  # behind: the laser sees the floor where the person will stand free
STAND = np.array([2.06, 0.0])  # where the person stands at the end, near leg in front, far leg hidden
N_WALK, N_STAND = 30, 6


def _frames() -> list[PerceptionFrame]:
    detector = get_laser_detector("classical")
    frames = []
    for k in range(N_WALK + N_STAND):
        if k < N_WALK:  # walks past on the far side, both legs seen
            c = np.array([1.0 + 0.1 * k, -1.5])
            legs = [(c[0], c[1] + 0.12, 0.06), (c[0], c[1] - 0.12, 0.06)]
        else:  # stands by the table leg, the far leg behind the near one
            legs = [(STAND[0] - 0.07, STAND[1], 0.06), (STAND[0] + 0.12, STAND[1], 0.06)]
        pts = scan([TABLE_LEG, PILLAR, *legs])
        f = PerceptionFrame(
            k, k * 100_000_000, Pose2(), None, None, None, np.zeros(0), np.zeros((1, 2)),
            *compact_beams(pts, np.zeros(len(pts)), 1),
        )  # fmt: skip
        laser, z = detect_again(f, detector)
        f.laser, f.laser_z = laser, z
        frames.append(f)
    return frames


def _standing_people(out: list) -> list[np.ndarray]:
    return [f.observations.xy[np.hypot(*(f.observations.xy - STAND).T) < 0.45] for f in out[N_WALK:]]


def test_the_detector_alone_pairs_the_leg_with_the_table_leg() -> None:
    """The premise: without the static map the person stands between their leg and the table leg."""
    frames = _frames()
    for f in frames[N_WALK:]:
        assert f.laser is not None
        k = int(np.argmin(np.hypot(*(f.laser.xy - STAND).T)))
        assert f.laser.kind[k] == KIND_PAIR
        assert np.hypot(*(f.laser.xy[k] - STAND)) > 0.2


def test_a_leg_paired_with_structure_is_detected_again_without_it() -> None:
    out = fuse_all(_frames(), None, LabelOptions(sources="laser"), body_maps=[])
    for people in _standing_people(out):
        assert len(people) == 1
        assert np.hypot(*(people[0] - STAND)) < 0.1
    for f in out:  # the table leg itself is structure: never a person
        assert not (np.hypot(*(f.observations.xy - TABLE_LEG[:2]).T) < 0.15).any()


def test_a_pair_with_a_few_points_on_structure_stays_a_pair(monkeypatch: pytest.MonkeyPatch) -> None:
    """Only a share of the pair's points away from the rest makes it a leg paired with structure: with the
    spread rule off (no pair is ever that far apart) the person stays between the two, as before."""
    monkeypatch.setattr(label, "_PAIR_SPREAD", 10.0)
    out = fuse_all(_frames(), None, LabelOptions(sources="laser"), body_maps=[])
    for people in _standing_people(out):
        assert len(people) == 1
        assert np.hypot(*(people[0] - STAND)) > 0.2
