"""Target-free calibration from people: time offset and camera yaw (studio.calibrate.people)."""

from __future__ import annotations

import argparse
import dataclasses
import json
import math
from pathlib import Path

import numpy as np
import pytest

from studio.calibrate.people import calibrate_people
from studio.calibrate.people_data import (
    ImageObservation,
    LaserPeople,
    PeopleCalibrationError,
    PeopleData,
    UnobservableError,
    collect_people,
    load_image_detections,
)
from studio.commands.calibrate_people import run_people, sparkline
from studio.geometry.se import Pose3
from studio.io import (
    CameraConfig,
    LaserConfig,
    OdometryConfig,
    Rig,
    SyncConfig,
    load_rig,
    open_recording,
    save_rig,
)

SHIFT_S = 0.35  # camera stamps are this late in the shifted copy
YAW_ERR_DEG = 2.5  # the rig's camera yaw is off by this
T0 = 1_700_000_000_000_000_000
CAM_Z = 1.15


# ----------------------------------------------------------------------------------- synthetic scenes
def _rig(yaw_deg: float = 0.0, latency_s: float = 0.0) -> Rig:
    pose = Pose3.from_xyz_rpy(0.0, 0.0, CAM_Z, 0.0, 0.0, math.radians(yaw_deg))
    return Rig(
        base_frame="base_link",
        odometry=OdometryConfig(topic="/odom"),
        camera=CameraConfig("/cam", pose),
        lasers=(LaserConfig("/scan", Pose3.identity()),),
        sync=SyncConfig(camera_latency_s=latency_s),
    )


def _scene(
    *,
    latency_s: float,
    cam_yaw_deg: float,
    moving: bool,
    seconds: float = 20.0,
    seed: int = 0,
    noise: float = 1.0,
) -> tuple[LaserPeople, list[ImageObservation]]:
    """A robot (turning when ``moving``) among 4 people (walking when ``moving``): laser people at 20 Hz
    with 2 cm noise, images at 5 Hz stamped ``latency_s`` after capture, azimuth noise 0.3°."""
    rng = np.random.default_rng(seed)
    start = rng.uniform(-4, 4, (4, 2)) + np.array([[3.0, 0.0], [0.0, 3.0], [-3.0, 0.0], [0.0, -3.0]])
    vel = rng.uniform(-0.8, 0.8, (4, 2)) if moving else np.zeros((4, 2))

    def robot(t: np.ndarray) -> np.ndarray:
        if not moving:
            return np.zeros((len(t), 3))
        return np.stack([0.2 * t, 0.1 * np.sin(0.3 * t), 0.6 * np.sin(0.4 * t) + 0.2 * t], -1)

    def people(t: float) -> np.ndarray:
        return start + vel * t

    def to_base(p: np.ndarray, r: np.ndarray) -> np.ndarray:
        c, s = math.cos(r[2]), math.sin(r[2])
        d = p - r[:2]
        return np.stack([c * d[:, 0] + s * d[:, 1], -s * d[:, 0] + c * d[:, 1]], -1)

    tl = np.arange(0.0, seconds, 0.05)
    rob = robot(tl)
    xy = [people(t) + rng.normal(0, 0.02 * noise, (4, 2)) for t in tl]
    laser = LaserPeople.from_frames((T0 + np.round(tl * 1e9)).astype(np.int64), rob, xy)
    yaw = math.radians(cam_yaw_deg)
    images = []
    for tc in np.arange(1.0, seconds - 1.0, 0.2):
        b = to_base(people(tc), robot(np.array([tc]))[0])
        c, s = math.cos(yaw), math.sin(yaw)
        xc, yc = c * b[:, 0] + s * b[:, 1], -s * b[:, 0] + c * b[:, 1]
        az = np.arctan2(yc, xc) + np.radians(rng.normal(0, 0.3 * noise, 4))
        el = np.arctan2(0.08 - CAM_Z, np.hypot(xc, yc)) + np.radians(rng.normal(0, 0.3 * noise, 4))
        images.append(ImageObservation(T0 + round((tc + latency_s) * 1e9), az, el))
    return laser, images


@pytest.mark.parametrize(("latency", "yaw_err"), [(0.35, 2.5), (-0.8, -6.0), (1.3, 12.0), (0.0, 0.0)])
def test_recovers_offset_and_yaw_on_a_synthetic_scene(latency: float, yaw_err: float) -> None:
    laser, images = _scene(latency_s=latency, cam_yaw_deg=0.0, moving=True)
    data = PeopleData(tuple(images), laser, (1920, 960), _rig(yaw_deg=yaw_err))
    res = calibrate_people(data, max_offset_s=2.0)
    assert abs(res.latency_s - latency) < 0.02
    assert abs(res.pose_change()["yaw"] + yaw_err) < 0.2
    assert abs(res.pose_change()["roll"]) < 0.2
    assert abs(res.pose_change()["pitch"]) < 0.2
    assert 0 < res.latency_std_s < 0.02
    assert res.n_pairs > 200
    assert res.residual_deg < 0.5
    assert res.rig.sync.camera_latency_s == pytest.approx(res.latency_s, abs=1e-4)
    assert res.rig.camera.pose.rpy()[2] == pytest.approx(0.0, abs=math.radians(0.2))
    assert len(res.curve["latency_s"]) == len(res.curve["score"])


def test_offset_is_relative_to_the_rigs_latency() -> None:
    laser, images = _scene(latency_s=0.5, cam_yaw_deg=0.0, moving=True, seed=3)
    data = PeopleData(tuple(images), laser, (1920, 960), _rig(latency_s=0.4))
    res = calibrate_people(data, max_offset_s=0.5)
    assert abs(res.latency_s - 0.5) < 0.02
    assert abs(res.offset_s - 0.1) < 0.02


def test_static_robot_and_people_is_unobservable() -> None:
    laser, images = _scene(latency_s=0.3, cam_yaw_deg=0.0, moving=False)
    data = PeopleData(tuple(images), laser, (1920, 960), _rig())
    with pytest.raises(UnobservableError, match="unobservable"):
        calibrate_people(data)


def test_too_few_people_is_a_clear_error() -> None:
    laser, images = _scene(latency_s=0.3, cam_yaw_deg=0.0, moving=True)
    empty = [ImageObservation(im.stamp_ns, im.az[:0], im.el_foot[:0]) for im in images]
    with pytest.raises(PeopleCalibrationError, match="too few"):
        calibrate_people(PeopleData(tuple(empty), laser, (1920, 960), _rig()))


def test_image_detections_file(tmp_path: Path) -> None:
    f = tmp_path / "image_detections.jsonl"
    f.write_text(
        '{"frame":0,"stamp_ns":5,"width":1920,"height":960,"boxes":[[1900,300,1980,600,0.9],[900,300,1020,600,0.5]]}\n'
    )
    obs, size = load_image_detections(f)
    assert size == (1920, 960)
    assert obs[0].stamp_ns == 5
    # seam box centred on u = 1940 ≡ 20 px: just left of ±180° → azimuth near +π; box at 960 px → 0
    assert obs[0].az[0] == pytest.approx(math.pi - 2 * math.pi * 20 / 1920, abs=1e-9)
    assert obs[0].az[1] == pytest.approx(0.0, abs=1e-9)
    assert np.isnan(obs[0].el_foot).all()
    f.write_text("{not json\n")
    with pytest.raises(PeopleCalibrationError, match=":1:"):
        load_image_detections(f)


def test_sparkline() -> None:
    assert sparkline([0.0, 1.0, 0.5]) == " █▄"
    assert len(sparkline(list(range(500)), width=40)) == 40


# ----------------------------------------------------------------------------------- real data
def _args(**kw: object) -> argparse.Namespace:
    base: dict[str, object] = {
        "run": None,
        "max_offset_s": 2.0,
        "max_yaw_deg": 30.0,
        "image_period_s": 0.2,
        "max_std_s": 0.05,
        "json": None,
    }
    base.update(kw)
    return argparse.Namespace(**base)


@pytest.fixture(scope="module")
def leg_bag() -> Path:
    bag = Path(__file__).resolve().parents[2] / ".." / "shared" / "data" / "leg_tracker"
    bag = bag / "demo_stationary_simple_environment.bag"
    if not bag.is_file():
        pytest.skip("../shared/data/leg_tracker is not present")
    return bag.resolve()


def test_laser_only_bag_is_a_clear_error(leg_bag: Path, tmp_path: Path) -> None:
    rig = tmp_path / "rig.yaml"
    rig.write_text("base_frame: laser\nlasers:\n  - topic: /scan\n")
    out = tmp_path / "calib.yaml"
    with pytest.raises(PeopleCalibrationError, match="no camera: nothing to calibrate"):
        run_people(_args(recording=str(leg_bag), rig=str(rig), out=str(out)))
    rig.write_text("base_frame: laser\ncamera: {topic: /theta/image}\nlasers:\n  - topic: /scan\n")
    with pytest.raises(PeopleCalibrationError, match="no images on the camera topic"):
        run_people(_args(recording=str(leg_bag), rig=str(rig), out=str(out)))
    assert not out.exists()


# ----------------------------------------------------------------------------------- simulated recording
def shifted_copy(src: Path, dst: Path, *, topic: str, shift_ns: int) -> None:
    """Copy a recording with the header stamp and log time of every message on ``topic`` moved."""
    from studio.io import RecordingWriter

    with open_recording(src) as rec, RecordingWriter(dst) as w:
        T = w.types
        for raw in rec.messages(None):
            msg = rec.decode(raw)
            log = raw.log_ns
            if raw.topic == topic:
                st = msg.header.stamp
                t = st.sec * 1_000_000_000 + st.nanosec + shift_ns
                stamp = T["builtin_interfaces/msg/Time"](sec=t // 1_000_000_000, nanosec=t % 1_000_000_000)
                header = T["std_msgs/msg/Header"](stamp=stamp, frame_id=msg.header.frame_id)
                msg = T["sensor_msgs/msg/CompressedImage"](header=header, format=msg.format, data=msg.data)
                log += shift_ns
            w.write_message(raw.topic, raw.msgtype, msg, log_ns=log, static=raw.topic == "/tf_static")


@pytest.fixture(scope="module")
def shifted_sim(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A 14 s ``moving`` simulation whose camera stamps are SHIFT_S late and whose rig yaw is off."""
    from studio.sim import simulate

    root = tmp_path_factory.mktemp("calib_people")
    simulate("moving", out=root / "sim", seconds=14, seed=3)
    out = root / "shifted"
    out.mkdir()
    rig = load_rig(root / "sim" / "rig.yaml")
    assert rig.camera is not None
    assert rig.camera.pose is not None
    shifted_copy(
        root / "sim" / "recording.mcap",
        out / "recording.mcap",
        topic=rig.camera.topic,
        shift_ns=round(SHIFT_S * 1e9),
    )
    d = rig.camera.pose.as_dict()
    d["yaw"] += math.radians(YAW_ERR_DEG)
    cam = dataclasses.replace(rig.camera, pose=Pose3.from_xyz_rpy(**d))
    save_rig(dataclasses.replace(rig, camera=cam), out / "rig.yaml")
    (out / "ground_truth.jsonl").write_text((root / "sim" / "ground_truth.jsonl").read_text())
    return out


@pytest.mark.slow
def test_recovers_offset_and_yaw_on_a_simulated_recording(shifted_sim: Path) -> None:
    data = collect_people(
        shifted_sim / "recording.mcap", load_rig(shifted_sim / "rig.yaml"), image_period_s=0.2
    )
    res = calibrate_people(data)
    print(res.summary())
    assert abs(res.latency_s - SHIFT_S) < 0.1  # one camera frame (10 Hz)
    assert abs(res.latency_s - SHIFT_S) < 0.03  # what it does today
    # MoveNet's leg keypoints sit ~0.2° left of the simulated people (measured against the ground truth):
    # that bias goes into the yaw; with the true boxes (next test) the yaw comes within 0.1°
    assert abs(res.pose_change()["yaw"] + YAW_ERR_DEG) < 0.3
    assert res.n_pairs >= 50


@pytest.mark.slow
def test_command_with_a_run_directory(shifted_sim: Path, tmp_path: Path) -> None:
    """``--run``: boxes from image_detections.jsonl (here: the simulator's true boxes, camera stamps)."""
    run = tmp_path / "run"
    run.mkdir()
    lines = []
    for k, line in enumerate((shifted_sim / "ground_truth.jsonl").read_text().splitlines()):
        f = json.loads(line)
        boxes = [[*p["box"], 1.0] for p in f["people"] if p.get("box") and p.get("visible", {}).get("camera")]
        stamp = f["stamp_ns"] + round(SHIFT_S * 1e9)
        lines.append(
            json.dumps({"frame": k, "stamp_ns": stamp, "width": 1920, "height": 960, "boxes": boxes})
        )
    (run / "image_detections.jsonl").write_text("\n".join(lines[::2]) + "\n")
    out, rep = tmp_path / "calib.yaml", tmp_path / "calib.json"
    rc = run_people(
        _args(
            recording=str(shifted_sim / "recording.mcap"),
            rig=str(shifted_sim / "rig.yaml"),
            run=str(run),
            out=str(out),
            json=str(rep),
        )
    )
    assert rc == 0
    rig = load_rig(out)
    assert abs(rig.sync.camera_latency_s - SHIFT_S) < 0.03  # one camera frame is 0.1 s
    report = json.loads(rep.read_text())
    assert abs(report["pose_change"]["yaw"] + YAW_ERR_DEG) < 0.2
    assert report["refined"] == ["yaw"]  # boxes only: no foot rows
    assert set(report) >= {"camera_latency_s", "camera_latency_std_s", "offset_s", "n_pairs", "curve"}
