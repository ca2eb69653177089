"""Pass one of ``studio label``: the image detector on its own thread, frames handed on in order."""

from __future__ import annotations

import threading
import time

import numpy as np
import pytest

import studio.detect.image as image_detectors
from studio.detect.image import ImageDetections, ImageDetectorError
from studio.io import load_rig
from studio.pipeline import LabelOptions
from studio.pipeline.perceive import FarLooks, far_bearings, perceive


class _Jittery:
    """Takes 0–40 ms at random; its one box's score is the panorama's mean intensity, so a result handed
    on with the wrong frame shows. Raises on call ``fail_at``. The first call lasts until the second one
    has begun (at most 10 s; 0.5 s where the detector is not thread-safe and no second call may begin), so
    that the next panorama arrives while it runs however loaded the machine is."""

    def __init__(self, fail_at: int | None = None, *, thread_safe: bool = False) -> None:
        self.fail_at = fail_at
        self.thread_safe = thread_safe
        self.running = 0
        self.most_at_once = 0
        self.calls = 0
        self.lock = threading.Lock()
        self.rng = np.random.default_rng(0)
        self.second_began = threading.Event()

    def detect(self, pano: np.ndarray) -> ImageDetections:
        with self.lock:
            k = self.calls
            self.calls += 1
            wait = float(self.rng.uniform(0.0, 0.04))
        if k == self.fail_at:
            raise ImageDetectorError("cannot run the network on this panorama")
        with self.lock:
            self.running += 1
            self.most_at_once = max(self.most_at_once, self.running)
        if k == 1:
            self.second_began.set()
        if k == 0:
            self.second_began.wait(10.0 if self.thread_safe else 0.5)
        else:
            time.sleep(wait)
        with self.lock:
            self.running -= 1
        h, w = pano.shape[:2]
        box = np.array([[w * 0.4, h * 0.3, w * 0.45, h * 0.7]])
        return ImageDetections(box, np.array([pano.mean() / 255.0]), None, w, h)


@pytest.mark.parametrize("thread_safe", [False, True])
def test_frames_come_out_in_order_with_their_own_detections(recording, monkeypatch, thread_safe):
    det = _Jittery(thread_safe=thread_safe)
    monkeypatch.setattr(image_detectors, "get_image_detector", lambda *a, **k: det)
    seen: list[tuple[int, float | None, float]] = []

    def on_frame(frame, pf):
        own = frame.panorama.image.mean() / 255.0 if frame.panorama is not None else float("nan")
        seen.append((pf.index, None if pf.image is None else float(pf.image.scores[0]), own))

    progress: list[int] = []
    frames, info = perceive(
        recording / "recording.mcap",
        load_rig(recording / "rig.yaml"),
        LabelOptions(),
        on_frame=on_frame,
        progress=lambda done, total: progress.append(done),
    )
    assert [f.index for f in frames] == list(range(len(frames)))
    assert [s[0] for s in seen] == [f.index for f in frames]
    assert progress == list(range(1, len(frames) + 1))
    ran = [s for s in seen if s[1] is not None]
    assert len(ran) == det.calls >= len(frames) // 2 - 1  # every other 10 Hz frame at 0.2 s
    for _, score, own in ran:
        assert score == pytest.approx(own)
    own_by_index = {i: own for i, _, own in seen}
    for f in frames:
        assert (f.image is None) == (f.appearance is None)
        if f.image is not None:
            assert f.appearance.shape[0] == len(f.image)
            assert f.image.scores[0] == pytest.approx(own_by_index[f.index])
    # a detector that does not say it is thread-safe runs one panorama at a time
    assert det.most_at_once == (2 if thread_safe else 1)
    assert info["static_map"] is not None
    assert info["static_map"].n_scans == sum(len(f.origins) for f in frames)
    t = info["timings_s"]
    assert t["image_detection"] > 0.0
    assert t["waiting_for_images"] >= 0.0


def test_an_image_detector_error_stops_pass_one(recording, monkeypatch):
    monkeypatch.setattr(image_detectors, "get_image_detector", lambda *a, **k: _Jittery(fail_at=3))
    handed_on: list[int] = []
    with pytest.raises(ImageDetectorError, match="cannot run the network"):
        perceive(
            recording / "recording.mcap",
            load_rig(recording / "rig.yaml"),
            LabelOptions(),
            on_frame=lambda frame, pf: handed_on.append(pf.index),
        )
    # frames are handed on in order up to the one whose detection failed, never past it
    assert handed_on == list(range(len(handed_on)))
    assert len(handed_on) <= 8


def test_beams_that_met_nothing_reach_the_static_map(recording):
    """The simulator's lasers read +inf where nothing lies within 10 m: pass one keeps those beams' far
    ends (10 m from their scanner, in the base frame) and hands them to the static map in the world frame
    (those of beams that have met something before: in these 2 s, 40 of them)."""
    from studio.pipeline.perceive import odom_scans

    frames, info = perceive(
        recording / "recording.mcap", load_rig(recording / "rig.yaml"), LabelOptions(sources="laser")
    )
    assert sum(len(f.open_ends) for f in frames) >= 20
    for f in frames[::5]:
        assert len(f.open_owner) == len(f.open_ends)
        reach = np.hypot(*(f.open_ends - f.origins[f.open_owner]).T)
        np.testing.assert_allclose(reach, 10.0, atol=1e-3)
        for k, (_points, origin, ends, sensor, stamp) in enumerate(odom_scans(f)):
            assert (sensor, stamp) == (k, f.stamp_ns * 1e-9)
            assert len(ends) == np.sum(f.open_owner == k)
            np.testing.assert_allclose(np.hypot(*(ends - origin).T), 10.0, atol=1e-3)
    assert info["static_map"].free.sum() > 0


def test_a_blind_sector_that_reads_inf_is_not_free_space():
    """A 360° scanner whose rear sector the robot's body blocks, on a driver that writes +inf there: those
    beams never meet anything, so they are blind, not open; beams that meet walls now and then stay open."""
    from studio.io import LaserScan
    from studio.pipeline.perceive import BeamReturns

    rng = np.random.default_rng(0)
    returns = BeamReturns()
    n = 360
    for i in range(200):
        r = np.where(rng.random(n) < 0.5, 4.0, np.inf).astype(np.float32)  # walls half of the time
        r[150:210] = np.inf  # the body
        seeing = returns.seeing("/scan", LaserScan(i + 1, "laser", -np.pi, np.radians(1.0), r, 0.1, 10.0))
    assert not seeing[150:210].any()
    assert seeing[:150].all()
    assert seeing[210:].all()
    assert not BeamReturns().seeing("/scan", LaserScan(1, "l", 0.0, 0.1, np.ones(5), 0.1, 10.0)).any()


def test_far_laser_detections_give_the_bearings_to_look_closer_at():
    from studio.geometry import EquirectCamera
    from studio.geometry.se import Pose3
    from studio.pipeline.perceive import ZOOM_RANGE_M

    camera = EquirectCamera(1920, 960, Pose3.from_xyz_rpy(0.1, 0.0, 1.1, 0.0, 0.0, 0.0), 0.0)
    xy = np.array([[6.0, 0.0], [0.0, 8.0], [3.0, 0.0], [-20.0, 0.0], [-7.0, -0.1]])
    az = far_bearings(camera, xy, np.full(len(xy), 0.3))
    assert len(az) == 3  # 3 m and 20 m away: no closer look
    assert ZOOM_RANGE_M[0] <= 6.0
    assert ZOOM_RANGE_M[1] < 20.0
    np.testing.assert_allclose(az[0], 0.0, atol=1e-9)  # ahead
    np.testing.assert_allclose(az[1], np.arctan2(8.0, -0.1), atol=1e-9)  # left, seen from the camera
    assert abs(abs(az[2]) - np.pi) < 0.02  # behind, near the seam
    assert far_bearings(camera, xy[2:4], np.zeros(2)) == []


class _Zooming:
    """A detector that can look closer (``windows``) and at part of the panorama (``looks_at_columns``):
    records the bearings it was asked to look at and whether it looked at everything; it finds one
    person at columns 40–45 % of the width, so the looks between whole ones are partial."""

    windows = True
    looks_at_columns = True

    def __init__(self) -> None:
        self.zoom: list[list[float]] = []
        self.whole: list[bool] = []

    def detect(
        self, pano: np.ndarray, *, columns: np.ndarray | None = None, zoom: tuple[float, ...] = ()
    ) -> ImageDetections:
        self.zoom.append(list(zoom))
        self.whole.append(columns is None)
        h, w = pano.shape[:2]
        return ImageDetections(np.array([[w * 0.4, h * 0.3, w * 0.45, h * 0.7]]), np.ones(1), None, w, h)


def test_the_image_detector_looks_closer_where_the_laser_found_someone_far(recording, monkeypatch):
    from studio.geometry import EquirectCamera

    det = _Zooming()
    monkeypatch.setattr(image_detectors, "get_image_detector", lambda *a, **k: det)
    rig = load_rig(recording / "rig.yaml")
    frames, _ = perceive(recording / "recording.mcap", rig, LabelOptions())
    assert sum(f.image is not None for f in frames) == len(det.zoom)
    camera = EquirectCamera(1920, 960, rig.camera.pose, rig.camera.lens_offset)
    far_looks, asked = FarLooks(), iter(det.zoom)
    for f in frames:  # on whole and partial looks alike: this frame's far detections, then the last 0.5 s's
        if f.image is not None:
            expected = far_looks.bearings(camera, f.stamp_ns, f.robot_pose, f.laser.xy, f.laser_z)
            own = far_bearings(camera, f.laser.xy, f.laser_z)
            assert expected[: len(own)] == pytest.approx(own)
            assert next(asked) == pytest.approx(expected)
        far_looks.add(f.stamp_ns, f.robot_pose, f.laser.xy, f.laser_z)
    assert sum(len(z) for z in det.zoom) > 0  # someone is far away in this recording
    assert any(z for z, whole in zip(det.zoom, det.whole, strict=True) if not whole)
    assert sum(map(len, det.zoom)) > sum(
        len(far_bearings(camera, f.laser.xy, f.laser_z)) for f in frames if f.image is not None
    )  # the scans between the images found far people too


def test_far_laser_detections_of_the_last_half_second_are_looked_at_where_they_are_now():
    from studio.geometry import EquirectCamera
    from studio.geometry.se import Pose2, Pose3
    from studio.pipeline.perceive import ZOOM_MEMORY_S

    camera = EquirectCamera(1920, 960, Pose3.identity(), 0.0)
    looks = FarLooks()
    z = np.zeros(1)
    # 0.3 s ago, at the odom origin facing +x: someone 8 m ahead, someone 2 m ahead (too near to zoom)
    looks.add(0, Pose2(0.0, 0.0, 0.0), np.array([[8.0, 0.0], [2.0, 0.0]]), np.zeros(2))
    # now 1 m further and turned left by 90°: the far one is 7 m to the right
    now = Pose2(1.0, 0.0, np.pi / 2)
    (bearing,) = looks.bearings(camera, 300_000_000, now, np.zeros((0, 2)), np.zeros(0))
    assert bearing == pytest.approx(far_bearings(camera, np.array([[0.0, -7.0]]), z)[0])
    # the frame's own far detections come first
    mine = looks.bearings(camera, 300_000_000, now, np.array([[0.0, 6.0]]), z)
    assert mine == pytest.approx(far_bearings(camera, np.array([[0.0, 6.0], [0.0, -7.0]]), np.zeros(2)))
    # forgotten once older than the memory
    late = round(ZOOM_MEMORY_S * 1e9) + 1
    assert looks.bearings(camera, late, now, np.zeros((0, 2)), np.zeros(0)) == []
