from __future__ import annotations

import numpy as np
import pytest
from laser_synth import cast

from studio.detect.laser import KIND_BLOB, LaserDetections, LaserDetectorError
from studio.detect.laser.static_map import StaticMap

ROOM = [(-1.0, -3.0, 9.0, -3.0), (9.0, -3.0, 9.0, 3.0), (9.0, 3.0, -1.0, 3.0), (-1.0, 3.0, -1.0, -3.0)]
PILLAR = (5.0, 1.5, 0.1)


def _recording(n=60):
    """Robot drives along x (turning a little) in a room; a person walks; another stands still a while."""
    scans = []
    for k in range(n):
        t = k / n
        rx, ry, yaw = 0.0 + 4.0 * t, 0.3 * np.sin(3 * t), 0.3 * np.sin(2 * t)
        walker = (3.0 + 4.0 * t, -1.5 + 2.5 * t, 0.15)
        stander = (
            (7.0, -2.0, 0.15)
            if k < n // 3
            else (7.0 - 5.0 * (k - n // 3) / n, -2.0 + 1.5 * (k - n // 3) / n, 0.15)
        )
        pts, _valid = cast(
            circles=[PILLAR, walker, stander], walls=ROOM, origin=(rx, ry), yaw=yaw, step_deg=0.5
        )
        c, s = np.cos(yaw), np.sin(yaw)
        odom = pts @ np.array([[c, s], [-s, c]]) + np.array([rx, ry])
        scans.append((odom, np.array([rx, ry]), walker, stander))
    return scans


@pytest.fixture(scope="module")
def recording():
    scans = _recording()
    smap = StaticMap.build(((p, o) for p, o, _, _ in scans), cell=0.05)
    return scans, smap


def test_static_fraction_moving_robot(recording):
    scans, smap = recording
    assert smap.n_scans == len(scans)
    wall = np.array([[9.0, 0.0], [4.0, 3.0], [2.0, -3.0]])
    assert np.all(smap.static_fraction(wall) > 0.9)
    pillar_front = np.array([[PILLAR[0] - PILLAR[2], PILLAR[1]]])
    assert smap.static_fraction(pillar_front)[0] > 0.7
    # the walker leaves low fractions along its path
    walker = np.array([w[:2] for _, _, w, _ in scans])[::5] - np.array([0.15, 0.0])
    assert np.mean(smap.static_fraction(walker) > 0.7) < 0.2
    # free space in the middle of the room, never-seen space outside it
    assert smap.static_fraction(np.array([[1.0, 0.0]]))[0] == 0.0
    assert smap.observations(np.array([[50.0, 50.0], [np.nan, 0.0]])).tolist() == [0, 0]


def test_is_static_uses_segment_points(recording):
    scans, smap = recording
    odom, _, walker, stander = scans[10]
    near = lambda c, r: np.flatnonzero(np.hypot(*(odom - np.array(c[:2])).T) < r + 0.03)  # noqa: E731
    segs = (near(walker, walker[2]), near(stander, stander[2]), near(PILLAR, PILLAR[2]))
    assert all(len(s) >= 3 for s in segs)
    xy = np.array([odom[s].mean(0) for s in segs])
    dets = LaserDetections(xy, np.full(3, 0.9), np.full(3, KIND_BLOB), np.full(3, 0.2), segs)
    static = smap.is_static(dets, odom)
    # walker moves, the person standing still for a third of the recording is kept, the pillar is static
    assert static.tolist() == [False, False, True]
    assert len(smap.filter(dets, odom)) == 2
    # without segments: judged by position
    no_segs = LaserDetections(xy, dets.scores, dets.kind, dets.radius)
    by_xy = smap.is_static(no_segs, xy=xy)
    assert by_xy.tolist() == [False, False, True]
    with pytest.raises(LaserDetectorError):
        smap.is_static(LaserDetections(xy, np.full(3, 0.9), np.full(3, KIND_BLOB), np.full(3, 0.2)))


def test_body_map_in_sensor_frame_finds_self_hits():
    # a mount post fixed to the robot at (0.3, 0.2) shows up in every scan while the world moves
    scans = []
    for k in range(30):
        pts, _ = cast(
            circles=[(0.3, 0.2, 0.03), (3.0 - 0.05 * k, 1.0, 0.2)],
            walls=[(5.0 - 0.05 * k, -3, 5.0 - 0.05 * k, 3)],
        )
        scans.append((pts, np.zeros(2)))
    body = StaticMap.build(scans)
    assert body.static_fraction(np.array([[0.27, 0.2]]))[0] > 0.9
    assert body.static_fraction(np.array([[2.0, 1.0]]))[0] < 0.5


def test_empty_and_bad_cell():
    smap = StaticMap.build([(np.full((4, 2), np.nan), np.zeros(2))])
    assert smap.n_scans == 1
    assert smap.static_fraction(np.zeros((2, 2))).tolist() == [0.0, 0.0]
    assert len(smap.filter(LaserDetections.empty(with_segments=True), np.zeros((0, 2)))) == 0
    with pytest.raises(LaserDetectorError):
        StaticMap.build([], cell=0.0)


@pytest.mark.parametrize(("step_deg", "wall"), [(0.25, 9.0), (0.5, 4.0), (1.0, 2.5)])
def test_free_space_thinning_marks_the_cells_every_beam_marks(step_deg, wall):
    """Sampling only every m-th beam near the sensor (beams closer than a cell) marks the same free cells
    as sampling every beam: scans in beam order (NaN beams in place) against the same scan shuffled."""
    from studio.detect.laser.static_map import _ray_samples

    pts, valid = cast(
        circles=[(1.5, 0.4, 0.06), (3.0, -0.5, 0.15)],
        walls=[(wall, -9.0, wall, 9.0), (-wall, -9.0, -wall, 9.0), (-9.0, wall, 9.0, wall)],
        step_deg=step_deg,
    )
    origin = np.array([0.013, -0.021])  # off the cell corners
    valid[np.random.default_rng(1).random(len(valid)) < 0.3] = False  # dropouts: no return on 30 % of beams
    pts = np.where(valid[:, None], pts, np.nan) + origin

    def cells(p):
        s = _ray_samples(p, origin, step=0.05, margin=0.15, max_range=10.0)
        return s.shape[0], set(map(tuple, np.floor(s / 0.05).astype(int)))

    n_thin, thin = cells(pts)
    n_all, every = cells(pts[np.random.default_rng(0).permutation(len(pts))])  # no beam order: no thinning
    assert len(every - thin) <= 0.005 * len(every)
    assert thin <= every
    if step_deg < 1.0:
        assert n_thin < 0.85 * n_all  # the point of it
