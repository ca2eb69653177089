"""Contracts: observations are checked, transformed between frames; appearance helpers."""

from __future__ import annotations

import numpy as np
import pytest

from studio.geometry.se import Pose2
from studio.track import Observations, TrackFrame, TrackPoint, TrackResult
from studio.track.appearance import (
    bhattacharyya_distance,
    bhattacharyya_matrix,
    colour_histogram,
    mean_histogram,
)


def test_create_defaults_and_read_only():
    o = Observations.create(7, [(1.0, 2.0), (3.0, 4.0)], sigma_m=0.1)
    assert len(o) == 2
    assert o.source == ("fused", "fused")
    np.testing.assert_allclose(o.cov[1], np.eye(2) * 0.01)
    np.testing.assert_array_equal(o.det_index, [0, 1])
    assert o.appearance is None
    with pytest.raises(ValueError, match="read-only"):
        o.xy[0, 0] = 5.0
    e = Observations.empty(9)
    assert (len(e), e.stamp_ns, e.xy.shape, e.cov.shape) == (0, 9, (0, 2), (0, 2, 2))


BAD = [
    ("stamp not int", {"stamp_ns": 1.5}, "stamp_ns"),
    ("nan position", {"xy": [(np.nan, 0.0)]}, "finite"),
    ("cov shape", {"cov": np.eye(2)}, "cov must have shape"),
    ("cov not PD", {"cov": [[[1.0, 0.0], [0.0, -1.0]]]}, "positive definite"),
    ("cov not symmetric", {"cov": [[[1.0, 0.5], [0.0, 1.0]]]}, "symmetric"),
    ("bad source", {"source": ("radar",)}, "source"),
    ("score shape", {"score": [1.0, 2.0]}, "score"),
    ("appearance rows", {"appearance": np.ones((2, 4))}, "appearance"),
    ("det_index float", {"det_index": np.array([0.5])}, "det_index"),
]


@pytest.mark.parametrize(("name", "change", "match"), BAD, ids=[b[0] for b in BAD])
def test_observations_are_checked(name, change, match):
    kw = {
        "stamp_ns": 1,
        "xy": [(0.0, 0.0)],
        "cov": [np.eye(2)],
        "source": ("laser",),
        "score": [0.9],
        "appearance": None,
        "det_index": np.array([0]),
    }
    kw.update(change)
    with pytest.raises(ValueError, match=match):
        Observations(**kw)


def test_det_index_must_be_unique():
    with pytest.raises(ValueError, match="unique"):
        Observations.create(0, [(0, 0), (1, 1)], det_index=[3, 3])


def test_transformed_moves_points_and_rotates_covariances():
    o = Observations.create(5, [(1.0, 0.0), (0.0, 2.0)], cov=[np.diag([0.04, 0.01])] * 2)
    pose = Pose2(1.0, 2.0, np.pi / 2)
    t = o.transformed(pose)
    np.testing.assert_allclose(t.xy, [(1.0, 3.0), (-1.0, 2.0)], atol=1e-12)
    np.testing.assert_allclose(t.cov[0], np.diag([0.01, 0.04]), atol=1e-12)
    back = t.transformed(pose.inverse())
    np.testing.assert_allclose(back.xy, o.xy, atol=1e-12)
    np.testing.assert_allclose(back.cov, o.cov, atol=1e-12)
    assert (t.stamp_ns, t.source) == (o.stamp_ns, o.source)


def test_track_result_helpers():
    p = TrackPoint(3, [0.0, 1.0], np.eye(2))
    q = TrackPoint(1, [2.0, 1.0], np.eye(2), det_index=4)
    res = TrackResult((TrackFrame(10, (p, q)), TrackFrame(20, (p,))))
    assert [x.track_id for x in res.frames[0].points] == [1, 3]  # sorted
    assert res.track_ids() == [1, 3]
    assert [i for i, _ in res.tracks()[3]] == [0, 1]
    with pytest.raises(ValueError, match="twice"):
        TrackFrame(0, (p, p))


def test_bhattacharyya_table():
    a = np.array([0.5, 0.5, 0.0, 0.0])
    b = np.array([0.0, 0.0, 0.5, 0.5])
    assert bhattacharyya_distance(a, a) == pytest.approx(0.0, abs=1e-7)
    assert bhattacharyya_distance(a, b) == pytest.approx(1.0)
    assert bhattacharyya_distance(a * 10, a) == pytest.approx(0.0, abs=1e-7)  # normalised first
    assert bhattacharyya_distance(a, np.zeros(4)) == 1.0
    c = np.array([0.25, 0.25, 0.25, 0.25])
    assert 0.0 < bhattacharyya_distance(a, c) < 1.0
    M = bhattacharyya_matrix([a, b], [a, b, c])
    assert M.shape == (2, 3)
    assert M[0, 2] == pytest.approx(bhattacharyya_distance(a, c))
    np.testing.assert_allclose(mean_histogram([a, b]), c)


def test_colour_histogram_separates_shirts():
    red = np.zeros((20, 10, 3), np.uint8)
    red[..., 2] = 200
    blue = np.zeros((20, 10, 3), np.uint8)
    blue[..., 0] = 200
    hr, hb = colour_histogram(red), colour_histogram(blue)
    assert hr.shape == (48,)
    assert hr.sum() == pytest.approx(1.0)
    assert bhattacharyya_distance(hr, hb) > 0.9
    noisy = np.clip(red.astype(int) + np.random.default_rng(0).integers(-20, 20, red.shape), 0, 255)
    assert bhattacharyya_distance(hr, colour_histogram(noisy.astype(np.uint8))) < 0.5
    assert colour_histogram(np.zeros((0, 3), np.uint8)).sum() == pytest.approx(1.0)


def test_all_nan_appearance_row_means_no_descriptor() -> None:
    app = np.array([[0.5, 0.5], [np.nan, np.nan]], np.float32)
    obs = Observations.create(0, [[0.0, 0.0], [1.0, 1.0]], appearance=app)
    assert np.isnan(obs.appearance[1]).all()
    with pytest.raises(ValueError, match="finite rows"):
        Observations.create(0, [[0.0, 0.0], [1.0, 1.0]], appearance=[[0.5, np.nan], [0.5, 0.5]])
