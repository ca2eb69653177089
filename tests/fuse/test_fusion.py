"""Box ↔ laser fusion on the sphere: each path of the association, on exact synthetic geometry."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
import pytest

from studio.detect.image.base import ImageDetections
from studio.detect.laser.base import LaserDetections
from studio.fuse import FusionConfig, ScanRays, box_ranges, colours_hidden, fuse_frame
from studio.geometry import EquirectCamera, Pose3

W, H = 1920, 960
CAM = EquirectCamera(W, H, Pose3.from_xyz_rpy(0.1, 0.0, 1.15, yaw=0.2))


def person(x: float, y: float, *, feet: bool = True, height: float = 1.75) -> tuple[np.ndarray, np.ndarray]:
    """Panorama box and COCO keypoints of an upright person standing at (x, y) in the base frame."""
    d = np.array([x, y]) - CAM.pose.t[:2]
    side = np.array([-d[1], d[0]]) / np.linalg.norm(d) * 0.25
    pts = np.array([[*(np.array([x, y]) + s * side), z] for s in (-1, 1) for z in (0.0, height)])
    uv, _ = CAM.project(pts)
    u = uv[:, 0]
    if u.max() - u.min() > W / 2:  # across the seam
        u = np.where(u < W / 2, u + W, u)
    box = np.array([u.min(), uv[:, 1].min(), u.max(), uv[:, 1].max()])
    kp = np.zeros((17, 3))
    joints = {5: 1.45, 6: 1.45, 11: 0.95, 12: 0.95, 13: 0.5, 14: 0.5, 15: 0.08, 16: 0.08}
    for j, z in joints.items():
        if not feet and j >= 13:
            continue
        uv1, _ = CAM.project(np.array([[x, y, z]]))
        kp[j] = (uv1[0, 0], uv1[0, 1], 0.9)
    if box[2] >= W:
        box[0] %= W
        box[2] = box[0] + (box[2] - box[0])
    return box, kp


def dets(*people: tuple[np.ndarray, np.ndarray]) -> ImageDetections:
    boxes = np.array([p[0] for p in people]).reshape(-1, 4)
    kps = np.array([p[1] for p in people]).reshape(-1, 17, 3)
    return ImageDetections(boxes, np.full(len(people), 0.8), kps, W, H)


def laser(*xy: tuple[float, float]) -> LaserDetections:
    a = np.array(xy, dtype=float).reshape(-1, 2)
    return LaserDetections(a, np.full(len(a), 0.7), np.zeros(len(a), int), np.full(len(a), 0.2))


def legs(x: float, y: float, n: int = 8) -> np.ndarray:
    d = np.array([x, y]) / np.hypot(x, y)
    t = np.array([-d[1], d[0]])
    pts = [np.array([x, y]) - 0.06 * d + t * s for s in np.linspace(-0.15, 0.15, n)]
    return np.c_[np.array(pts), np.full(n, 0.3)]


def test_foot_row_range_is_exact_for_visible_ankles() -> None:
    br = box_ranges(dets(person(3.0, 1.0)), CAM)
    true = np.hypot(3.0 - 0.1, 1.0)
    assert br.how == ("foot-row",)
    assert br.range[0] == pytest.approx(true, abs=0.02)
    assert 0.0 < br.sigma[0] < 0.3


def test_torso_size_when_feet_hidden() -> None:
    br = box_ranges(dets(person(1.5, -0.5, feet=False)), CAM)
    assert br.how == ("torso-size",)
    assert br.range[0] == pytest.approx(np.hypot(1.4, 0.5), rel=0.1)


def test_box_with_laser_detection_is_fused_at_the_laser_position() -> None:
    obs = fuse_frame(dets(person(3.0, 1.0)), laser((3.02, 0.97)), camera=CAM)
    assert obs.source == ("fused",)
    assert obs.how == ("laser-detection",)
    np.testing.assert_allclose(obs.xy[0], [3.02, 0.97])
    assert obs.box_index[0] == 0
    assert obs.laser_index[0] == 0


def test_range_consistency_picks_the_right_detection_in_one_column() -> None:
    # two people behind each other in almost the same column; laser sees both
    obs = fuse_frame(dets(person(2.0, 0.5), person(5.0, 1.3)), laser((5.0, 1.3), (2.0, 0.5)), camera=CAM)
    by_box = {int(b): tuple(obs.xy[k]) for k, b in enumerate(obs.box_index)}
    assert by_box[0] == pytest.approx((2.0, 0.5))
    assert by_box[1] == pytest.approx((5.0, 1.3))
    assert set(obs.source) == {"fused"}


def test_box_across_the_seam() -> None:
    # straight behind the camera (camera yaw 0.2 rad): the seam runs through the person
    x, y = 0.1 + 3.0 * np.cos(np.pi + 0.2), 3.0 * np.sin(np.pi + 0.2)
    p = person(x, y)
    assert p[0][0] < W < p[0][2]  # one box across the 0/360° seam
    obs = fuse_frame(dets(p), laser((x, y + 0.03)), camera=CAM)
    assert obs.source == ("fused",)


def test_scan_cluster_fallback_takes_the_closest_person_not_the_wall() -> None:
    wall = np.c_[np.full(30, 6.0), np.linspace(0.0, 3.0, 30), np.full(30, 0.3)]
    pts = np.r_[legs(3.0, 1.0), wall]
    obs = fuse_frame(dets(person(3.0, 1.0)), None, camera=CAM, scan_points=pts)
    assert obs.how == ("scan-cluster",)
    assert np.hypot(*(obs.xy[0] - [3.0, 1.0])) < 0.1


def test_image_only_position_has_a_radial_covariance() -> None:
    obs = fuse_frame(dets(person(4.0, -2.0)), None, camera=CAM)
    assert obs.source == ("image",)
    assert obs.how == ("foot-row",)
    assert np.hypot(*(obs.xy[0] - [4.0, -2.0])) < 0.15
    evals, evecs = np.linalg.eigh(obs.cov[0])
    radial = np.array([4.0 - 0.1, -2.0]) / np.hypot(4.0 - 0.1, -2.0)
    assert abs(evecs[:, 1] @ radial) > 0.9  # the long axis points along the ray
    assert evals[1] > evals[0]


def test_feet_hidden_by_the_robot_the_laser_decides() -> None:
    # very close person: only shoulders and hips visible, size cue coarse; the laser has the answer
    obs = fuse_frame(dets(person(0.9, 0.3, feet=False)), laser((0.9, 0.3), (4.0, 4.0)), camera=CAM)
    fused = [k for k, s in enumerate(obs.source) if s == "fused"]
    assert len(fused) == 1
    np.testing.assert_allclose(obs.xy[fused[0]], [0.9, 0.3])


def test_a_box_with_hidden_feet_takes_nobody_beyond_its_top_row() -> None:
    # someone 0.7 m away whom only head and shoulders keypoints describe (no range cue), the laser missing
    # their legs, and someone 5 m behind on the same bearing: the box is not that one's
    near, far = (0.75, 0.1), (5.0, 0.7)
    box, kp = person(*near, feet=False)
    kp[11:13] = 0.0  # hips not seen either: no torso-size cue
    d = dets((box, kp))
    br = box_ranges(d, CAM)
    assert br.how == ("none",)
    assert np.hypot(0.75 - 0.1, 0.1) < br.max_range[0] < 2.0
    obs = fuse_frame(d, laser(far), camera=CAM)
    assert sorted(obs.source) == ["laser"]  # the far person stays the laser's, without the near one's box
    # the scan cluster of the near person's legs is the box's
    obs = fuse_frame(d, laser(far), camera=CAM, scan_points=np.r_[legs(*near), legs(*far)])
    k = obs.source.index("fused")
    assert obs.how[k] == "scan-cluster"
    assert np.hypot(*(obs.xy[k] - near)) < 0.15
    # someone at 3 m with raised hands (box top 2.3 m above the floor) is still within the bound
    box3, kp3 = person(3.0, 0.5, feet=False, height=2.3)
    kp3[11:13] = 0.0
    assert box_ranges(dets((box3, kp3)), CAM).max_range[0] > np.hypot(2.9, 0.5)
    assert fuse_frame(dets((box3, kp3)), laser((3.0, 0.5)), camera=CAM).source == ("fused",)
    # a camera above everyone's head: no bound
    high = EquirectCamera(W, H, Pose3.from_xyz_rpy(0.0, 0.0, 2.5))
    assert np.isinf(box_ranges(dets(person(2.0, 0.0)), high).max_range[0])


def test_unconfirmed_laser_detections_are_kept_as_laser() -> None:
    obs = fuse_frame(dets(person(3.0, 1.0)), laser((3.0, 1.0), (-2.0, -2.0)), camera=CAM)
    assert sorted(obs.source) == ["fused", "laser"]
    k = obs.source.index("laser")
    np.testing.assert_allclose(obs.xy[k], [-2.0, -2.0])
    assert np.all(np.isnan(obs.box[k]))


def test_static_laser_detections_only_count_when_a_box_vouches_for_them() -> None:
    # someone standing still all recording looks static to the laser: the box still takes the detection;
    # static detections no box takes (furniture) are dropped, moving ones are kept as laser
    static = np.array([True, True, False])
    obs = fuse_frame(
        dets(person(3.0, 1.0)),
        laser((3.02, 0.97), (-2.0, -2.0), (1.0, -3.0)),
        camera=CAM,
        laser_static=static,
    )
    assert sorted(obs.source) == ["fused", "laser"]
    k = obs.source.index("fused")
    np.testing.assert_allclose(obs.xy[k], [3.02, 0.97])
    assert obs.how[k] == "laser-detection"
    np.testing.assert_allclose(obs.xy[obs.source.index("laser")], [1.0, -3.0])
    no_box = fuse_frame(
        None, laser((3.02, 0.97), (1.0, -3.0)), camera=CAM, laser_static=np.array([True, False])
    )
    assert no_box.source == ("laser",)
    np.testing.assert_allclose(no_box.xy[0], [1.0, -3.0])


def test_a_box_does_not_take_the_wall_seen_between_the_legs_of_someone_the_laser_missed() -> None:
    # the laser detector missed a person at (4, 1) (their legs are in the scan) and found a piece of wall
    # 1.3 m behind them on the same bearing, seen between their legs; the box's range cue (feet hidden:
    # torso size) is too loose to choose: the box takes the nearer scan cluster, the person
    box = dets(person(4.0, 1.0, feet=False))
    wall = laser((5.2, 1.3))
    obs = fuse_frame(box, wall, camera=CAM, scan_points=legs(4.0, 1.0), laser_static=np.array([True]))
    assert obs.source == ("fused",)
    assert obs.how[0] == "scan-cluster"
    assert np.hypot(*(obs.xy[0] - [4.0, 1.0])) < 0.15
    # without the check, or without the nearer points, the box takes the static detection
    off = fuse_frame(
        box,
        wall,
        camera=CAM,
        scan_points=legs(4.0, 1.0),
        laser_static=np.array([True]),
        config=FusionConfig(static_behind=0.0),
    )
    np.testing.assert_allclose(off.xy[off.source.index("fused")], [5.2, 1.3])
    alone = fuse_frame(box, wall, camera=CAM, scan_points=np.zeros((0, 3)), laser_static=np.array([True]))
    np.testing.assert_allclose(alone.xy[alone.source.index("fused")], [5.2, 1.3])


def test_no_fixed_fallback_position() -> None:
    # a box whose foot row is above the horizon (nonsense) and no laser: nothing is invented
    bad = ImageDetections(np.array([[100.0, 10.0, 150.0, 60.0]]), np.array([0.9]), None, W, H)
    obs = fuse_frame(bad, None, camera=CAM, config=FusionConfig())
    assert len(obs) == 0


def test_laser_only_rig() -> None:
    obs = fuse_frame(None, laser((1.0, 2.0)), camera=None)
    assert obs.source == ("laser",)


def test_a_single_leg_is_less_certain_than_a_leg_pair() -> None:
    # a walker's leg is up to half a stride from the body: the covariance says so, fused or laser-only
    cfg = FusionConfig()
    two = LaserDetections(
        np.array([[3.0, 1.0], [-2.0, -2.0]]), np.full(2, 0.7), np.array([0, 1]), np.full(2, 0.2)
    )
    obs = fuse_frame(dets(person(3.0, 1.0)), two, camera=CAM, config=cfg)
    k_pair, k_leg = obs.source.index("fused"), obs.source.index("laser")
    np.testing.assert_allclose(obs.cov[k_pair], cfg.laser_sigma**2 * np.eye(2))
    np.testing.assert_allclose(obs.cov[k_leg], cfg.leg_sigma**2 * np.eye(2))
    assert cfg.leg_sigma > 2 * cfg.laser_sigma
    swapped = LaserDetections(two.xy, two.scores, np.array([1, 0]), two.radius)
    obs = fuse_frame(dets(person(3.0, 1.0)), swapped, camera=CAM, config=cfg)
    np.testing.assert_allclose(obs.cov[obs.source.index("fused")], cfg.leg_sigma**2 * np.eye(2))


def test_the_other_leg_inside_a_matched_box_is_not_a_second_person() -> None:
    # walking: the laser sees the two legs 0.35 m apart as two single-leg people; the box takes one, the
    # other is the same person, not a laser-only someone else
    obs = fuse_frame(dets(person(3.0, 1.0)), laser((3.1, 1.1), (2.85, 0.85)), camera=CAM)
    assert obs.source == ("fused",)
    # beyond same_person_radius, or outside the box, a laser person stays someone else
    far = fuse_frame(dets(person(3.0, 1.0)), laser((3.0, 1.0), (4.2, 1.4)), camera=CAM)
    assert sorted(far.source) == ["fused", "laser"]
    off = fuse_frame(
        dets(person(3.0, 1.0)),
        laser((3.0, 1.0), (3.0, 1.45)),
        camera=CAM,
        config=FusionConfig(same_person_radius=0.0),
    )
    assert sorted(off.source) == ["fused", "laser"]


def test_someone_beside_a_boxed_person_in_the_same_box_is_seen_by_the_camera() -> None:
    # two people side by side 0.6 m apart at 5 m make one box; the laser sees both: the box takes one, the
    # other is someone the camera saw too ("beside-box"), unless farther in range or the rule is off
    box = person(5.0, 0.3)[0]
    box[0] -= 60.0  # the box spans both people
    one_box = ImageDetections(box[None], np.array([0.6]), None, W, H)
    obs = fuse_frame(one_box, laser((5.0, 0.3), (5.0, 0.9), (7.0, 0.9)), camera=CAM)
    assert obs.source == ("fused", "laser", "laser")
    assert obs.how[1:] == ("beside-box", "laser-only")  # the one 2 m behind is outside the range step
    assert sorted(round(float(obs.xy[k, 1]), 2) for k in (0, 1)) == [0.3, 0.9]
    np.testing.assert_allclose(obs.xy[2], [7.0, 0.9])
    off = fuse_frame(
        one_box, laser((5.0, 0.3), (5.0, 0.9)), camera=CAM, config=FusionConfig(beside_box_range=0.0)
    )
    assert off.how == ("laser-detection", "laser-only")
    # outside the box's columns it is just a laser person
    narrow = fuse_frame(dets(person(5.0, 0.3)), laser((5.0, 0.3), (5.0, 1.5)), camera=CAM)
    assert narrow.how == ("laser-detection", "laser-only")


def test_colours_of_a_box_over_two_people_on_one_bearing_are_hidden() -> None:
    # the laser sees B 1.5 m in front of A, in the middle of A's box, and the detector gave B no box (one box
    # over both): A's colours are hidden; C beside A at the same range and D behind, boxed, are not
    boxed = [(5.0, 0.0), (5.0, 1.8), (6.5, -1.1)]
    front = (3.5, 0.05)
    obs = fuse_frame(dets(*(person(*p) for p in boxed)), laser(*boxed, front), camera=CAM)
    assert sorted(obs.source) == ["fused", "fused", "fused", "laser"]
    order = [int(np.argmin(np.hypot(*(obs.xy - np.array(p)).T))) for p in [*boxed, front]]
    hidden = colours_hidden(obs, CAM)
    assert [bool(hidden[k]) for k in order] == [True, False, False, False]
    # no nearer than the margin (two people side by side), or in front of the box's edge only: not hidden
    assert not colours_hidden(obs, CAM, margin=2.0).any()
    edge = fuse_frame(dets(person(5.0, 0.0)), laser((5.0, 0.0), (3.5, 0.45)), camera=CAM)
    assert edge.source == ("fused", "laser")
    assert not colours_hidden(edge, CAM).any()
    # the detector told them apart (B has a box of its own): each box is cut around its own person
    apart = fuse_frame(dets(person(5.0, 0.0), person(*front)), laser((5.0, 0.0), front), camera=CAM)
    assert apart.source == ("fused", "fused")
    assert not colours_hidden(apart, CAM).any()


def test_colours_hidden_across_the_seam() -> None:
    # on the panorama's 0/360° seam (behind the robot, the camera yawed by 0.2 rad)
    az = np.pi + 0.2
    back, front = (5.0 * np.cos(az), 5.0 * np.sin(az)), (3.5 * np.cos(az + 0.01), 3.5 * np.sin(az + 0.01))
    box = person(*back)[0]
    assert box[0] < W < box[2]
    seam = fuse_frame(dets(person(*back)), laser(back, front), camera=CAM)
    assert seam.source == ("fused", "laser")
    assert colours_hidden(seam, CAM).tolist() == [True, False]
    alone = fuse_frame(dets(person(*back)), laser(back), camera=CAM)
    assert colours_hidden(alone, CAM).tolist() == [False]


def rays(
    origin: tuple[float, float], ranges: Callable[[np.ndarray], np.ndarray], fov_deg: float = 270.0
) -> ScanRays:
    """A 0.25° scanner at ``origin`` (facing +x) whose beam at bearing ``a`` returns at ``ranges(a)``."""
    a = np.radians(np.arange(-fov_deg / 2, fov_deg / 2 + 1e-9, 0.25))
    r = ranges(a)
    o = np.asarray(origin, dtype=float)
    ends = o + r[:, None] * np.c_[np.cos(a), np.sin(a)]
    return ScanRays(np.tile(o, (len(a), 1)), ends)


def test_a_box_the_laser_saw_through_makes_no_image_only_position() -> None:
    # a box with no laser person and no scan cluster: an image-only position at (4, 1) from its foot row
    box = dets(person(4.0, 1.0))
    only = fuse_frame(box, None, camera=CAM)
    assert only.source == ("image",)
    bearing = float(np.arctan2(1.0, 4.0 - 0.4))
    # every beam of the scanner at (0.4, 0) past that spot returns from a wall 9 m away: nobody stands there
    wall = rays((0.4, 0.0), lambda a: np.full(a.shape, 9.0))
    assert len(fuse_frame(box, None, camera=CAM, rays=wall).xy) == 0
    # a door frame 0.2 m beside the spot (4 m away) is outside the narrow window: still seen through
    door = rays((0.4, 0.0), lambda a: np.where(np.abs(a - bearing - 0.055) < 0.01, 3.75, 9.0))
    assert len(fuse_frame(box, None, camera=CAM, rays=door).xy) == 0
    # someone's legs there stop some of the beams: the position stays
    person_there = rays((0.4, 0.0), lambda a: np.where(np.abs(a - bearing - 0.012) < 0.012, 3.68, 9.0))
    assert fuse_frame(box, None, camera=CAM, rays=person_there).source == ("image",)
    # the spot at the edge of the scanner's field of view: half the window unseen says nothing
    edge = rays((0.4, 0.0), lambda a: np.full(a.shape, 9.0), fov_deg=2 * np.degrees(bearing))
    assert fuse_frame(box, None, camera=CAM, rays=edge).source == ("image",)
    # and the check can be turned off
    assert fuse_frame(
        box, None, camera=CAM, rays=wall, config=FusionConfig(see_through_halfwidth=0.0)
    ).source == ("image",)


def test_a_box_whose_foot_row_reads_too_far_takes_the_laser_person_inside_it_nearer() -> None:
    box, kp = person(3.0, 1.0)
    kp[15:17] = person(4.8, 1.6)[1][15:17]  # the ankles of someone 1.9 m farther on the same bearing
    img = dets((box, kp))
    assert box_ranges(img, CAM).range[0] > 4.5
    obs = fuse_frame(img, laser((3.0, 1.0)), camera=CAM)
    assert obs.source == ("fused",)
    assert obs.how == ("laser-detection",)
    np.testing.assert_allclose(obs.xy[0], [3.0, 1.0])
    assert obs.box_index[0] == 0
    apart = fuse_frame(img, laser((3.0, 1.0)), camera=CAM, config=FusionConfig(nearer_laser=False))
    assert sorted(apart.source) == ["image", "laser"]
    # not a laser person on never-moving structure (a chair in front of the feet)
    static = fuse_frame(img, laser((3.0, 1.0)), camera=CAM, laser_static=np.array([True]))
    assert static.source == ("image",)


def test_a_laser_person_beyond_a_box_is_someone_else() -> None:
    # the box's range is right; the laser person behind it in its columns is another person
    obs = fuse_frame(dets(person(3.0, 1.0)), laser((5.8, 1.95)), camera=CAM)
    assert sorted(obs.source) == ["image", "laser"]


def test_a_far_box_takes_structure_only_where_its_range_agrees() -> None:
    # someone 9.9 m away (foot row ±1.2 m) on the bearing of a door frame the laser finds 3 m nearer: a
    # moving laser person there would pass the 3 σ range gate; a never-moving one needs 2 σ
    img = dets(person(9.5, 3.0))
    br = box_ranges(img, CAM)
    d = (np.array([9.5, 3.0]) - CAM.pose.t[:2]) / np.hypot(9.4, 3.0)

    def at(r: float) -> LaserDetections:
        return laser(tuple(CAM.pose.t[:2] + r * d))

    r_door = br.range[0] - 3.0
    sigma = np.hypot(br.sigma[0], FusionConfig().leg_sigma)
    assert 2.0 < 3.0 / sigma < 3.0
    door = fuse_frame(img, at(r_door), camera=CAM, laser_static=np.array([True]))
    assert door.source == ("image",)
    assert door.how == ("foot-row",)
    walker = fuse_frame(img, at(r_door), camera=CAM, laser_static=np.array([False]))
    assert walker.source == ("fused",)
    # someone who stood there all along looks static too: their range agrees, and the box takes them
    still = fuse_frame(img, at(br.range[0] - 0.4), camera=CAM, laser_static=np.array([True]))
    assert still.source == ("fused",)
    assert still.how == ("laser-detection",)
    loose = fuse_frame(
        img, at(r_door), camera=CAM, laser_static=np.array([True]), config=FusionConfig(static_gate_sigma=3.0)
    )
    assert loose.source == ("fused",)
