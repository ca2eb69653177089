from __future__ import annotations

import numpy as np
import pytest

from studio.detect.laser.segment import (
    FEATURE_NAMES,
    SegmentParams,
    estimate_angle_step,
    segment_features,
    segment_scan,
)

F = {n: i for i, n in enumerate(FEATURE_NAMES)}


def _scan(ranges, step_deg=0.5):
    r = np.asarray(ranges, float)
    a = np.radians(np.arange(r.size) * step_deg - 10.0)
    return np.stack([r * np.cos(a), r * np.sin(a)], 1)


def _spans(segs):
    return [(int(s[0]), int(s[-1])) for s in segs]


@pytest.mark.parametrize(
    ("ranges", "spans"),
    [
        # one flat run
        ([3.0] * 10, [(0, 9)]),
        # a gap of invalid beams inside an object does not split it
        ([3.0] * 4 + [np.nan] * 3 + [3.0] * 4, [(0, 10)]),
        # a range jump splits
        ([3.0] * 5 + [2.0] * 5, [(0, 4), (5, 9)]),
        # jump across invalid beams splits too
        ([3.0] * 5 + [np.nan] * 2 + [2.0] * 5, [(0, 4), (7, 11)]),
        # too few points: dropped
        ([3.0] * 5 + [1.0] * 2 + [3.0] * 5, [(0, 4), (7, 11)]),
        # nothing valid
        ([np.nan] * 6, []),
    ],
)
def test_segmentation_table(ranges, spans):
    pts = _scan(ranges)
    assert _spans(segment_scan(pts)) == spans


def test_valid_mask_and_range_adaptive_jump():
    pts = _scan([3.0] * 10)
    valid = np.ones(10, bool)
    valid[4] = False
    assert _spans(segment_scan(pts, valid)) == [(0, 9)]
    # sparse far returns (1° step, 20 m: 0.35 m apart) stay one segment thanks to the range term
    far = _scan([20.0] * 8, step_deg=1.0)
    assert len(segment_scan(far, params=SegmentParams(jump_min=0.13, jump_beams=2.5))) == 1
    assert len(segment_scan(far, params=SegmentParams(jump_min=0.13, jump_beams=0.5))) == 0  # all split
    assert estimate_angle_step(_scan([3.0, np.nan, 3.0, 3.0])) == pytest.approx(np.radians(0.5))


def test_segment_origin_shifts_ranges():
    pts = _scan([3.0] * 10) + np.array([5.0, 5.0])
    assert _spans(segment_scan(pts, origin=(5.0, 5.0))) == [(0, 9)]


def test_full_circle_scan_joins_across_wrap():
    a = np.radians(np.arange(0.0, 360.0, 1.0))
    r = np.full(a.size, 2.0)
    r[100:110] = 1.0  # an object splits the ring into two pieces that touch across 0°/360°
    pts = np.stack([r * np.cos(a), r * np.sin(a)], 1)
    segs = segment_scan(pts)
    assert len(segs) == 2
    assert sorted(len(s) for s in segs) == [10, 350]


def test_features_circle_and_line():
    # a leg: arc of a 6 cm circle seen from 2 m
    ang = np.linspace(np.pi / 2 + 0.3, 3 * np.pi / 2 - 0.3, 12)
    leg = np.stack([2.06 + 0.06 * np.cos(ang), 0.06 * np.sin(ang)], 1)
    wall = np.stack([np.full(30, 3.0), np.linspace(-0.6, 0.6, 30)], 1)
    pts = np.concatenate([wall[:15], leg, wall[15:]])
    segs = [np.arange(15, 27)]
    f = segment_features(pts, segs)[0]
    assert f[F["n_points"]] == 12
    assert f[F["circle_radius"]] == pytest.approx(0.06, abs=1e-6)
    assert f[F["circle_residual"]] < 1e-9
    assert f[F["bulge"]] > 0.02  # convex toward the sensor
    assert f[F["occlusion_min"]] > 0.5  # the wall is behind it on both sides
    assert f[F["range"]] == pytest.approx(2.06 - 0.06 * np.mean(np.cos(ang - np.pi)), abs=0.02)
    fw = segment_features(wall, [np.arange(30)])[0]
    assert fw[F["width"]] == pytest.approx(1.2)
    assert fw[F["line_residual"]] < 1e-9
    assert fw[F["circle_radius"]] == pytest.approx(2.0)  # a line: radius capped
    assert abs(fw[F["bulge"]]) < 1e-9
    assert fw[F["coverage"]] == 1.0


def test_outline_is_averaged_only_where_returns_are_dense():
    """Jaggedness and turning read the outline averaged over ~3 cm: range noise on returns a few mm apart
    (a leg near the scanner) is not a jagged surface, while a segment with sparse returns is unchanged."""
    rng = np.random.default_rng(3)

    def leg(dist: float, n: int, noise: float) -> np.ndarray:
        ang = np.linspace(np.pi / 2 + 0.3, 3 * np.pi / 2 - 0.3, n)
        pts = np.stack([dist + 0.06 * np.cos(ang), 0.06 * np.sin(ang)], 1)
        r = np.hypot(*pts.T)
        return pts * ((r + rng.normal(0.0, noise, n)) / r)[:, None]

    dense = leg(0.7, 36, 0.012)  # ~3 mm apart under 12 mm of noise
    f = segment_features(dense, [np.arange(36)])[0]
    assert f[F["jaggedness"]] < 2.0  # the raw returns zigzag: their path is > 4× the width
    raw = np.hypot(*np.diff(dense, axis=0).T).sum() / f[F["width"]]
    assert raw > 3.0
    sparse = leg(3.0, 6, 0.0)  # 2 cm apart: every return is its own outline point
    g = segment_features(sparse, [np.arange(6)])[0]
    assert g[F["jaggedness"]] == pytest.approx(np.hypot(*np.diff(sparse, axis=0).T).sum() / g[F["width"]])
