"""Pixel ↔ angle conventions and seam-aware panorama boxes."""

from __future__ import annotations

import numpy as np
import pytest

from studio.geometry import (
    angles_to_pixel,
    angles_to_rays,
    merge_pano_boxes,
    normalize_pano_box,
    pano_box_center_az,
    pano_box_iou,
    pano_box_nms,
    pixel_to_angles,
    rays_to_angles,
    wrap_u,
)

W, H = 1920, 960


def cyc(d: np.ndarray, period: float) -> np.ndarray:
    """Signed difference modulo ``period`` (u = 0 and u = W are the same column)."""
    return (np.asarray(d) + period / 2) % period - period / 2


# (az, el) → (u, v): the conventions, by hand
CONVENTION_TABLE = [
    (0.0, 0.0, W / 2, H / 2),  # straight ahead → image centre
    (np.pi / 2, 0.0, W / 4, H / 2),  # left → W/4
    (-np.pi / 2, 0.0, 3 * W / 4, H / 2),  # right → 3W/4
    (np.pi, 0.0, 0.0, H / 2),  # behind → the seam
    (-np.pi, 0.0, 0.0, H / 2),
    (0.0, np.pi / 2, W / 2, 0.0),  # zenith → top edge
    (0.0, -np.pi / 2, W / 2, H),  # nadir → bottom edge
    (np.pi / 4, np.pi / 4, 3 * W / 8, H / 4),
]


@pytest.mark.parametrize(("az", "el", "u", "v"), CONVENTION_TABLE)
def test_convention_table(az: float, el: float, u: float, v: float) -> None:
    uu, vv = angles_to_pixel(az, el, W, H)
    assert float(uu) == pytest.approx(u, abs=1e-9)
    assert float(vv) == pytest.approx(v, abs=1e-9)


def test_u_is_wrapped_into_range() -> None:
    az = np.array([np.pi, -np.pi, np.nextafter(-np.pi, 0.0), 3 * np.pi, -5.0, 1e-17, -1e-17])
    u, _ = angles_to_pixel(az, np.zeros_like(az), W, H)
    assert np.all(u >= 0.0)
    assert np.all(u < W)
    assert wrap_u(-1e-17, W) < W
    assert wrap_u(np.array([-1e-300, W, 2 * W + 3.0]), W).tolist() == [0.0, 0.0, 3.0]


EDGE_U = [0.0, 1e-9, 0.5, 1.0, W / 4, W / 2, 3 * W / 4, W - 1.0, W - 0.5, W - 1e-9, np.nextafter(W, 0.0)]
EDGE_V = [0.0, 1e-9, 1e-3, 0.5, 1.0, H / 2, H - 1.0, H - 0.5, H - 1e-3, H - 1e-9, float(H)]


def _edge_grid() -> tuple[np.ndarray, np.ndarray]:
    uu, vv = np.meshgrid(EDGE_U, EDGE_V)
    return uu.ravel(), vv.ravel()


def test_pixel_angles_pixel_round_trip() -> None:
    rng = np.random.default_rng(0)
    eu, ev = _edge_grid()
    u = np.concatenate([rng.uniform(0, W, 20000), eu])
    v = np.concatenate([rng.uniform(0, H, 20000), ev])
    az, el = pixel_to_angles(u, v, W, H)
    assert np.all(az >= -np.pi)
    assert np.all(az < np.pi)
    assert np.all(np.abs(el) <= np.pi / 2)
    u2, v2 = angles_to_pixel(az, el, W, H)
    assert np.max(np.abs(cyc(u2 - u, W))) < 1e-3
    assert np.max(np.abs(v2 - v)) < 1e-3
    assert np.max(np.abs(cyc(u2 - u, W))) < 1e-9  # in fact exact to rounding


def test_angles_pixel_angles_round_trip() -> None:
    rng = np.random.default_rng(1)
    edge_az = [
        -np.pi,
        np.nextafter(-np.pi, 0),
        -np.pi / 2,
        0.0,
        1e-12,
        np.pi / 2,
        np.nextafter(np.pi, 0),
        np.pi,
    ]
    edge_el = [-np.pi / 2, -np.pi / 2 + 1e-9, -0.5, 0.0, 0.5, np.pi / 2 - 1e-9, np.pi / 2]
    ea, ee = (x.ravel() for x in np.meshgrid(edge_az, edge_el))
    az = np.concatenate([rng.uniform(-np.pi, np.pi, 20000), ea])
    el = np.concatenate([rng.uniform(-np.pi / 2, np.pi / 2, 20000), ee])
    u, v = angles_to_pixel(az, el, W, H)
    az2, el2 = pixel_to_angles(u, v, W, H)
    assert np.max(np.abs(cyc(az2 - az, 2 * np.pi))) < 1e-6
    assert np.max(np.abs(el2 - el)) < 1e-6


def test_rays_angles_round_trip_and_zero_ray() -> None:
    rng = np.random.default_rng(2)
    az = rng.uniform(-np.pi, np.pi, 5000)
    el = rng.uniform(-np.pi / 2 + 1e-6, np.pi / 2 - 1e-6, 5000)
    r = angles_to_rays(az, el)
    np.testing.assert_allclose(np.linalg.norm(r, axis=-1), 1.0, atol=1e-12)
    az2, el2 = rays_to_angles(r * rng.uniform(0.1, 10.0, (5000, 1)))
    assert np.max(np.abs(cyc(az2 - az, 2 * np.pi))) < 1e-9
    assert np.max(np.abs(el2 - el)) < 1e-9
    # x forward, y left, z up
    np.testing.assert_allclose(angles_to_rays(np.pi / 2, 0.0), [0.0, 1.0, 0.0], atol=1e-15)
    np.testing.assert_allclose(angles_to_rays(0.0, np.pi / 2), [0.0, 0.0, 1.0], atol=1e-15)
    a, e = rays_to_angles(np.zeros((2, 3)))
    assert np.all(np.isnan(a))
    assert np.all(np.isnan(e))


# ---------------------------------------------------------------- boxes on the cylinder


def test_normalize_pano_box() -> None:
    np.testing.assert_allclose(normalize_pano_box([1900, 10, 1940, 50], W), [1900, 10, 1940, 50])
    np.testing.assert_allclose(normalize_pano_box([-20, 10, 20, 50], W), [1900, 10, 1940, 50])
    np.testing.assert_allclose(normalize_pano_box([1930, 10, 1970, 50], W), [10, 10, 50, 50])
    np.testing.assert_allclose(normalize_pano_box([[100, 0, 2500, 5]], W), [[100, 0, 100 + W, 5]])
    assert normalize_pano_box(np.zeros((0, 4)), W).shape == (0, 4)


IOU_TABLE = [
    # a, b, expected IoU
    ([100, 0, 200, 100], [100, 0, 200, 100], 1.0),
    ([100, 0, 200, 100], [150, 0, 250, 100], 50 / 150),
    ([100, 0, 200, 100], [300, 0, 400, 100], 0.0),
    ([1900, 0, 1940, 100], [0, 0, 20, 100], 0.5),  # [0, 20] is the part of [1900, 1940] past the seam
    ([1900, 0, 1940, 100], [-20, 0, 20, 100], 1.0),
    ([1880, 0, 1920, 100], [0, 0, 40, 100], 0.0),  # neighbours, touching at the seam
    ([1900, 0, 1940, 100], [10, 0, 50, 100], 10 / 70),  # overlapping across the seam
    ([1910, 0, 1930, 100], [1900, 50, 1920, 150], (10 * 50) / (2000 + 2000 - 500)),
    ([0, 0, W, 100], [1900, 0, 1940, 100], 40 / W),  # a full-width box overlaps anything in its rows
]


@pytest.mark.parametrize(("a", "b", "expected"), IOU_TABLE)
def test_pano_box_iou_table(a: list[float], b: list[float], expected: float) -> None:
    iou = pano_box_iou(a, b, W)
    assert iou.shape == (1, 1)
    assert float(iou[0, 0]) == pytest.approx(expected, abs=1e-12)
    assert float(pano_box_iou(b, a, W)[0, 0]) == pytest.approx(expected, abs=1e-12)


def test_pano_box_iou_matches_shifted_plain_iou() -> None:
    """Rolling the whole panorama by any amount must not change any IoU."""
    rng = np.random.default_rng(3)
    u1, v1 = rng.uniform(0, W, 30), rng.uniform(0, H / 2, 30)
    a = np.column_stack([u1, v1, u1 + rng.uniform(5, 300, 30), v1 + rng.uniform(5, 300, 30)])
    ref = pano_box_iou(a, a, W)
    for shift in (0.3, 517.0, W / 2, W - 1.0):
        s = a.copy()
        s[:, [0, 2]] += shift
        np.testing.assert_allclose(pano_box_iou(s, a + np.array([shift, 0.0, shift, 0.0]), W), ref, atol=1e-9)
    np.testing.assert_allclose(np.diag(ref), 1.0)


def test_pano_box_center_az() -> None:
    assert float(pano_box_center_az([950, 0, 970, 10], W)) == pytest.approx(0.0)
    assert float(pano_box_center_az([470, 0, 490, 10], W)) == pytest.approx(np.pi / 2)
    # a box straddling the seam is centred behind (az = ±π), not at the image centre
    assert abs(float(pano_box_center_az([1900, 0, 1940, 10], W))) == pytest.approx(np.pi)
    assert abs(float(pano_box_center_az([-20, 0, 20, 10], W))) == pytest.approx(np.pi)
    assert pano_box_center_az(np.array([[950, 0, 970, 10], [470, 0, 490, 10]]), W).shape == (2,)


def test_merge_pano_boxes() -> None:
    np.testing.assert_allclose(
        merge_pano_boxes([[100, 10, 200, 20], [150, 5, 300, 15]], W), [100, 5, 300, 20]
    )
    # across the seam: the short way round
    np.testing.assert_allclose(
        merge_pano_boxes([[1880, 10, 1900, 20], [10, 5, 30, 15]], W), [1880, 5, 1950, 20]
    )
    # all the way round → full width
    boxes = [[0, 0, 700, 1], [600, 0, 1300, 1], [1200, 0, 1950, 1]]
    np.testing.assert_allclose(merge_pano_boxes(boxes, W), [0, 0, W, 1])


def test_pano_box_nms_across_seam() -> None:
    boxes = np.array([[1900, 0, 1960, 100], [-18, 0, 42, 100], [500, 0, 560, 100]])
    keep = pano_box_nms(boxes, [0.5, 0.9, 0.7], W, iou_threshold=0.5)
    assert keep.tolist() == [1, 2]
