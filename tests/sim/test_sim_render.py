"""Renderer and laser edge cases: the 0/360° seam, occlusion by walls and by other people, legs in scans."""

from __future__ import annotations

import json
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from studio.geometry import EquirectCamera, Pose3
from studio.io import open_recording
from studio.io.decode import decode_scan
from studio.sim import SimError, simulate
from studio.sim.base import SimRig
from studio.sim.body import body_capsules, draw_appearance, leg_circles
from studio.sim.laser import LaserCaster
from studio.sim.render import PanoramaRenderer
from studio.sim.world import build_world

W, H = 960, 480


@pytest.fixture(scope="module")
def renderer() -> PanoramaRenderer:
    return PanoramaRenderer(build_world(), width=W, height=H, zc=1.15)


def _people(states: np.ndarray, seed: int = 0) -> list:  # type: ignore[type-arg]
    rng = np.random.default_rng(seed)
    apps = [draw_appearance(rng) for _ in states]
    return [(body_capsules(s, a), a) for s, a in zip(states, apps, strict=True)]


def test_person_behind_the_robot_gives_one_box_across_the_seam(renderer: PanoramaRenderer) -> None:
    states = np.array([[-3.0, 0.3, 0.0, 0.0, 0.0]])  # robot at (0, 0.3) facing +x: person right behind
    img, info = renderer.render(np.array([0.0, 0.3, 0.0]), _people(states), states[:, :2])
    assert img.shape == (H, W, 3)
    box = info[0].box
    assert box is not None
    assert info[0].visible > 100
    u1, _, u2, _ = box
    assert 0 <= u1 < W < u2 < u1 + W / 4


def test_walls_hide_people_and_people_hide_each_other(renderer: PanoramaRenderer) -> None:
    cam = np.array([3.0, 0.5, 0.0])
    states = np.array(
        [
            [9.0, 2.0, 0.0, 0.0, 0.0],  # room B, behind the wall x = 6 (the door is at |y| < 0.6)
            [5.0, 0.5, 0.0, 0.0, 0.0],  # 2 m ahead
            [5.8, 0.55, 0.0, 0.0, 0.0],  # right behind the previous one
        ]
    )
    empty, _ = renderer.render(cam, [], np.zeros((0, 2)))
    img, info = renderer.render(cam, _people(states), states[:, :2])
    assert info[0].visible == 0
    assert info[1].visible == info[1].pixels > 0
    assert 0 < info[2].visible < 0.6 * info[2].pixels
    cam_model = EquirectCamera(W, H, Pose3.from_xyz_rpy(0.0, 0.0, 1.15))
    (u, v), _ = cam_model.project(np.array([2.0, 0.0, 1.1]))  # torso of the near person
    assert np.abs(img[int(v), int(u)].astype(int) - empty[int(v), int(u)].astype(int)).sum() > 30


def test_laser_sees_both_legs_with_a_gait_and_none_through_walls() -> None:
    rig = SimRig()
    caster = LaserCaster(build_world(), rig)
    states = np.array([[2.0, 0.3, 0.0, 1.2, np.pi / 2], [9.0, 2.0, 0.0, 0.0, 0.0]])  # walking; behind a wall
    legs = leg_circles(states, np.array([1.75, 1.75]))
    assert np.hypot(*(legs[0, 0, :2] - legs[0, 1, :2])) > 0.4  # mid-stride: legs apart
    standing = leg_circles(np.array([[0.0, 0.0, 0.0, 0.0, 1.0]]), np.array([1.75]))
    assert np.hypot(*(standing[0, 0, :2] - standing[0, 1, :2])) == pytest.approx(0.18, abs=0.01)
    res = caster.cast(rig.lasers[0], np.array([0.0, 0.3, 0.0]), legs, np.zeros(2), None)
    assert res.person_hits[0] >= 10
    assert res.person_hits[1] == 0
    hit = res.person == 0
    pts = np.stack([np.cos(rig.lasers[0].angles()[hit]), np.sin(rig.lasers[0].angles()[hit])], 1)
    pts = pts * res.true_ranges[hit, None] + np.array([0.4, 0.3])
    d = np.min(np.hypot(pts[:, None, 0] - legs[0, None, :, 0], pts[:, None, 1] - legs[0, None, :, 1]), axis=1)
    assert np.all(np.abs(d - legs[0, 0, 2]) < 1e-6)  # returns lie on the leg circles
    noisy = caster.cast(rig.lasers[0], np.array([0.0, 0.3, 0.0]), legs, np.zeros(2), np.random.default_rng(0))
    assert noisy.ranges.dtype == np.float32
    assert np.isnan(noisy.ranges).any()  # dropouts (and the robot's own body) read NaN
    assert np.isinf(noisy.ranges).sum() == np.isinf(res.true_ranges).sum()  # nothing in range reads +inf


def test_a_scanner_upside_down_or_sweeping_clockwise_sees_the_same_world_in_its_own_beam_order() -> None:
    rig = SimRig()
    up = rig.lasers[0]
    last = up.angle_min + (up.n_beams - 1) * up.angle_increment
    r, p, y = up.pose.rpy()
    t = up.pose.t
    flipped = replace(up, pose=Pose3.from_xyz_rpy(*t, roll=r + np.pi, pitch=p, yaw=y), angle_min=-last)
    clockwise = replace(up, angle_min=last, angle_increment=-up.angle_increment)
    caster = LaserCaster(build_world(), rig)
    legs = leg_circles(np.array([[2.0, 0.3, 0.0, 1.2, np.pi / 2]]), np.array([1.75]))
    robot = np.array([0.5, 0.3, 0.4])
    want = caster.cast(up, robot, legs, np.zeros(1), None)
    for spec in (flipped, clockwise):
        np.testing.assert_allclose(spec.base_angles(), up.base_angles()[::-1], atol=1e-9)
        got = caster.cast(spec, robot, legs, np.zeros(1), None)
        np.testing.assert_array_equal(got.true_ranges, want.true_ranges[::-1])
        np.testing.assert_array_equal(got.person, want.person[::-1])
        assert got.person_hits[0] == want.person_hits[0] >= 10


def test_a_sweeping_scanner_casts_each_beam_from_where_the_robot_and_people_were_at_its_time() -> None:
    """A 10 Hz scanner (0.075 s over its 270°) on a robot turning at 0.6 rad/s while a person walks past:
    each beam's range is the one cast alone from the poses at that beam's time, to the millimetre but at
    grazing walls (the pieces are short enough); without the sweep the scan differs by metres at depth
    edges."""
    rig = SimRig()
    spec = replace(rig.lasers[0], rate_hz=10.0, sweep_s=0.075)
    caster = LaserCaster(build_world(), rig)

    def robot_at(t: float) -> np.ndarray:
        return np.array([0.5 + 0.4 * t, 0.3, 0.4 + 0.6 * t])

    def legs_at(t: float) -> np.ndarray:
        return leg_circles(np.array([[2.0, 0.3 + 1.4 * t, 0.0, 1.4, np.pi / 2]]), np.array([1.75]))

    got = caster.cast_sweep(spec, 1.0, robot_at, legs_at, np.zeros(1), None)
    dt = spec.sweep_s / (spec.n_beams - 1)
    beams = np.arange(0, spec.n_beams, 3)
    want = np.array(
        [
            caster.cast(
                replace(spec, angle_min=spec.angle_min + i * spec.angle_increment, n_beams=1),
                robot_at(1.0 + i * dt),
                legs_at(1.0 + i * dt),
                np.zeros(1),
                None,
            ).true_ranges[0]
            for i in beams
        ]
    )
    finite = np.isfinite(want) & np.isfinite(got.true_ranges[beams])
    assert finite.sum() > 300
    assert np.sum(np.isfinite(want) != np.isfinite(got.true_ranges[beams])) <= 2  # at the range limit
    err = np.abs(got.true_ranges[beams][finite] - want[finite])
    assert np.median(err) < 0.001
    assert np.percentile(err, 95) < 0.005  # the scanner's range noise: 0.012
    assert got.person_hits[0] == (got.person == 0).sum() >= 5
    still = caster.cast(spec, robot_at(1.0), legs_at(1.0), np.zeros(1), None)
    assert np.abs(still.true_ranges[beams][finite] - want[finite]).max() > 1.0
    # no sweep: the scan at the stamp, as before
    plain = replace(spec, sweep_s=0.0)
    np.testing.assert_array_equal(
        caster.cast_sweep(plain, 1.0, robot_at, legs_at, np.zeros(1), None).true_ranges,
        caster.cast(plain, robot_at(1.0), legs_at(1.0), np.zeros(1), None).true_ranges,
    )


def test_a_simulated_sweeping_scanner_writes_its_time_between_beams(tmp_path: Path) -> None:
    base = SimRig(width=256, height=128)
    spec = replace(base.lasers[0], rate_hz=10.0, sweep_s=0.075)
    res = simulate("static", out=tmp_path / "s", seconds=0.5, seed=4, rig=replace(base, lasers=(spec,)))
    with open_recording(res.recording) as rec:
        scans = [decode_scan(rec.decode(raw), raw.log_ns) for raw in rec.messages([spec.topic])]
    assert len(scans) == 5
    assert all(sc.time_increment == pytest.approx(0.075 / (spec.n_beams - 1)) for sc in scans)
    with pytest.raises(SimError, match="sweep_s"):
        simulate(
            "static", out=tmp_path / "t", seconds=0.5, rig=replace(base, lasers=(replace(spec, sweep_s=0.1),))
        )


def test_a_rotated_camera_puts_people_where_its_pose_projects_them(tmp_path: Path) -> None:
    pose = Pose3.from_xyz_rpy(0.05, 0.0, 1.15, yaw=np.pi / 2)
    res = simulate(
        "static", out=tmp_path / "r", seconds=0.5, seed=4, rig=SimRig(camera_pose=pose, width=960, height=480)
    )
    cam = EquirectCamera(960, 480, pose)
    n = 0
    for line in res.ground_truth_jsonl.read_text().splitlines():
        for p in json.loads(line)["people"]:
            if not p["visible"]["camera"] or p["visible_frac"] < 0.95:
                continue
            (u, v), _ = cam.project(np.array([p["x"], p["y"], 1.0]))
            u1, v1, u2, v2 = p["box"]
            u = u + 960 if u < u1 else u
            assert u1 - 2 <= u <= u2 + 2
            assert v1 - 2 <= v <= v2 + 2
            n += 1
    assert n > 0
