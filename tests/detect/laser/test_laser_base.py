from __future__ import annotations

import numpy as np
import pytest

from studio.detect.laser import (
    KIND_LEG,
    KIND_PAIR,
    LaserDetections,
    LaserDetector,
    LaserDetectorError,
    get_laser_detector,
    laser_detector_names,
    merge_detections,
)
from studio.errors import StudioError


def _dets(xy, scores, segs=None):
    n = len(xy)
    return LaserDetections(
        np.array(xy, float), np.array(scores, float), np.zeros(n, int), np.full(n, 0.2), segs
    )


def test_empty_and_shapes():
    e = LaserDetections.empty()
    assert len(e) == 0
    assert e.xy.shape == (0, 2)
    assert e.segments is None
    assert LaserDetections.empty(with_segments=True).segments == ()


def test_then_concatenates_and_fills_missing_legs_with_nan():
    a = _dets([[1.0, 0.0]], [0.9], (np.array([0, 1]),))
    a = LaserDetections(a.xy, a.scores, a.kind, a.radius, a.segments, np.ones((1, 2, 2)))
    b = _dets([[2.0, 0.0], [3.0, 0.0]], [0.2, 0.3], (np.array([5]), np.array([6, 7])))
    both = a.then(b)
    assert len(both) == 3
    np.testing.assert_array_equal(both.xy[:, 0], [1.0, 2.0, 3.0])
    np.testing.assert_array_equal(both.scores, [0.9, 0.2, 0.3])
    assert both.segments is not None
    assert [g.tolist() for g in both.segments] == [[0, 1], [5], [6, 7]]
    assert both.legs is not None
    assert both.legs.shape == (3, 2, 2)
    assert (both.legs[0] == 1).all()
    assert np.isnan(both.legs[1:]).all()
    assert a.then(_dets([[4.0, 0.0]], [0.5])).segments is None  # one side without segments: none
    assert LaserDetections.empty().then(LaserDetections.empty()).legs is None


@pytest.mark.parametrize(
    ("kwargs", "msg"),
    [
        ({"scores": [0.5, 0.5]}, "scores"),
        ({"scores": [1.5]}, r"\[0, 1\]"),
        ({"xy": [[np.nan, 0.0]]}, "finite"),
        ({"segments": (np.arange(2), np.arange(3))}, "segments"),
        ({"legs": np.zeros((2, 2, 2))}, "legs"),
    ],
)
def test_validation(kwargs, msg):
    base = {"xy": [[1.0, 0.0]], "scores": [0.5], "kind": [KIND_LEG], "radius": [0.1]}
    base.update(kwargs)
    with pytest.raises(ValueError, match=msg):
        LaserDetections(**base)


def test_select_above_transformed():
    d = _dets([[1, 0], [2, 0], [3, 0]], [0.2, 0.9, 0.6], (np.array([0]), np.array([1]), np.array([2])))
    a = d.above(0.5)
    assert a.xy[:, 0].tolist() == [2, 3]
    assert [s.tolist() for s in a.segments] == [[1], [2]]
    assert len(d.select([2, 0])) == 2
    m = np.array([[0.0, -1.0, 1.0], [1.0, 0.0, 0.0], [0, 0, 1]])  # rotate 90° then x += 1
    np.testing.assert_allclose(d.transformed(m).xy[0], [1.0, 1.0])


def test_merge_detections_merges_close_and_offsets_segments():
    a = _dets([[1.0, 0.0], [5.0, 0.0]], [0.9, 0.5], (np.array([0, 1]), np.array([5])))
    b = _dets([[1.1, 0.0]], [0.6], (np.array([2, 3]),))
    m = merge_detections([a, b], radius=0.3, offsets=[0, 10])
    assert len(m) == 2
    i = int(np.argmax(m.scores))
    assert m.scores[i] == pytest.approx(0.9)
    assert 1.0 < m.xy[i, 0] < 1.1  # score-weighted mean
    assert m.segments[i].tolist() == [0, 1, 12, 13]
    assert len(merge_detections([a, b], radius=0.05)) == 3
    assert len(merge_detections([])) == 0
    assert m.legs is None  # the parts had no legs


def test_merge_keeps_the_legs_of_the_best():
    legs = np.array([[[1.0, -0.1], [1.0, 0.1]]])
    a = LaserDetections([[1.0, 0.0]], [0.9], [KIND_PAIR], [0.2], legs=legs)
    b = LaserDetections([[1.1, 0.0]], [0.5], [KIND_LEG], [0.2], legs=np.full((1, 2, 2), np.nan))
    m = merge_detections([a, b, LaserDetections.empty()], radius=0.3)
    assert len(m) == 1
    np.testing.assert_allclose(m.legs[0], legs[0])


def test_registry():
    assert "classical" in laser_detector_names()
    det = get_laser_detector("classical")
    assert isinstance(det, LaserDetector)
    with pytest.raises(LaserDetectorError, match="classical") as err:
        get_laser_detector("nope")
    assert isinstance(err.value, StudioError)
    assert KIND_PAIR != KIND_LEG
