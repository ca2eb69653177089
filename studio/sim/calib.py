"""Simulated calibration recordings: a target moved around a static robot (``simulate --scenario calib-*``).

Scenarios:

* ``calib-ball`` — an orange ball of radius :data:`~studio.sim.calib_render.BALL_RADIUS` carried from
  station to station around the robot, its centre 10–20 cm above the laser plane, so both lasers cut it
  in a circle of radius ``sqrt(R² - h²)``; it holds still at each station and moves between them.
* ``calib-board`` — the thesis's vertical green/white board (:data:`~studio.sim.calib_render.BOARD_WIDTH`
  wide, green below and white above the boundary at the laser height :data:`~studio.sim.base.LASER_Z`),
  facing the robot with a random turn, from station to station.
* ``calib-checkerboard`` — a planar checkerboard (:data:`~studio.sim.calib_render.CHECKER_SQUARES` squares
  of :data:`~studio.sim.calib_render.CHECKER_SQUARE` m) held at 24 tilted poses in front of the four
  horizontal cube faces, for intrinsics; the board jumps between stations (no motion).

The robot stands still at the origin of a 9 × 7 m room (world frame = base frame). The camera sits at the
TRUE pose :data:`TRUE_CAMERA_POSE` (not a round value; roll and pitch included) and its image stamps are
:data:`TRUE_LATENCY_S` late; the recording's ``/tf_static``, ``rig.yaml`` and a zero latency carry the
NOMINAL pose :data:`NOMINAL_CAMERA_POSE`, as a robot's URDF would. ``truth.yaml`` holds the truth;
``targets.jsonl`` holds, per image, the target's true state and the true pixel of its reference point.

Panoramas are ray cast exactly (no lens model: the ideal spherical camera; :mod:`studio.sim.calib_render`),
the target supersampled 3 × 3 per pixel; scans come from :class:`~studio.sim.laser.LaserCaster` (noise,
dropouts, the robot body).
"""

from __future__ import annotations

import json
import math
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np
import yaml
from numpy.typing import NDArray

from studio.atomic import MANIFEST, atomic_dir
from studio.geometry.equirect import EquirectCamera
from studio.geometry.se import Pose2, Pose3
from studio.sim.base import LASER_Z, WALL_HEIGHT, SimResult, SimRig, World
from studio.sim.calib_render import (
    BALL_RADIUS,
    BOARD_HEIGHT,
    BOARD_WIDTH,
    CHECKER_SQUARE,
    CHECKER_SQUARES,
    ROOM,
    SUPERSAMPLE,
    cached_background,
    render_target,
    room_background,
)
from studio.sim.errors import SimError
from studio.sim.laser import LaserCaster

__all__ = [
    "CALIB_OUTPUT_FILES",
    "CALIB_SCENARIOS",
    "NOMINAL_CAMERA_POSE",
    "TRUE_CAMERA_POSE",
    "TRUE_LATENCY_S",
    "render_target_panorama",
    "sample_stations",
    "simulate_calib",
    "target_state",
]

FloatArray = NDArray[np.float64]

START_NS = 1_700_000_000_000_000_000
TRUE_CAMERA_POSE = Pose3.from_xyz_rpy(
    0.031, -0.012, 1.137, roll=math.radians(0.4), pitch=math.radians(-0.7), yaw=math.radians(1.3)
)
"""The camera pose the panoramas are rendered from (``T_base_cam``), the truth to recover."""
NOMINAL_CAMERA_POSE = Pose3.from_xyz_rpy(0.0, 0.0, 1.15)
"""The pose written to ``rig.yaml`` and ``/tf_static``."""
TRUE_LATENCY_S = 0.23
"""Image header stamps are this late after the capture, s (the rig says 0)."""
CALIB_OUTPUT_FILES = ("recording.mcap", "rig.yaml", "truth.yaml", "targets.jsonl")
_BOARD_AZ = tuple(math.pi / 4 * k for k in (0, 1, 4, 0, -1, 4, 3, 0, 4, -3))


@dataclass(frozen=True)
class _Calib:
    name: str
    target: str
    seconds: float
    camera_rate_hz: float
    hold_s: float
    move_s: float


CALIB_SCENARIOS: dict[str, _Calib] = {
    "calib-ball": _Calib("calib-ball", "ball", 20.0, 5.0, 1.2, 0.8),
    "calib-board": _Calib("calib-board", "board", 30.0, 5.0, 1.0, 0.5),
    "calib-checkerboard": _Calib("calib-checkerboard", "checkerboard", 12.0, 2.0, 0.5, 0.0),
}


# ---------------------------------------------------------------------------------------------- stations
def _stations(
    kind: str, rng: np.random.Generator, n: int, caster_ok: Callable[[FloatArray], bool]
) -> FloatArray:
    """Target stations, ordered around the robot.

    Rows: ball ``x, y, z`` (centre); board ``x, y, yaw`` (boundary centre at the laser height, yaw of the
    normal pointing to the robot); checkerboard ``x, y, z, roll, pitch, yaw`` of the board frame.
    """
    out: list[list[float]] = []
    if kind == "checkerboard":
        faces = (0.0, 0.5 * math.pi, math.pi, -0.5 * math.pi)
        for k in range(n):
            face = faces[k % 4]
            az = face + rng.uniform(-0.2, 0.2)
            el = rng.uniform(-0.25, 0.1)
            d = rng.uniform(0.95, 1.25)
            c = TRUE_CAMERA_POSE.t + d * np.array(
                [math.cos(el) * math.cos(az), math.cos(el) * math.sin(az), math.sin(el)]
            )
            out.append(
                [
                    *c,
                    rng.uniform(-0.45, 0.45),
                    rng.uniform(-0.45, 0.45),
                    az + math.pi + rng.uniform(-0.1, 0.1),
                ]
            )
        return np.array(out)
    for k in range(n):  # stratified in azimuth; bins the lasers cannot see (the robot's sides) stay empty
        for _ in range(80):
            if kind == "board":  # mostly facing the front and back cube faces (the thesis's homographies)
                az = _BOARD_AZ[k % len(_BOARD_AZ)] + rng.uniform(-0.3, 0.3)
            else:
                az = -math.pi + 2 * math.pi * (k + rng.uniform(0.1, 0.9)) / n
            d = rng.uniform(1.3, 2.4)
            x, y = d * math.cos(az), d * math.sin(az)
            if kind == "ball":
                row = [x, y, LASER_Z + rng.uniform(0.10, 0.20)]
            else:
                row = [x, y, az + math.pi + rng.uniform(-0.5, 0.5)]
            if caster_ok(np.array(row)):
                out.append(row)
                break
    if len(out) < min(n, 2):  # pragma: no cover - the room leaves plenty of room
        raise SimError(f"cannot place calibration stations (only {len(out)} of {n})")
    arr = np.array(out)
    order = np.argsort(np.arctan2(arr[:, 1], arr[:, 0]))
    return arr[order]


def target_state(stations: FloatArray, t: float, *, hold_s: float, move_s: float) -> tuple[FloatArray, bool]:
    """The target's parameters at ``t`` s (stations held ``hold_s``, then a smooth move of ``move_s``).

    Returns:
        The parameter row (as in the stations) and whether the target is still.
    """
    period = hold_s + move_s
    k = int(t // period)
    if k >= stations.shape[0] - 1:
        return stations[-1].copy(), True
    tau = t - k * period
    if tau <= hold_s or move_s <= 0:
        return stations[k].copy(), True
    s = (tau - hold_s) / move_s
    w = 0.5 - 0.5 * math.cos(math.pi * s)
    a, b = stations[k], stations[k + 1]
    d = b - a
    if stations.shape[1] == 3 and not np.isclose(a[2], b[2]) and abs(d[2]) > 1.0:  # board yaw: wrap
        d[2] = (d[2] + math.pi) % (2 * math.pi) - math.pi
    return a + w * d, False


# ---------------------------------------------------------------------------------------------- laser
def _world(extra_seg: FloatArray | None = None) -> World:
    x0, x1, y0, y1 = ROOM
    seg = [[x0, y0, x1, y0], [x1, y0, x1, y1], [x1, y1, x0, y1], [x0, y1, x0, y0]]
    if extra_seg is not None:
        seg.append(list(extra_seg))
    s = np.array(seg, dtype=np.float64)
    n = s.shape[0]
    return World(
        seg=s,
        seg_z=np.tile([0.0, WALL_HEIGHT], (n, 1)),
        seg_color=np.full((n, 3), 200.0),
        seg_full=np.ones(n, dtype=bool),
        circ=np.zeros((0, 3)),
        circ_z=np.zeros((0, 2)),
        circ_color=np.zeros((0, 3)),
        rect=np.zeros((0, 5)),
        rect_color=np.zeros((0, 3)),
        rooms={"A": ROOM},
        doors=(),
        obstacles=np.zeros((0, 3)),
        floor_color={"A": (150.0, 146.0, 140.0)},
    )


def _board_segment(par: FloatArray) -> FloatArray:
    ex = np.array([-math.sin(par[2]), math.cos(par[2])])
    a = par[:2] - ex * BOARD_WIDTH / 2
    b = par[:2] + ex * BOARD_WIDTH / 2
    return np.array([a[0], a[1], b[0], b[1]])


def _cast(
    kind: str, par: FloatArray, rig: SimRig, rng: np.random.Generator | None, li: int, base: LaserCaster
):
    """One scan of laser ``li`` with the target at ``par``; returns the ScanResult and the target's hits."""
    robot = np.zeros(3)
    if kind == "ball":
        h = par[2] - LASER_Z
        r = math.sqrt(max(BALL_RADIUS**2 - h * h, 0.0))
        legs = np.array([[[par[0], par[1], r], [par[0], par[1], r]]])
        res = base.cast(rig.lasers[li], robot, legs, np.zeros(1), rng)
        return res, int(res.person_hits[0])
    if kind == "board":
        caster = LaserCaster(_world(_board_segment(par)), rig)
        res = caster.cast(rig.lasers[li], robot, np.zeros((0, 2, 3)), np.zeros(0), rng)
        seg = _board_segment(par)
        mid = 0.5 * (seg[:2] + seg[2:])
        ang = rig.lasers[li].base_angles()
        o = rig.lasers[li].pose.t[:2]
        pts = o + res.true_ranges[:, None] * np.stack([np.cos(ang), np.sin(ang)], 1)
        on = np.isfinite(res.true_ranges) & (np.hypot(*(pts - mid).T) <= BOARD_WIDTH / 2 + 0.01)
        return res, int(on.sum())
    res = base.cast(rig.lasers[li], robot, np.zeros((0, 2, 3)), np.zeros(0), rng)
    return res, 0


# ---------------------------------------------------------------------------------------------- main
def _check_args(scenario: str, seconds: float | None, seed: int, out: Path) -> tuple[_Calib, float]:
    sc = CALIB_SCENARIOS.get(scenario)
    if sc is None:
        raise SimError(f"unknown scenario '{scenario}' (calibration scenarios: {', '.join(CALIB_SCENARIOS)})")
    dur = sc.seconds if seconds is None else seconds
    try:
        dur = float(dur)
    except (TypeError, ValueError):
        raise SimError(f"--seconds must be a number, got {seconds!r}") from None
    period = sc.hold_s + sc.move_s
    if not (math.isfinite(dur) and 2 * period <= dur <= 600.0):
        raise SimError(f"--seconds must be in [{2 * period:g}, 600] for {scenario}, got {seconds}")
    if isinstance(seed, bool) or not isinstance(seed, int | np.integer) or seed < 0:
        raise SimError(f"--seed must be a non-negative integer, got {seed!r}")
    if out.exists() and not out.is_dir():
        raise SimError(f"--out {out}: exists and is not a directory")
    if out.is_dir() and any(p.name not in (*CALIB_OUTPUT_FILES, MANIFEST) for p in out.iterdir()):
        raise SimError(
            f"--out {out}: holds other files; give a new directory (or an earlier simulate output)"
        )
    return sc, dur


def _reference_uv(kind: str, par: FloatArray, cam: EquirectCamera) -> list[float]:
    """True pixel of the target's reference point (ball centre, board boundary centre, board centre)."""
    p = par[:3].copy()
    if kind == "board":
        p = np.array([par[0], par[1], LASER_Z])
    uv, _ = cam.project(p)
    return [round(float(uv[0]), 4), round(float(uv[1]), 4)]


def simulate_calib(
    scenario: str,
    *,
    out: Path | str,
    seconds: float | None = None,
    seed: int = 0,
    progress: Callable[[int, int], None] | None = None,
) -> SimResult:
    """Simulate a calibration scenario: ``recording.mcap``, ``rig.yaml``, ``truth.yaml``, ``targets.jsonl``.

    Args:
        scenario: ``calib-ball``, ``calib-board`` or ``calib-checkerboard``.
        out: output directory (replaced atomically if it holds an earlier output).
        seconds: duration, s (default 20 / 30 / 12 s).
        seed: random seed (stations, noise); the same seed gives the same files.
        progress: called as ``progress(done, total)`` after each image.

    Returns:
        A :class:`SimResult`; ``ground_truth_yaml`` is ``truth.yaml`` and ``ground_truth_jsonl`` is
        ``targets.jsonl``, ``num_gt`` the images with the target, ``num_people`` 0.

    Raises:
        SimError: unknown scenario, bad duration or seed, or an output directory that cannot be written.
    """
    from studio.io.base import LaserScan, Odometry
    from studio.io.rig import CameraConfig, LaserConfig, OdometryConfig, Rig, SyncConfig, save_rig
    from studio.io.writer import RecordingWriter

    t_start = time.perf_counter()
    out = Path(out)
    sc, dur = _check_args(scenario, seconds, seed, out)
    rig = SimRig(camera_rate_hz=sc.camera_rate_hz)
    r_st, r_laser = np.random.default_rng(np.random.SeedSequence(int(seed))).spawn(2)
    base_caster = LaserCaster(_world(), rig)
    period = sc.hold_s + sc.move_s
    n_st = int(dur // period) + (1 if sc.move_s > 0 else 0)

    def visible(row: FloatArray) -> bool:
        return max(_cast(sc.target, row, rig, None, li, base_caster)[1] for li in range(len(rig.lasers))) >= 8

    stations = _stations(sc.target, r_st, n_st, visible)
    cam = EquirectCamera(rig.width, rig.height, TRUE_CAMERA_POSE)
    bg = room_background(cam)

    events: list[tuple[float, int, int]] = []  # (header stamp s, kind: 0 odom, 1+li scan, 9 camera, index)
    events += [(k * 0.1, 0, k) for k in range(int(dur / 0.1) + 1)]
    for li, spec in enumerate(rig.lasers):
        n = math.floor((dur - spec.offset_s) * spec.rate_hz + 1e-9) + 1
        events += [(spec.offset_s + k / spec.rate_hz, 1 + li, k) for k in range(n)]
    n_cam = math.floor((dur - rig.camera_offset_s) * rig.camera_rate_hz + 1e-9) + 1
    events += [(rig.camera_offset_s + k / rig.camera_rate_hz + TRUE_LATENCY_S, 9, k) for k in range(n_cam)]
    events.sort()
    lines: list[str] = []
    n_img = n_scan = n_odom = n_gt = 0
    try:
        with atomic_dir(out, outputs=CALIB_OUTPUT_FILES, what="simulated calibration recording") as tmp:
            bag = tmp / "recording.mcap"
            with RecordingWriter(bag) as wr:
                wr.write_tf(
                    [(rig.base_frame, s.frame_id, START_NS, s.pose) for s in rig.lasers]
                    + [(rig.base_frame, rig.camera_frame, START_NS, NOMINAL_CAMERA_POSE)],
                    static=True,
                )
                for ts, kind, k in events:
                    stamp = START_NS + round(ts * 1e9)
                    if kind == 0:
                        od = Odometry(stamp, rig.odom_frame, rig.base_frame, Pose2(0.0, 0.0, 0.0))
                        wr.write_odometry(rig.odom_topic, od, vx=0.0, wz=0.0)
                        wr.write_tf([(rig.odom_frame, rig.base_frame, stamp, Pose3.identity())], static=False)
                        n_odom += 1
                    elif kind < 9:
                        spec = rig.lasers[kind - 1]
                        par, _ = target_state(stations, ts, hold_s=sc.hold_s, move_s=sc.move_s)
                        res, _ = _cast(sc.target, par, rig, r_laser, kind - 1, base_caster)
                        scan = LaserScan(
                            stamp_ns=stamp,
                            frame_id=spec.frame_id,
                            angle_min=spec.angle_min,
                            angle_increment=spec.angle_increment,
                            ranges=res.ranges,
                            range_min=spec.range_min,
                            range_max=spec.range_max,
                        )
                        wr.write_scan(spec.topic, scan)
                        n_scan += 1
                    else:
                        t_cap = ts - TRUE_LATENCY_S
                        par, still = target_state(stations, t_cap, hold_s=sc.hold_s, move_s=sc.move_s)
                        img = render_target(sc.target, par, bg, cam)
                        ok, buf = cv2.imencode(".jpg", img, [cv2.IMWRITE_JPEG_QUALITY, 95])
                        if not ok:  # pragma: no cover
                            raise SimError("JPEG encoding failed")
                        wr.write_compressed_image(
                            rig.camera_topic, stamp, rig.camera_frame, buf.tobytes(), "jpeg"
                        )
                        rec = {
                            "frame": k,
                            "stamp_ns": stamp,
                            "capture_ns": START_NS + round(t_cap * 1e9),
                            "target": sc.target,
                            "params": [round(float(x), 6) for x in par],
                            "still": still,
                            "uv": _reference_uv(sc.target, par, cam),
                        }
                        lines.append(json.dumps(rec))
                        n_img += 1
                        n_gt += 1
                        if progress is not None:
                            progress(k + 1, n_cam)
            rig_cfg = Rig(
                base_frame=rig.base_frame,
                odometry=OdometryConfig(topic=rig.odom_topic),
                camera=CameraConfig(topic=rig.camera_topic, pose=NOMINAL_CAMERA_POSE),
                lasers=tuple(LaserConfig(topic=s.topic, pose=s.pose) for s in rig.lasers),
                sync=SyncConfig(max_dt_s=0.05, camera_latency_s=0.0),
            )
            save_rig(rig_cfg, tmp / "rig.yaml")
            truth = {
                "scenario": sc.name,
                "seed": int(seed),
                "seconds": dur,
                "target": sc.target,
                "camera_pose": {k: round(v, 9) for k, v in TRUE_CAMERA_POSE.as_dict().items()},
                "camera_pose_nominal": NOMINAL_CAMERA_POSE.as_dict(),
                "camera_latency_s": TRUE_LATENCY_S,
                "camera_rate_hz": rig.camera_rate_hz,
                "image_size": [rig.width, rig.height],
                "laser_z": LASER_Z,
                "ball_radius": BALL_RADIUS,
                "board": {
                    "width": BOARD_WIDTH,
                    "bottom": BOARD_HEIGHT[0],
                    "top": BOARD_HEIGHT[1],
                    "boundary_z": LASER_Z,
                },
                "checkerboard": {"squares": list(CHECKER_SQUARES), "square": CHECKER_SQUARE},
                "hold_s": sc.hold_s,
                "move_s": sc.move_s,
                "stations": [[round(float(x), 6) for x in row] for row in stations],
            }
            (tmp / "truth.yaml").write_text(yaml.safe_dump(truth, sort_keys=False))
            (tmp / "targets.jsonl").write_text("".join(line + "\n" for line in lines))
            size = bag.stat().st_size
    except OSError as exc:
        raise SimError(f"--out {out}: cannot write ({exc.strerror or exc})") from None
    return SimResult(
        out=out,
        recording=out / "recording.mcap",
        rig=out / "rig.yaml",
        ground_truth_yaml=out / "truth.yaml",
        ground_truth_jsonl=out / "targets.jsonl",
        scenario=sc.name,
        seed=int(seed),
        seconds=dur,
        num_images=n_img,
        num_scans=n_scan,
        num_odometry=n_odom,
        num_people=0,
        num_gt=n_gt,
        odom_drift_m=0.0,
        bytes=int(size),
        wall_s=time.perf_counter() - t_start,
    )


def sample_stations(kind: str, n: int, *, seed: int = 0) -> FloatArray:
    """``n`` target stations as a calibration scenario places them (rows as in ``truth.yaml``).

    Args:
        kind: ``ball``, ``board`` or ``checkerboard``.
        n: stations wanted (ball and board stations the lasers cannot see are left out).
        seed: random seed.
    """
    if kind not in SUPERSAMPLE:
        raise SimError(f"unknown target '{kind}' (ball, board, checkerboard)")
    rig = SimRig()
    base = LaserCaster(_world(), rig)

    def visible(row: FloatArray) -> bool:
        return max(_cast(kind, row, rig, None, li, base)[1] for li in range(len(rig.lasers))) >= 8

    return _stations(kind, np.random.default_rng(seed), n, visible)


def render_target_panorama(
    kind: str, params: FloatArray, *, width: int = 1920, height: int = 960, pose: Pose3 = TRUE_CAMERA_POSE
) -> NDArray[np.uint8]:
    """One noise-free panorama (BGR, no JPEG) of the calibration room with the target at ``params``.

    Args:
        kind: ``ball``, ``board`` or ``checkerboard``.
        params: the target's parameters (a row of :func:`sample_stations`).
        width, height: panorama size, px (2:1).
        pose: camera pose ``T_base_cam`` (the robot stands at the world origin).
    """
    if kind not in SUPERSAMPLE:
        raise SimError(f"unknown target '{kind}' (ball, board, checkerboard)")
    cam = EquirectCamera(width, height, pose)
    return render_target(kind, np.asarray(params, dtype=np.float64), cached_background(cam), cam)
