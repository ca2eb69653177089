"""Contracts: observations are checked, transformed between frames; appearance helpers."""

from __future__ import annotations

import numpy as np
import pytest

from studio.geometry.se import Pose2
from studio.track import Observations, TrackFrame, TrackPoint, TrackResult
from studio.track.appearance import (
    APPEARANCE_DIM,
    appearance_distance,
    appearance_matrix,
    clothing_colours,
    median_appearance,
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


def _person_panorama(shirt_bgr, trousers_bgr, *, u0: int = 100, seam: bool = False):
    """A grey panorama with one upright 'person' box: shirt over trousers, background around them."""
    W, H = 400, 200
    pano = np.full((H, W, 3), 128, np.uint8)
    cols = np.arange(u0, u0 + 40) % W
    pano[40:100][:, cols] = shirt_bgr
    pano[100:170][:, cols] = trousers_bgr
    box = np.array([[u0 - 10, 30, u0 + 50, 180]], float)
    if seam:
        box[0, 0] %= W
        box[0, 2] = box[0, 0] + 60
    return pano, box


def test_clothing_colours_from_the_box_and_the_keypoints():
    pano, box = _person_panorama((40, 40, 190), (120, 70, 40))  # red shirt, blue trousers (BGR)
    d = clothing_colours(pano, box)
    assert d.shape == (1, APPEARANCE_DIM)
    torso, legs = d[0, :3], d[0, 3:]
    assert torso[1] > 40
    assert legs[2] < -20
    # the pose gives the same regions
    kp = np.zeros((1, 17, 3))
    joints = {5: (108, 45), 6: (132, 45), 11: (112, 100), 12: (128, 100), 13: (112, 135), 14: (128, 135)}
    for j, (u, v) in joints.items():
        kp[0, j] = (u, v, 0.9)
    np.testing.assert_allclose(clothing_colours(pano, box, kp), d, atol=1.0)
    # across the 0/360° seam
    pano_s, box_s = _person_panorama((40, 40, 190), (120, 70, 40), u0=380, seam=True)
    np.testing.assert_allclose(clothing_colours(pano_s, box_s), d, atol=1.0)
    # a box too small to describe gives an all-NaN row; so does a far person's (short) box
    assert np.isnan(clothing_colours(pano, [[10, 10, 12, 12]], min_height_frac=0.0)).all()
    assert np.isnan(clothing_colours(pano, box, min_height_frac=0.8)).all()


def test_appearance_distance_is_the_worse_of_torso_and_legs():
    pano, box = _person_panorama((40, 40, 190), (120, 70, 40))
    red_blue = clothing_colours(pano, box)[0]
    pano, box = _person_panorama((40, 40, 190), (30, 30, 32))
    red_black = clothing_colours(pano, box)[0]
    pano, box = _person_panorama((42, 38, 185), (118, 72, 41))
    similar = clothing_colours(pano, box)[0]
    assert appearance_distance(red_blue, red_blue) == pytest.approx(0.0)
    assert appearance_distance(red_blue, similar) < 3.0
    assert appearance_distance(red_blue, red_black) > 15.0  # same shirt, other trousers
    M = appearance_matrix([red_blue, red_black], [red_blue, similar, red_black])
    assert M.shape == (2, 3)
    assert M[1, 1] == pytest.approx(appearance_distance(red_black, similar))
    nan = np.full(APPEARANCE_DIM, np.nan)
    np.testing.assert_allclose(median_appearance([red_blue, nan, red_blue, similar]), red_blue)
    assert median_appearance([nan]) is None


def test_all_nan_appearance_row_means_no_descriptor() -> None:
    app = np.array([[0.5, 0.5], [np.nan, np.nan]], np.float32)
    obs = Observations.create(0, [[0.0, 0.0], [1.0, 1.0]], appearance=app)
    assert np.isnan(obs.appearance[1]).all()
    with pytest.raises(ValueError, match="finite rows"):
        Observations.create(0, [[0.0, 0.0], [1.0, 1.0]], appearance=[[0.5, np.nan], [0.5, 0.5]])
