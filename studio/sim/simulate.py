"""Run a scenario and write the recording, the rig and the ground truth (``studio simulate``).

Output directory (built in a temporary sibling and renamed into place, so a failure leaves no half
result):

* ``recording.mcap`` — a ROS2 MCAP bag: ``/theta_camera/image/compressed`` (sensor_msgs/CompressedImage,
  1920×960 equirectangular JPEG, 10 Hz), ``/scan_front`` and ``/scan_rear`` (sensor_msgs/LaserScan,
  270°, 0.25°, 40 Hz), ``/odom`` (nav_msgs/Odometry, 50 Hz), ``/tf`` (odom → base_link, 50 Hz) and
  ``/tf_static`` (base_link → laser_front, laser_rear, camera_link);
* ``rig.yaml`` — the true sensor poses;
* ``ground_truth.yaml`` (thesis format) and ``ground_truth.jsonl`` — one frame per camera image.

Ground truth: a person is listed in a frame when within :data:`GT_MAX_RANGE` of the robot and visible to
at least one sensor at the image stamp: the camera (at least :data:`CAM_MIN_PIXELS` unoccluded pixels and
5 % of the figure) or a laser (at least :data:`LASER_MIN_BEAMS` beams of a noise-free scan taken at the
image stamp end on the person's legs). Positions are the point on the floor between the feet (the body
centre), in ``base_link`` (``x``, ``y``) and in the published, drifting ``odom`` frame (``x_odom``,
``y_odom``, from the odometry interpolated at the image stamp). ``box`` is the tight box of the person's
visible pixels; the JSON lines also carry ``visible`` per sensor, ``box_full`` (unoccluded figure),
``visible_frac``, ``laser_beams``, ``range``, ``speed`` and the true world position (``x_world``,
``y_world``); ``robot_pose`` is the odometry pose and ``robot_world`` the true pose of the robot.

Laser conventions: a beam with nothing within ``range_max`` reads ``+inf``; a dropout (dark trousers and
thin furniture legs drop a few percent of returns, grazing walls and far targets more) and a beam that
hits the robot's own body read ``NaN``. The robot body hides the sides from both lasers (front at
x = +0.40 m, rear at x = -0.40 m): someone standing right beside the robot is seen by the camera only.
"""

from __future__ import annotations

import math
import os
import threading
import time
from collections.abc import Callable
from concurrent.futures import Future, ThreadPoolExecutor
from pathlib import Path

import cv2
import numpy as np

from studio.atomic import MANIFEST, atomic_dir
from studio.geometry.se import Pose2, Pose3
from studio.labels import LabelFrame, LabelPerson
from studio.labels.formats import write_labels_jsonl, write_labels_yaml
from studio.sim.base import LASER_Z, SimResult, SimRig
from studio.sim.body import Appearance, body_capsules, draw_appearance, leg_circles
from studio.sim.errors import SimError
from studio.sim.laser import LaserCaster
from studio.sim.motion import DT, Motion, simulate_motion
from studio.sim.render import PanoramaRenderer
from studio.sim.scenarios import get_scenario
from studio.sim.world import build_world

__all__ = [
    "CAM_MIN_PIXELS",
    "GT_MAX_RANGE",
    "LASER_MIN_BEAMS",
    "OUTPUT_FILES",
    "SIM_VERSION",
    "START_NS",
    "simulate",
]

START_NS = 1_700_000_000_000_000_000
"""Stamp of the recording start, ns (fixed, so a seed gives identical bytes)."""
SIM_VERSION = 6
"""Raised whenever a scenario and seed simulate differently than before (2: bodies no longer overlap; 3:
someone whose way a person blocks walks around them instead of passing through them after 2 s; 4: someone
who stepped around a person to within 0.3 m of furniture can still plan a way out, where before they
stood there for good; 5: nobody stands pressed against a door jamb for good: a step into a wall slides
along it, two people meeting in a door passage keep to its opposite sides, and a route from inside a door
passage leaves it along the door's axis; 6: walkers predict their closest approach to each other and
sidestep early when it is under 1 m, instead of meeting at the 0.4 m body floor), so generated recordings
that are kept (``studio demo``'s default) are made again."""
GT_MAX_RANGE = 10.0
CAM_MIN_PIXELS = 25
LASER_MIN_BEAMS = 3
MAX_SECONDS = 3600.0
_AHEAD = 4  # panoramas rendered ahead of the writer
_RENDER_THREADS = 2
OUTPUT_FILES = ("recording.mcap", "rig.yaml", "ground_truth.yaml", "ground_truth.jsonl")

Progress = Callable[[int, int], None]


def _ns(t: float) -> int:
    return START_NS + round(t * 1e9)


def _pose3(p: Pose2) -> Pose3:
    return Pose3.from_xyz_rpy(p.x, p.y, 0.0, yaw=p.yaw)


def simulate(
    scenario: str,
    *,
    out: Path | str,
    seconds: float | None = None,
    seed: int = 0,
    progress: Progress | None = None,
    rig: SimRig | None = None,
) -> SimResult:
    """Simulate ``scenario`` and write its recording, rig and ground truth into ``out``.

    Args:
        scenario: ``static``, ``moving`` or ``rooms``; ``calib-ball``, ``calib-board`` and
            ``calib-checkerboard`` are dispatched to :func:`studio.sim.calib.simulate_calib`.
        out: output directory (replaced atomically if it exists).
        seconds: duration, s (default: the scenario's, 50 / 96 / 165 s).
        seed: random seed; the same seed gives the same messages and ground truth.
        progress: called as ``progress(done, total)`` after each camera frame.
        rig: the simulated robot (default :class:`SimRig`).

    Returns:
        The :class:`SimResult` (paths and summary numbers).

    Raises:
        SimError: unknown scenario, bad duration, or ``out`` is not a writable directory.
    """
    if isinstance(scenario, str) and scenario.startswith("calib-"):
        from studio.sim.calib import simulate_calib

        if rig is not None:
            raise SimError(f"scenario {scenario} uses its own rig (rig= is not supported)")
        return simulate_calib(scenario, out=out, seconds=seconds, seed=seed, progress=progress)
    t_start = time.perf_counter()
    sc = get_scenario(scenario)
    dur = sc.seconds if seconds is None else seconds
    try:
        dur = float(dur)
    except (TypeError, ValueError):
        raise SimError(f"--seconds must be a number, got {seconds!r}") from None
    if not (math.isfinite(dur) and 0.0 < dur <= MAX_SECONDS):
        raise SimError(f"--seconds must be in (0, {MAX_SECONDS:.0f}], got {seconds}")
    if isinstance(seed, bool) or not isinstance(seed, int | np.integer) or seed < 0:
        raise SimError(f"--seed must be a non-negative integer, got {seed!r}")
    out = Path(out)
    if out.exists() and not out.is_dir():
        raise SimError(f"--out {out}: exists and is not a directory")
    if out.is_dir() and any(p.name not in (*OUTPUT_FILES, MANIFEST) for p in out.iterdir()):
        raise SimError(
            f"--out {out}: holds other files; give a new directory (or an earlier simulate output)"
        )
    rig = rig or SimRig()
    _check_rig(rig)
    world = build_world()
    r_motion, r_app, r_laser = np.random.default_rng(np.random.SeedSequence(int(seed))).spawn(3)
    motion = simulate_motion(sc, world, seconds=dur, rng=r_motion)
    n_people = motion.people.shape[0]
    apps = [draw_appearance(r_app) for _ in range(n_people)]
    heights = np.array([a.height for a in apps])
    dark = np.array([a.dark for a in apps])
    caster = LaserCaster(world, rig)
    cam_t = rig.camera_pose.t
    local = threading.local()

    def renderer() -> PanoramaRenderer:
        """Each render thread has its own renderer (they keep per-frame buffers and a background cache)."""
        if not hasattr(local, "renderer"):
            local.renderer = PanoramaRenderer(
                world,
                width=rig.width,
                height=rig.height,
                zc=float(cam_t[2]),
                cam_xy=(float(cam_t[0]), float(cam_t[1])),
                cam_yaw=rig.camera_pose.to_pose2().yaw,
                body=(rig.body_length, rig.body_width, rig.body_height),
            )
        r: PanoramaRenderer = local.renderer
        return r

    # every message as (time s, order, kind, index), written in stamp order
    events: list[tuple[float, int, str, int]] = []
    n_odom = math.ceil(dur / DT - 1e-9) + 1  # the last odometry (and TF) is not before any other stamp
    events += [(k * DT, 0, "odom", k) for k in range(n_odom)]
    for li, spec in enumerate(rig.lasers):
        n = math.floor((dur - spec.offset_s) * spec.rate_hz + 1e-9) + 1
        events += [
            (spec.offset_s + k / spec.rate_hz, 1 + li, "scan", li * 1_000_000 + k) for k in range(max(n, 0))
        ]
    n_cam = math.floor((dur - rig.camera_offset_s) * rig.camera_rate_hz + 1e-9) + 1
    n_cam = max(n_cam, 0)
    events += [(rig.camera_offset_s + k / rig.camera_rate_hz, 9, "camera", k) for k in range(n_cam)]
    events.sort()

    from studio.io.base import LaserScan
    from studio.io.rig import CameraConfig, LaserConfig, OdometryConfig, Rig, SyncConfig, save_rig
    from studio.io.writer import RecordingWriter

    frames: list[LabelFrame] = []
    counts = {"odom": 0, "scan": 0, "camera": 0}
    n_gt = 0
    cam_times = {idx: t for t, _, kind, idx in events if kind == "camera"}

    def render(k: int) -> Future[tuple[LabelFrame, bytes]]:
        t = cam_times[k]
        return pool.submit(
            lambda: _camera_frame(k, t, _ns(t), motion, apps, heights, dark, caster, renderer(), rig)
        )

    # panoramas are rendered (and JPEG-encoded) a few frames ahead in worker threads while this thread
    # casts the scans; numpy and OpenCV release the GIL for the heavy array work, so the cores share it
    pool = ThreadPoolExecutor(max_workers=_RENDER_THREADS, thread_name_prefix="studio-sim-render")
    pending: dict[int, Future[tuple[LabelFrame, bytes]]] = {k: render(k) for k in range(min(_AHEAD, n_cam))}
    try:
        with atomic_dir(out, outputs=OUTPUT_FILES, what="simulated recording") as tmp:
            bag = tmp / "recording.mcap"
            with RecordingWriter(bag) as wr:
                wr.write_tf(
                    [(rig.base_frame, s.frame_id, START_NS, s.pose) for s in rig.lasers]
                    + [(rig.base_frame, rig.camera_frame, START_NS, rig.camera_pose)],
                    static=True,
                )
                for t, _, kind, idx in events:
                    stamp = _ns(t)
                    if kind == "odom":
                        _write_odom(wr, rig, motion.odom, idx, stamp)
                    elif kind == "scan":
                        spec = rig.lasers[idx // 1_000_000]
                        res = caster.cast_sweep(
                            spec,
                            t,
                            motion.robot_at,
                            lambda when: leg_circles(motion.people_at(when), heights),
                            dark,
                            r_laser,
                        )
                        wr.write_scan(
                            spec.topic,
                            LaserScan(
                                stamp_ns=stamp,
                                frame_id=spec.frame_id,
                                angle_min=spec.angle_min,
                                angle_increment=spec.angle_increment,
                                ranges=res.ranges,
                                range_min=spec.range_min,
                                range_max=spec.range_max,
                                time_increment=spec.sweep_s / max(spec.n_beams - 1, 1),
                            ),
                        )
                    else:
                        frame, jpeg = pending.pop(idx).result()
                        if idx + _AHEAD < n_cam:
                            pending[idx + _AHEAD] = render(idx + _AHEAD)
                        wr.write_compressed_image(rig.camera_topic, stamp, rig.camera_frame, jpeg, "jpeg")
                        frames.append(frame)
                        n_gt += len(frame.people)
                        if progress is not None:
                            progress(idx + 1, n_cam)
                    counts[kind] += 1
            rig_cfg = Rig(
                base_frame=rig.base_frame,
                odometry=OdometryConfig(topic=rig.odom_topic),
                camera=CameraConfig(topic=rig.camera_topic, pose=rig.camera_pose),
                lasers=tuple(LaserConfig(topic=s.topic, pose=s.pose) for s in rig.lasers),
                sync=SyncConfig(max_dt_s=0.05, camera_latency_s=0.0),
            )
            save_rig(rig_cfg, tmp / "rig.yaml")
            write_labels_yaml(tmp / "ground_truth.yaml", frames)
            write_labels_jsonl(tmp / "ground_truth.jsonl", frames)
            size = bag.stat().st_size
            _public_modes(tmp)
    except OSError as exc:
        raise SimError(f"--out {out}: cannot write ({exc.strerror or exc})") from None
    finally:
        for fut in pending.values():
            fut.cancel()
        pool.shutdown(wait=True)
    end = Pose2(*motion.robot_at(dur))
    start = Pose2(*motion.robot[0])
    true_rel = start.inverse().compose(end)
    od = motion.odom_at(dur)
    drift = float(np.hypot(true_rel.x - od[0], true_rel.y - od[1]))
    return SimResult(
        out=out,
        recording=out / "recording.mcap",
        rig=out / "rig.yaml",
        ground_truth_yaml=out / "ground_truth.yaml",
        ground_truth_jsonl=out / "ground_truth.jsonl",
        scenario=sc.name,
        seed=int(seed),
        seconds=dur,
        num_images=counts["camera"],
        num_scans=counts["scan"],
        num_odometry=counts["odom"],
        num_people=n_people,
        num_gt=n_gt,
        odom_drift_m=drift,
        bytes=int(size),
        wall_s=time.perf_counter() - t_start,
    )


def _check_rig(rig: SimRig) -> None:
    """The renderer and the ray caster model a level camera and level lasers (upright or upside down) at
    :data:`LASER_Z`."""
    roll, pitch, _ = rig.camera_pose.rpy()
    if abs(roll) > 1e-9 or abs(pitch) > 1e-9:
        raise SimError("the simulated camera must be level (roll = pitch = 0)")
    for spec in rig.lasers:
        if not 0.0 <= spec.sweep_s < 1.0 / spec.rate_hz:
            raise SimError(
                f"simulated laser {spec.frame_id}: sweep_s must be in [0, 1 / rate_hz), got {spec.sweep_s}"
            )
        r, p, _ = spec.pose.rpy()  # level: upright (roll 0) or upside down (roll π)
        if abs(np.sin(r)) > 1e-9 or abs(p) > 1e-9 or abs(float(spec.pose.t[2]) - LASER_Z) > 1e-9:
            raise SimError(
                f"simulated laser {spec.frame_id} must be level (upright or upside down) at z = {LASER_Z} m"
            )
    if rig.width != 2 * rig.height:
        raise SimError(f"panorama must be twice as wide as high, got {rig.width}×{rig.height}")


def _public_modes(directory: Path) -> None:
    """Give the output the usual permissions (temporary files and directories are private)."""
    umask = os.umask(0)
    os.umask(umask)
    os.chmod(directory, 0o777 & ~umask)
    for p in directory.iterdir():
        os.chmod(p, 0o666 & ~umask)


def _write_odom(wr: object, rig: SimRig, odom: np.ndarray, k: int, stamp: int) -> None:
    from studio.io.base import Odometry

    x, y, yaw = (float(v) for v in odom[k])
    nxt = odom[min(k + 1, odom.shape[0] - 1)]
    dx, dy = float(nxt[0]) - x, float(nxt[1]) - y
    vx = (np.cos(yaw) * dx + np.sin(yaw) * dy) / DT
    wz = float((nxt[2] - yaw + np.pi) % (2 * np.pi) - np.pi) / DT
    pose = Pose2(x, y, yaw)
    wr.write_odometry(  # type: ignore[attr-defined]
        rig.odom_topic, Odometry(stamp, rig.odom_frame, rig.base_frame, pose), vx=float(vx), wz=wz
    )
    wr.write_tf([(rig.odom_frame, rig.base_frame, stamp, _pose3(pose))], static=False)  # type: ignore[attr-defined]


def _camera_frame(
    k: int,
    t: float,
    stamp: int,
    motion: Motion,
    apps: list[Appearance],
    heights: np.ndarray,
    dark: np.ndarray,
    caster: LaserCaster,
    renderer: PanoramaRenderer,
    rig: SimRig,
) -> tuple[LabelFrame, bytes]:
    """Render image ``k`` at ``t`` s and build its ground-truth frame."""
    states = motion.people_at(t)
    robot = motion.robot_at(t)
    T_wb = Pose2(*robot)
    cam_off = T_wb.apply(rig.camera_pose.t[:2])
    cam = np.array([cam_off[0], cam_off[1], robot[2] + rig.camera_pose.to_pose2().yaw])
    people = [(body_capsules(states[i], apps[i]), apps[i]) for i in range(states.shape[0])]
    img, info = renderer.render(cam, people, states[:, :2])
    ok, buf = cv2.imencode(".jpg", img, [cv2.IMWRITE_JPEG_QUALITY, rig.jpeg_quality])
    if not ok:  # pragma: no cover - OpenCV always encodes a uint8 image
        raise SimError("JPEG encoding failed")
    legs = leg_circles(states, heights)
    beams = np.stack([caster.cast(s, robot, legs, dark, None).person_hits for s in rig.lasers])  # (L, P)
    od = motion.odom_at(t)
    T_ob = Pose2(*od)
    p_base = T_wb.inverse().apply(states[:, :2])
    p_odom = T_ob.apply(p_base)
    people_gt = []
    for i in range(states.shape[0]):
        rng_i = float(np.hypot(*p_base[i]))
        r = info[i]
        cam_vis = r.visible >= CAM_MIN_PIXELS and r.visible >= 0.05 * max(r.pixels, 1)
        las_vis = [bool(b >= LASER_MIN_BEAMS) for b in beams[:, i]]
        if rng_i > GT_MAX_RANGE or not (cam_vis or any(las_vis)):
            continue
        visible = {"camera": bool(cam_vis)}
        visible.update(
            {s.frame_id.replace("laser_", "") + "_laser": v for s, v in zip(rig.lasers, las_vis, strict=True)}
        )
        extra = {
            "visible": visible,
            "visible_frac": round(r.visible / max(r.pixels, 1), 4),
            "laser_beams": {
                s.frame_id.replace("laser_", ""): int(b) for s, b in zip(rig.lasers, beams[:, i], strict=True)
            },
            "range": round(rng_i, 4),
            "speed": round(float(states[i, 3]), 4),
            "x_world": round(float(states[i, 0]), 4),
            "y_world": round(float(states[i, 1]), 4),
        }
        if r.box_full is not None:
            extra["box_full"] = list(r.box_full)
        people_gt.append(
            LabelPerson(
                id=i,
                x=float(p_base[i, 0]),
                y=float(p_base[i, 1]),
                x_odom=float(p_odom[i, 0]),
                y_odom=float(p_odom[i, 1]),
                source="gt",
                box=r.box if cam_vis else None,
                extra=extra,
            )
        )
    frame = LabelFrame(
        frame=k,
        people=tuple(people_gt),
        stamp_ns=stamp,
        robot_pose=T_ob,
        extra={"robot_world": T_wb.as_dict()},
    )
    return frame, buf.tobytes()
