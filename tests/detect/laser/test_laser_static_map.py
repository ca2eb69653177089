from __future__ import annotations

from collections.abc import Callable

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


def test_body_map_of_hits_alone_judges_by_the_share_of_all_scans():
    # what studio label builds: base-frame hits only (no free space drawn); a post fixed to the robot is hit
    # in every scan, a person walking past in a third of them, a wall that the moving robot sees
    # everywhere along its way in none for long
    scans = []
    for k in range(30):
        walker = (1.0 + 0.1 * k, -1.0, 0.15) if k < 10 else (9.0, 9.0, 0.15)
        pts, _ = cast(circles=[(0.3, 0.2, 0.03), walker], walls=[(5.0 - 0.2 * k, -3, 5.0 - 0.2 * k, 3)])
        scans.append((pts, np.zeros(2)))
    body = StaticMap.build(scans, max_free_range=0.0)
    assert not body.free.any()
    post, walk, wall = np.array([[0.27, 0.2]]), np.array([[1.35, -1.0]]), np.array([[3.0, 0.0]])
    assert body.hit_fraction(post)[0] > 0.9
    assert body.hit_fraction(walk)[0] < 0.2
    assert body.hit_fraction(wall)[0] < 0.2
    assert body.hit_fraction(np.array([[np.nan, 0.0]]))[0] == 0.0


def test_empty_and_bad_cell():
    smap = StaticMap.build([(np.full((4, 2), np.nan), np.zeros(2))])
    assert smap.n_scans == 1
    assert smap.static_fraction(np.zeros((2, 2))).tolist() == [0.0, 0.0]
    assert len(smap.filter(LaserDetections.empty(with_segments=True), np.zeros((0, 2)))) == 0
    with pytest.raises(LaserDetectorError):
        StaticMap.build([], cell=0.0)


def _fan(step_deg=0.25, gap=(10.0, 20.0)):
    """A 0.25° scan from (0.013, -0.021) of a wall at x = 3 (±40°), no return in the ``gap`` sector."""
    origin = np.array([0.013, -0.021])  # off the cell corners
    a = np.radians(np.arange(-40.0, 40.0 + 1e-9, step_deg))
    pts = origin + np.c_[np.full(a.size, 3.0 - origin[0]), (3.0 - origin[0]) * np.tan(a)]
    pts[(np.degrees(a) > gap[0]) & (np.degrees(a) < gap[1])] = np.nan
    return pts, origin


def test_one_scan_marks_free_space_along_the_beams():
    pts, origin = _fan()
    smap = StaticMap.build([(pts, origin)], cell=0.05, free_margin=0.15)
    h, f, _ = smap._lookup(
        np.array([[1.5, 0.0], [2.7, 0.0], [2.9, 0.0], [3.0, 0.0], [3.6, 0.0], [2.0, 0.55]])
    )
    # in the fan, before the margin: free; the margin and the wall: not; behind the wall: unseen
    assert f.tolist() == [1, 1, 0, 0, 0, 0]
    assert h.tolist() == [0, 0, 0, 1, 0, 0]
    # 2.0, 0.55 lies in the sector without returns (15°): nothing is known there
    assert smap.observations(np.array([[2.0, 0.55]]))[0] == 0
    # the whole fan up to the margin is free: every cell between the first and the last beam at 1–2.5 m
    xs = np.arange(1.0, 2.5, 0.05) + 0.025
    ys = np.arange(-0.5, 0.5, 0.05) + 0.025
    grid = np.array([(x, y) for x in xs for y in ys if not (0.15 < y / x < 0.39)])  # off the gap
    assert np.all(smap.observations(grid) == 1)


def test_scan_order_and_dropouts():
    """Beams may come in any order; a beam without a return marks nothing."""
    pts, origin = _fan(gap=(0.0, 0.0))
    drop = np.random.default_rng(1).random(len(pts)) < 0.3
    pts[drop] = np.nan
    a = StaticMap.build([(pts, origin)])
    b = StaticMap.build([(pts[np.random.default_rng(0).permutation(len(pts))], origin)])
    assert np.array_equal(a.hits, b.hits)
    assert np.array_equal(a.free, b.free)
    assert np.array_equal(a.origin, b.origin)
    # 30 % of 0.25° beams missing still leave the fan free at 2 m (neighbours 1 cm apart)
    assert a.observations(np.array([[2.0, 0.0], [2.0, 0.5], [2.0, -0.5]])).tolist() == [1, 1, 1]


def _open_field(n: int = 40, stand: int = 12) -> list[tuple[np.ndarray, np.ndarray, np.ndarray]]:
    """A static laser in open space: a wall to its left only; someone stands 4 m ahead for ``stand``
    scans, then leaves. Beams that meet nothing within range are the open ends (REP 117: +inf)."""
    out = []
    for k in range(n):
        circles = [(4.0, 0.0, 0.15)] if k < stand else []
        pts, valid = cast(circles=circles, walls=[(-2.0, 3.0, 9.0, 3.0)], step_deg=0.5, max_range=8.0)
        half = np.radians(135.0)
        ang = np.arange(-half, half + 1e-9, np.radians(0.5))
        ends = 8.0 * np.stack([np.cos(ang), np.sin(ang)], axis=1)[~valid]
        out.append((pts, np.zeros(2), ends))
    return out


def test_beams_that_met_nothing_mark_free_space():
    """Without the open ends the spot where someone stood before open space was never seen free: it looks
    like structure. With them it was seen free in every scan after they left."""
    scans = _open_field()
    spot = np.array([[4.0 - 0.15, 0.0]])
    closed = StaticMap.build([(p, o) for p, o, _ in scans])
    opened = StaticMap.build(scans)
    assert closed.static_fraction(spot)[0] > 0.9
    assert opened.static_fraction(spot)[0] < 0.4
    # the wall stays structure, space beyond max_free_range stays unobserved
    wall = np.array([[3.0, 3.0]])
    assert opened.static_fraction(wall)[0] > 0.9
    short = StaticMap.build(scans, max_free_range=3.0)
    assert short.observations(spot)[0] == 12
    # a body map (no free space at all) ignores them
    assert StaticMap.build(scans, max_free_range=0.0).free.sum() == 0


def _waiting(
    n: int = 120, arrive: int = 30, drive: int = 30
) -> list[tuple[np.ndarray, np.ndarray, tuple[float, ...]]]:
    """The robot drives along x towards a 0.4 m pillar, 6 cm per scan for the first ``drive`` scans, then
    stands; the spot ahead to its right is empty for the first ``arrive`` scans, then someone stands there
    for the rest of the recording."""
    pillar, person = (3.0, 1.5, 0.2), (2.5, -1.0, 0.15)
    out = []
    for k in range(n):
        origin = (0.06 * min(k, drive), 0.0)
        circles = [pillar] + ([person] if k >= arrive else [])
        pts, _ = cast(circles=circles, walls=ROOM, origin=origin, step_deg=0.5)
        out.append((pts + np.array(origin), np.array(origin), person))
    return out


def test_a_spot_seen_empty_before_someone_waited_there_is_not_structure():
    """Someone who stands at one spot for 75 % of the recording (in front of a robot that stopped there)
    hits its cells in 75 % of the scans that observe them: by the share alone they are structure. The
    spot was seen empty (free, the cells around it too, within 4 m) from 30 places in a row before they
    came, which a pillar's cells never are: the beams that graze its silhouette cross the cells at its
    edge, never the ones inside."""
    scans = _waiting()
    smap = StaticMap.build((p, o) for p, o, _ in scans)
    share_only = StaticMap.build(((p, o) for p, o, _ in scans), empty_scans=0)
    pts = scans[60][0]
    person = np.flatnonzero(np.hypot(*(pts - np.array([2.5, -1.0])).T) < 0.15 + 0.03)
    pillar = np.flatnonzero(np.hypot(*(pts - np.array([3.0, 1.5])).T) < 0.2 + 0.03)
    assert len(person) >= 3
    assert len(pillar) >= 3
    assert np.all(share_only.static_fraction(pts[person]) >= 0.7)
    dets = LaserDetections(
        np.array([pts[person].mean(0), pts[pillar].mean(0)]),
        np.full(2, 0.9),
        np.full(2, KIND_BLOB),
        np.full(2, 0.2),
        (person, pillar),
    )
    assert share_only.is_static(dets, pts).tolist() == [True, True]
    assert smap.is_static(dets, pts).tolist() == [False, True]
    assert not smap.structure(pts[person]).any()
    # the pillar's silhouette was crossed by grazing beams: free in some scans, yet never seen empty
    edge = np.hypot(*(np.argwhere(smap.free > 0) * 0.05 + smap.origin + 0.025 - np.array([3.0, 1.5])).T)
    assert np.any(edge < 0.25)
    assert np.all(smap.structure(pts[pillar]))
    # seen empty from fewer places in a row than empty_scans, or too far away: the share decides again
    for kw in ({"empty_scans": 40}, {"empty_range": 0.9}):
        assert StaticMap.build(((p, o) for p, o, _ in scans), **kw).is_static(dets, pts).tolist() == [
            True,
            True,
        ]


def test_scans_from_one_place_see_a_spot_empty_once():
    """A thin leg that falls between two beams is missed by every scan from the same place: a robot that
    stands still sees one view of the spot however many scans it takes, and a run of empty scans counts
    places, not scans."""
    scans = _waiting(drive=0)
    pts = scans[60][0]
    person = np.flatnonzero(np.hypot(*(pts - np.array([2.5, -1.0])).T) < 0.15 + 0.03)
    assert np.all(StaticMap.build((p, o) for p, o, _ in scans).structure(pts[person]))
    assert not StaticMap.build(((p, o) for p, o, _ in scans), empty_step=0.0).structure(pts[person]).any()


def test_a_spot_that_changed_while_the_scanner_stood_still():
    """A robot that never moves: someone arrives at a spot after 30 scans and stays. The spot was seen free
    30 scans in a row and then hit 90 in a row, all from one place: it changed, so what stands there moved.
    The pillar and the walls look the same in every scan."""
    scans = _waiting(drive=0)
    smap = StaticMap.build((p, o) for p, o, _ in scans)
    pts = scans[60][0]
    person = np.flatnonzero(np.hypot(*(pts - np.array([2.5, -1.0])).T) < 0.15 + 0.03)
    pillar = np.flatnonzero(np.hypot(*(pts - np.array([3.0, 1.5])).T) < 0.2 + 0.03)
    assert smap.changed_at(pts[person]).all()
    assert not smap.changed_at(pts[pillar]).any()
    wall = np.array([[9.0, 0.0], [4.0, 3.0], [4.0, -3.0]])
    assert not smap.changed_at(wall).any()
    assert smap.changed_at(np.array([[np.nan, 0.0], [50.0, 50.0]])).tolist() == [False, False]
    assert not StaticMap.build(((p, o) for p, o, _ in scans), steady_scans=0).changed.any()
    # the walk's share: the occupied fraction, 0 where the spot changed (the person), 0 off the map
    share = smap.walk_share(np.r_[pts[person], pts[pillar], [[np.nan, 0.0], [50.0, 50.0]]])
    assert np.all(share[: len(person)] == 0.0)
    assert np.all(share[len(person) : -2] == smap.static_fraction(pts[pillar]))
    assert np.all(share[len(person) : -2] > 0.9)
    assert share[-2:].tolist() == [0.0, 0.0]


Origin = Callable[[int], tuple[float, float]]


def _leg_scans(
    n: int, origin: Origin, seen: Callable[[int], bool], radius: float
) -> tuple[list[tuple[np.ndarray, np.ndarray]], np.ndarray]:
    """Scans by a 0.5° scanner at ``origin(k)`` of a table leg at (3, 0.4) there when ``seen(k)``, and the
    returns from the leg."""
    scans, hits = [], []
    for k in range(n):
        o = np.array(origin(k))
        pts, _ = cast(
            circles=[(3.0, 0.4, radius)] if seen(k) else [], walls=ROOM, origin=tuple(o), step_deg=0.5
        )
        pts = pts + o
        scans.append((pts, o))
        hits.append(pts[np.hypot(*(pts - np.array([3.0, 0.4])).T) < radius + 0.02])
    return scans, np.concatenate(hits)


def test_a_thin_leg_missed_now_and_then_did_not_change():
    """From one place, a table leg hit in one scan and missed in the next (it falls between two beams as
    the scanner jitters) never makes a steady run of either, though its share says half occupied."""
    scans, leg = _leg_scans(60, lambda k: (1.0, -0.5), lambda k: k % 2 == 0, 0.03)
    smap = StaticMap.build(scans)
    assert len(leg) >= 30
    assert np.all(smap.static_fraction(leg) == pytest.approx(0.5, abs=0.1))
    assert not smap.changed_at(leg).any()
    # taken one scan at a time, the flicker is a change
    assert StaticMap.build(scans, steady_scans=1).changed_at(leg).all()
    # missed for 3 scans in a row, then hit for 3, from one place: that is a change
    scans, leg = _leg_scans(60, lambda k: (1.0, -0.5), lambda k: (k // 3) % 2 == 0, 0.03)
    assert StaticMap.build(scans).changed_at(leg).all()


def test_a_leg_a_moving_robot_hits_from_some_places_did_not_change():
    """Driving past a 2 cm leg 2 m away, a 0.5° scanner hits it from some places and its beams pass beside it
    from others, in runs: the places where it looked different lie farther apart than ``same_view``."""
    scans, leg = _leg_scans(80, lambda k: (-0.5 + 0.06 * k, -1.5), lambda k: True, 0.01)
    smap = StaticMap.build(scans)
    assert 20 <= sum(np.hypot(*(p - np.array([3.0, 0.4])).T).min() < 0.03 for p, _ in scans) <= 70
    assert not smap.changed_at(leg).any()
    assert StaticMap.build(scans, same_view=1.0).changed_at(leg).any()


def test_each_scanner_keeps_its_own_runs():
    """Two scanners 0.6 m apart on a robot that never moves take turns; someone arrives and stays. Whichever
    scanner sees the spot first, each one saw it free and then hit from where it stands: it changed."""
    person = (2.5, -1.0, 0.15)
    for first in (0, 1):
        scans = []
        for k in range(60):
            sensor = (k + first) % 2
            origin = (0.3, 0.0) if sensor == 0 else (-0.3, 0.0)
            pts, _ = cast(circles=[person] if k >= 20 else [], walls=ROOM, origin=origin, step_deg=0.5)
            scans.append((pts + np.array(origin), np.array(origin), np.zeros((0, 2)), sensor, k / 20))
        hit = scans[-1][0][np.hypot(*(scans[-1][0] - np.array(person[:2])).T) < 0.18]
        assert len(hit) >= 3
        assert StaticMap.build(scans).changed_at(hit).all()


def test_runs_are_timed_so_a_fast_scanner_on_a_moving_robot_did_not_stand_still():
    """Driving past a 2 cm leg at 0.5 m/s, a 40 Hz scanner moves 1.25 cm a scan: three scans in a row are
    3.75 cm of travel, and the runs where the leg was hit and where it was missed seem to come from one
    place. Timed, a run must last 0.2 s (10 cm), and a run begun 0.2 m back is not from here."""
    scans, leg = _leg_scans(384, lambda k: (-0.5 + 0.0125 * k, -1.5), lambda k: True, 0.01)
    timed = [(p, o, np.zeros((0, 2)), 0, k / 40) for k, (p, o) in enumerate(scans)]
    assert not StaticMap.build(timed).changed_at(leg).any()
    assert StaticMap.build(scans).changed_at(leg).any()  # untimed: three scans make a run


def test_timed_runs_catch_someone_arriving_in_front_of_a_robot_that_stands():
    """As above for a 7.5 Hz scanner that stands still: the spot was free for 4 s, then hit."""
    scans = [(p, o, np.zeros((0, 2)), 0, k / 7.5) for k, (p, o, _) in enumerate(_waiting(drive=0))]
    pts = scans[60][0]
    person = np.flatnonzero(np.hypot(*(pts - np.array([2.5, -1.0])).T) < 0.15 + 0.03)
    assert StaticMap.build(scans).changed_at(pts[person]).all()
