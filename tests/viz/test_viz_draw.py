"""Drawing helpers: seam-split boxes, skeletons, vertical markers, covariance ellipses, colours."""

from __future__ import annotations

import numpy as np
import pytest

from studio.viz.colors import id_color, id_colors, range_colors
from studio.viz.draw import (
    ellipse_strips,
    skeleton_strips,
    split_seam_boxes,
    vertical_strips,
    wrapped_box_center,
)
from studio.viz.paths import entity_name


@pytest.mark.parametrize(
    ("box", "expected"),
    [
        ([10, 5, 20, 15], [[10, 5, 20, 15]]),
        ([95, 5, 110, 15], [[95, 5, 100, 15], [0, 5, 10, 15]]),
        ([90, 5, 100, 15], [[90, 5, 100, 15]]),  # touching the seam is not crossing it
    ],
)
def test_split_seam_boxes(box: list[float], expected: list[list[float]]) -> None:
    out, idx = split_seam_boxes(np.array([box], float), 100)
    np.testing.assert_allclose(out, expected)
    assert idx.tolist() == [0] * len(expected)


def test_split_seam_boxes_empty_and_centre() -> None:
    out, idx = split_seam_boxes(np.zeros((0, 4)), 100)
    assert out.shape == (0, 4)
    assert idx.shape == (0,)
    np.testing.assert_allclose(
        wrapped_box_center(np.array([[95, 0, 105, 1.0], [10, 0, 20, 1]]), 100), [0, 15]
    )


def test_skeleton_drops_low_scores_and_seam_jumps() -> None:
    kp = np.zeros((1, 17, 3))
    kp[0, :, 0] = 50
    kp[0, :, 1] = np.arange(17)
    kp[0, :, 2] = 1.0
    strips, owner = skeleton_strips(kp, 100)
    assert len(strips) == 16
    assert set(owner) == {0}
    kp[0, 0, 2] = 0.1  # nose hidden: its 2 segments go
    kp[0, 5, 0] = 99  # left shoulder across the seam from the right shoulder? no: 49 px apart
    kp[0, 6, 0] = 1  # right shoulder: 98 px from the left one → a seam jump, dropped
    strips, _ = skeleton_strips(kp, 100)
    assert all(abs(s[0, 0] - s[1, 0]) < 50 for s in strips)
    assert len(strips) < 14
    assert skeleton_strips(np.zeros((0, 17, 3)), 100) == ([], [])


def test_vertical_strips_skip_nan() -> None:
    lo = np.array([[10.0, 50], [np.nan, 1], [99, 50]])
    hi = np.array([[10.0, 20], [5, 1], [1, 20]])
    strips, idx = vertical_strips(lo, hi, 100)
    assert idx.tolist() == [0]
    assert len(strips) == 1


def test_ellipse_strips_size() -> None:
    (e,) = ellipse_strips(np.array([[1.0, 2.0]]), np.array([np.diag([0.04, 0.01])]), n_sigma=2.0, z=0.5)
    r = e[:, :2] - [1.0, 2.0]
    assert np.isclose(np.abs(r[:, 0]).max(), 0.4)
    assert np.isclose(np.abs(r[:, 1]).max(), 0.2, atol=2e-3)
    assert np.allclose(e[:, 2], 0.5)
    assert np.allclose(e[0], e[-1])


def test_colours() -> None:
    assert id_color(3) == id_color(3)
    assert id_color(3) != id_color(4)
    assert id_colors([1, 2]).shape == (2, 3)
    c = range_colors(np.array([0.5, 9.5, np.nan]))
    assert c.shape == (3, 3)
    assert c.dtype == np.uint8
    assert range_colors(np.zeros(0)).shape == (0, 3)


def test_entity_name() -> None:
    assert entity_name("/scan_front") == "scan_front"
    assert entity_name("/robot/scan front") == "robot_scan_front"
