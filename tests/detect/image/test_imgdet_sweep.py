"""View sweep: view ↔ panorama mapping of detections and merging duplicates on the sphere (no network)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from imgdet_synth import OracleSweep, angles_to_uv, person_keypoints, person_outline

from studio.detect.image.base import ViewDetections
from studio.detect.image.sweep import MergeParams, SweepParams, column_runs, merge_on_sphere, views_to_pano
from studio.geometry import PerspectiveView, pano_box_iou

W, H = 1280, 640


def _gt_box(az: float, dist: float) -> np.ndarray:
    a, e = person_outline(az, dist)
    uv = angles_to_uv(a, e, W, H)
    u = uv[:, 0]
    if u.max() - u.min() > W / 2:  # across the seam
        u = np.where(u < W / 2, u + W, u)
    return np.array([u.min(), uv[:, 1].min(), u.max(), uv[:, 1].max()])


def test_views_to_pano_centre_and_seam():
    views = [
        PerspectiveView(0.0, 0.0, math.radians(90), 256, 256),
        PerspectiveView(math.pi, 0.0, math.radians(90), 256, 256),
    ]
    dets = [ViewDetections([[118, 100, 138, 156]], [0.5]), ViewDetections([[118, 100, 138, 156]], [0.7])]
    b, s, k, m, vi = views_to_pano(views, dets, W, H)
    assert k is None
    assert s.tolist() == [0.5, 0.7]
    assert vi.tolist() == [0, 1]
    assert b[0, 0] < W / 2 < b[0, 2]  # forward = panorama centre
    assert 0 <= b[1, 0] < W < b[1, 2]  # backward = across the seam, u2 > W
    assert m.tolist() == [118.0, 118.0]


def test_views_to_pano_keypoints_wrapped():
    view = PerspectiveView(math.pi, 0.0, math.radians(90), 256, 256)
    kp = np.zeros((1, 17, 3))
    kp[0, :, 0] = np.linspace(100, 156, 17)
    kp[0, :, 1] = 128
    kp[0, :, 2] = 0.8
    _, _, k, _, _ = views_to_pano([view], [ViewDetections([[100, 100, 156, 156]], [0.5], kp)], W, H)
    assert k is not None
    assert np.all((k[0, :, 0] >= 0) & (k[0, :, 0] < W))
    assert np.all(np.abs(k[0, :, 1] - H / 2) < 1.0)
    assert np.allclose(k[0, :, 2], 0.8)


# (people as (azimuth rad, distance m)) — each must come out as exactly one detection
CASES = {
    "view centre": [(0.0, 3.0)],
    "view border (36° between 5 views)": [(math.radians(36), 2.0)],
    "seam": [(math.pi, 2.5)],
    "seam, close": [(math.radians(179), 0.9)],
    "border, close (partial in both views)": [(math.radians(36), 0.7)],
    "two side by side": [(math.radians(-40), 2.0), (math.radians(-52), 2.0)],
    "ring of six": [(math.radians(a), 1.5 + (a % 7) / 3) for a in range(-170, 180, 60)],
}


@pytest.mark.parametrize("people", CASES.values(), ids=CASES.keys())
def test_oracle_sweep_one_detection_per_person(people):
    det = OracleSweep(people, W, H)  # the default sweep
    out = det.detect(np.zeros((H, W, 3), np.uint8))
    assert len(out) == len(people)
    assert out.keypoints is not None
    gts = np.array([_gt_box(az, d) for az, d in people])
    iou = pano_box_iou(out.boxes, gts, W)
    # every person matched by one box; the box covers what the views saw of it (views clip near feet/head)
    assert np.all(iou.max(axis=0) > 0.6), iou
    assert len(set(iou.argmax(axis=0).tolist())) == len(people)


def test_same_view_never_merged_and_keypoints_split_people():
    # person behind person, same azimuth: a single view reports both -> two detections
    boxes = np.array([[100.0, 100, 160, 300], [105.0, 120, 155, 260]])
    kp_a = np.zeros((17, 3))
    kp_a[:, 0], kp_a[:, 1], kp_a[:, 2] = 130, np.linspace(100, 300, 17), 0.9
    kp_b = kp_a.copy()
    kp_b[:, 1] = np.linspace(120, 260, 17)
    out = merge_on_sphere(
        boxes, np.array([0.9, 0.8]), np.stack([kp_a, kp_b]), np.array([10.0, 10.0]), np.array([0, 0]), W, H
    )
    assert len(out) == 2
    # the same boxes from different views: keypoints agree -> merged; disagree -> kept apart
    kp_far = kp_a.copy()
    kp_far[:, 0] += 80
    same = merge_on_sphere(
        boxes, np.array([0.9, 0.8]), np.stack([kp_a, kp_a]), np.array([10.0, 10.0]), np.array([0, 1]), W, H
    )
    apart = merge_on_sphere(
        boxes, np.array([0.9, 0.8]), np.stack([kp_a, kp_far]), np.array([10.0, 10.0]), np.array([0, 1]), W, H
    )
    assert len(same) == 1
    assert len(apart) == 2


def test_merge_prefers_whole_view_and_unites_partials():
    whole = [1000.0, 200, 1100, 400]
    part = [1050.0, 200, 1100, 400]
    out = merge_on_sphere(
        np.array([part, whole]), np.array([0.9, 0.5]), None, np.array([0.0, 20.0]), np.array([0, 1]), W, H
    )
    assert len(out) == 1
    assert out.boxes[0].tolist() == whole
    assert out.scores[0] == 0.9
    # two partial halves across the seam -> their union, in seam form
    left, right = [1250.0, 200, 1290, 400], [0.0, 210, 40, 390]
    out = merge_on_sphere(
        np.array([left, right]),
        np.array([0.6, 0.7]),
        None,
        np.array([0.0, 0.0]),
        np.array([0, 1]),
        W,
        H,
        params=MergeParams(containment=0.0),
    )
    assert len(out) == 1
    assert np.allclose(out.boxes[0], [1250, 200, 1320, 400])


def test_empty_sweep():
    det = OracleSweep([], W, H)
    out = det.detect(np.zeros((H, W, 3), np.uint8))
    assert len(out) == 0
    assert out.width == W
    assert out.height == H


def test_sweep_params_views():
    vs = SweepParams(count=4, fov_deg=100, width=64, height=96, pitch_deg=-5).views()
    assert len(vs) == 4
    assert vs[0].yaw == 0.0
    assert vs[0].width == 64
    assert vs[0].height == 96
    assert math.isclose(vs[1].yaw, math.pi / 2)
    assert math.isclose(vs[0].pitch, math.radians(-5))
    _ = person_keypoints(0.0, 1.0)


def _columns(*spans_deg: tuple[float, float]) -> np.ndarray:
    """A ``(W,)`` mask of the panorama columns whose azimuth lies in one of the spans (degrees, left +)."""
    az = np.degrees((0.5 - (np.arange(W) + 0.5) / W) * 2 * math.pi)
    out = np.zeros(W, bool)
    for lo, hi in spans_deg:
        out |= ((az - lo) % 360) <= (hi - lo) % 360
    return out


def test_views_seeing_columns():
    det = OracleSweep([], W, H)  # 5 views of 90°, at 0, ±72, ±144 degrees
    assert det.views_seeing(_columns((-5, 5))) == [0]  # straight ahead: only the front view
    assert det.views_seeing(_columns((30, 40))) == [0, 1]  # in the overlap of two views
    assert det.views_seeing(_columns((175, -175))) == [2, 3]  # behind, across the seam
    assert det.views_seeing(np.zeros(W, bool)) == []
    assert det.views_seeing(np.ones(W, bool)) == [0, 1, 2, 3, 4]


def test_detect_looks_only_at_the_views_that_see_the_columns():
    people = [(0.0, 3.0), (math.radians(144), 2.0)]
    det = OracleSweep(people, W, H)
    pano = np.zeros((H, W, 3), np.uint8)
    ahead = det.detect(pano, columns=_columns((-10, 10)))
    assert det.views_run == 1
    assert len(ahead) == 1  # the person behind on the left is not looked at
    everyone = det.detect(pano)
    assert det.views_run == 1 + 5
    assert len(everyone) == 2
    front = everyone.boxes[np.argmin(np.abs(everyone.boxes[:, :3:2].mean(axis=1) - W / 2))]
    np.testing.assert_allclose(ahead.boxes[0], front)  # the one ahead is found as with every view
    with pytest.raises(ValueError, match="one flag per panorama column"):
        det.detect(pano, columns=np.ones(W // 2, bool))


def test_a_person_cut_by_a_border_whose_next_view_did_not_run_is_dropped():
    # view 0 sees -45°..45°; a person at 42° is cut by its left border, one at 25° is whole in it
    det = OracleSweep([(math.radians(42), 2.0), (math.radians(25), 3.0)], W, H)
    pano = np.zeros((H, W, 3), np.uint8)
    out = det.detect(pano, columns=_columns((-5, 5)))
    assert det.views_run == 1
    assert len(out) == 1
    assert abs(out.boxes[0, :3:2].mean() - W * (0.5 - 25 / 360)) < 15
    both = det.detect(pano, columns=_columns((-5, 5), (60, 65)))  # view 1 runs too: whole there
    assert len(both) == 2


def test_column_runs_wrap_the_seam_and_join_close_runs():
    cols = np.zeros(100, bool)
    assert column_runs(cols) == []
    cols[10:20] = True
    cols[25:30] = True
    assert column_runs(cols) == [(10, 10), (25, 5)]
    assert column_runs(cols, gap=5) == [(10, 20)]  # 5 clear columns between: one run
    cols[95:] = True
    cols[:3] = True  # across the seam: one run of 8 from column 95
    assert column_runs(cols) == [(10, 10), (25, 5), (95, 8)]
    assert column_runs(cols, gap=7) == [(95, 35)]  # all three: gaps of 7 and 5
    assert column_runs(np.ones(100, bool)) == [(0, 100)]


def _windowed(people: list[tuple[float, float]]) -> OracleSweep:
    det = OracleSweep(people, W, H)
    det.windows = True
    return det


def test_windows_centre_narrow_views_on_the_runs_at_the_sweeps_scale():
    det = _windowed([])
    ref = det.views[0]
    (win,) = det.windows_for(_columns((-10, 10)))  # type: ignore[misc]
    assert abs(math.degrees(win.yaw)) < 360 / W  # centred on the run, to a column
    assert win.width % 32 == 0
    assert det.window_min_px <= win.width < ref.width
    assert math.isclose(win.focal, ref.focal)
    assert win.height == ref.height
    assert win.pitch == ref.pitch
    assert math.degrees(win.fov) / 2 >= 10  # sees the whole run
    back, ahead = det.windows_for(_columns((-10, 10), (170, -170)))  # type: ignore[misc]
    assert {round(math.degrees(abs(v.yaw))) for v in (back, ahead)} == {0, 180}
    assert det.windows_for(np.zeros(W, bool)) == []
    # a run wider than a sweep view, or windows no narrower than the sweep views: the sweep's views
    assert det.windows_for(_columns((-50, 50))) is None
    assert det.windows_for(_columns(*[(a, a + 5) for a in range(0, 360, 20)])) is None
    det.windows = False
    assert det.windows_for(_columns((-10, 10))) is None


def test_detect_through_windows_finds_the_people_in_the_columns_as_the_sweep_does():
    people = [(math.radians(20), 3.0), (math.radians(-150), 2.0), (math.radians(100), 4.0)]
    det = _windowed(people)
    pano = np.zeros((H, W, 3), np.uint8)
    everyone = det.detect(pano)
    assert len(everyone) == 3
    look = _columns((5, 35), (-170, -130))  # the people at 20° and -150°, not the one at 100°
    out = det.detect(pano, columns=look)
    assert det.views_run == 5 + 2  # two windows
    assert det.view_columns_run < 5 * det.sweep.width + 2 * det.sweep.width
    assert len(out) == 2
    iou = pano_box_iou(out.boxes, everyone.boxes, W)
    assert np.all(iou.max(axis=1) > 0.9)  # the same boxes as the whole sweep's


def test_a_person_cut_by_a_windows_border_is_dropped():
    # a window on 0°..10° is ~40° wide; a person 2 m away at 25° reaches into it from outside
    det = _windowed([(math.radians(24), 2.0), (math.radians(5), 4.0)])
    pano = np.zeros((H, W, 3), np.uint8)
    out = det.detect(pano, columns=_columns((0, 10)))
    assert len(out) == 1
    assert abs(out.boxes[0, :3:2].mean() - W * (0.5 - 5 / 360)) < 15


class _ShortSighted(OracleSweep):
    """The oracle, blind to people under 40 px tall in a view (as a network is to people far away)."""

    def detect_view(self, image: np.ndarray) -> ViewDetections:
        d = super().detect_view(image)
        tall = d.boxes[:, 3] - d.boxes[:, 1] >= 40 if len(d) else np.zeros(0, bool)
        kp = None if d.keypoints is None else d.keypoints[tall]
        return ViewDetections(d.boxes[tall], d.scores[tall], kp)


def test_zoom_looks_closer_at_a_far_bearing_where_the_views_found_nobody():
    far, near = (math.radians(30), 8.0), (math.radians(-90), 2.0)
    det = _ShortSighted([far, near], W, H)
    det.windows = True
    pano = np.zeros((H, W, 3), np.uint8)
    assert len(det.detect(pano)) == 1  # 27-38 px tall in the sweep's views: missed
    run = det.views_run
    out = det.detect(pano, zoom=[far[0], far[0] + math.radians(2), near[0]])
    assert det.views_run == run + 5 + 1  # one closer look: the near person has a box, two bearings share
    assert len(out) == 2
    iou = pano_box_iou(out.boxes, _gt_box(*far)[None], W).max()
    assert iou > 0.8
    (view,) = det.zoom_views([far[0]], np.zeros((0, 4)), W)
    assert view.focal > 1.5 * det.views[0].focal  # the panorama's own resolution here (2.5× at most)
    assert math.isclose(view.focal, W / (2 * math.pi), rel_tol=0.1)
    assert view.width % 32 == 0
    assert view.height % 32 == 0
    det.windows = False  # a network of one input size: no closer looks
    assert det.zoom_views([far[0]], np.zeros((0, 4)), W) == []


def test_as_many_other_views_as_the_sweep_has_are_rendered_as_themselves():
    """Five closer looks (or windows) are not the sweep's five views (until session 74 they were rendered as
    the sweep's, and the sweep's people were mapped back through the closer looks' geometry)."""
    det = OracleSweep([], W, H)
    det.windows = True
    pano = np.random.default_rng(0).integers(0, 255, (H, W, 3), dtype=np.uint8)
    closer = det.zoom_views([math.radians(a) for a in (-150, -80, 0, 60, 130)], np.zeros((0, 4)), W)
    assert len(closer) == len(det.views)
    for view, image in zip(closer, det.render_views(pano, closer), strict=True):
        assert image.shape == (view.height, view.width, 3)
        np.testing.assert_array_equal(image, det.renderer.render(pano, view))
    sweep = det.render_views(pano, list(det.views))
    for view, image in zip(det.views, sweep, strict=True):
        np.testing.assert_array_equal(image, det.renderer.render(pano, view))
