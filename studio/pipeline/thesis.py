"""The thesis method, as a baseline to compare against (``studio label --method thesis``; issue 3, item 6).

Faithful to the thesis on identical inputs, with the two calibration shortcuts it relied on replaced by the
rig's true camera pose (so the comparison measures the method, not a bad calibration):

1. the panorama is cut into the four side faces of a cube (front, left, back, right; 90°, ``f = size/2``,
   ``size = W/4``) and people are detected on each face;
2. laser people (the same classical detector as ours, without the static-world filter) and scan points are
   assigned to a face by their azimuth about the robot origin (the thesis's Algorithm 3.1: front
   [-45°, 45°), left [45°, 135°), back, right);
3. each face projects its laser points with its own pinhole model; a box keeps the laser detection that
   projects inside it closest to the robot, else the scan point inside it closest to the robot;
4. the positions, in the robot frame (no odometry), are tracked with a UKF and plain nearest-neighbour
   association.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from studio.errors import StudioError
from studio.fuse.base import PersonObservations
from studio.geometry import EquirectCamera, PerspectiveView, ViewRenderer, cube_faces
from studio.geometry.se import Pose3
from studio.labels.base import LabelFrame, LabelPerson, as_box
from studio.pipeline.base import FrameResult, LabelOptions

__all__ = ["assign_face", "label_thesis", "thesis_fuse"]

FloatArray = NDArray[np.float64]
_FACE_ORDER = ("front", "left", "back", "right")


def assign_face(xy: FloatArray) -> NDArray[np.int64]:
    """Algorithm 3.1: face index (0 front, 1 left, 2 back, 3 right) of robot-frame points ``(N, 2)``."""
    az = np.degrees(np.arctan2(xy[:, 1], xy[:, 0]))
    return (np.floor((az + 45.0) / 90.0).astype(np.int64)) % 4


def _face_project(face: PerspectiveView, camera: EquirectCamera, pts_base: FloatArray) -> FloatArray:
    """Pinhole projection of base-frame points into a face (NaN behind it), px."""
    p_cam = camera.pose.inverse().apply(pts_base)
    return face.pixel_of_rays(p_cam)


def thesis_fuse(
    face_boxes: list[tuple[FloatArray, FloatArray]],
    faces: list[PerspectiveView],
    camera: EquirectCamera,
    laser_xyz: FloatArray,
    laser_scores: FloatArray,
    scan_xyz: FloatArray,
    *,
    sigma: float = 0.1,
) -> PersonObservations:
    """Steps 2–3 of the module docstring for one frame; positions in the robot (base) frame."""
    las_face = assign_face(laser_xyz[:, :2]) if len(laser_xyz) else np.zeros(0, np.int64)
    pts_face = assign_face(scan_xyz[:, :2]) if len(scan_xyz) else np.zeros(0, np.int64)
    out = []
    W, H = camera.width, camera.height
    for k, (face, (boxes, scores)) in enumerate(zip(faces, face_boxes, strict=True)):
        if not len(boxes):
            continue
        li = np.flatnonzero(las_face == k)
        pi = np.flatnonzero(pts_face == k)
        luv = _face_project(face, camera, laser_xyz[li]) if len(li) else np.zeros((0, 2))
        puv = _face_project(face, camera, scan_xyz[pi]) if len(pi) else np.zeros((0, 2))
        lrange = np.hypot(laser_xyz[li, 0], laser_xyz[li, 1])
        prange = np.hypot(scan_xyz[pi, 0], scan_xyz[pi, 1])
        for b, box in enumerate(boxes):
            u1, v1, u2, v2 = box
            pano_box = face.box_to_pano(box, W, H)[0]
            inside = (luv[:, 0] >= u1) & (luv[:, 0] <= u2) & (luv[:, 1] >= v1) & (luv[:, 1] <= v2)
            if inside.any():
                j = np.flatnonzero(inside)[np.argmin(lrange[inside])]
                xy, how, src, lidx = laser_xyz[li[j], :2], "laser-detection", "fused", int(li[j])
                sc = float(max(scores[b], laser_scores[li[j]]))
            else:
                inside = (puv[:, 0] >= u1) & (puv[:, 0] <= u2) & (puv[:, 1] >= v1) & (puv[:, 1] <= v2)
                if not inside.any():
                    continue
                j = np.flatnonzero(inside)[np.argmin(prange[inside])]
                xy, how, src, lidx = scan_xyz[pi[j], :2], "scan-cluster", "fused", -1
                sc = float(scores[b])
            out.append(
                PersonObservations(
                    np.asarray(xy)[None],
                    (sigma**2 * np.eye(2))[None],
                    np.array([sc]),
                    (src,),
                    (how,),
                    pano_box[None],
                    np.array([b]),
                    np.array([lidx]),
                )
            )
    return PersonObservations.concat(out)


def label_thesis(
    recording: Path,
    rig: Any,
    options: LabelOptions,
    *,
    progress: Callable[[int, int], None] | None = None,
    on_frame: Callable[[Any, Any], None] | None = None,
) -> Any:
    """Run the thesis method over a recording; returns a :class:`studio.pipeline.label.LabelRun`."""
    from studio.detect.image import get_image_detector
    from studio.detect.laser import get_laser_detector
    from studio.io import count_frames, iter_frames, open_recording, resolve_sensor_poses
    from studio.io.sync import SyncReport
    from studio.pipeline.label import LabelRun
    from studio.pipeline.perceive import laser_frame, laser_in_base, require_camera_pose
    from studio.track.base import Observations
    from studio.track.thesis import ThesisTracker

    use_camera = rig.camera is not None and options.sources in ("both", "camera")
    use_laser = options.sources in ("both", "laser")
    if use_camera and not use_laser:
        raise StudioError("the thesis method needs the laser (it has no image-only range)")
    detector = get_image_detector(options.image_detector or "movenet") if use_camera else None
    laser_detector = get_laser_detector(options.laser_detector or "classical")
    renderer = ViewRenderer()
    faces: list[PerspectiveView] = []
    camera: EquirectCamera | None = None
    report = SyncReport()
    fused: list[FrameResult] = []
    t = {"read_decode_sync": 0.0, "image_detection": 0.0, "laser_detection": 0.0, "fusion": 0.0}
    size = None
    t0 = time.perf_counter()
    with open_recording(recording) as rec:
        rig = resolve_sensor_poses(rec, rig)
        if use_camera:
            require_camera_pose(rec, rig)
        total = count_frames(rec, rig)
        tick = time.perf_counter()
        for frame in iter_frames(rec, rig, report=report):
            t1 = time.perf_counter()
            t["read_decode_sync"] += t1 - tick
            face_boxes: list[tuple[FloatArray, FloatArray]] = []
            stamp = frame.stamp_ns
            if use_camera and frame.panorama is not None and detector is not None:
                pano = frame.panorama.image
                stamp = frame.panorama.stamp_ns
                if camera is None:
                    size = (pano.shape[1], pano.shape[0])
                    pose = rig.camera.pose if rig.camera.pose is not None else Pose3.identity()
                    camera = EquirectCamera(pano.shape[1], pano.shape[0], pose, rig.camera.lens_offset)
                    all_faces = cube_faces(max(32, pano.shape[1] // 4))
                    faces = [all_faces[n] for n in _FACE_ORDER]
                # the faces run on the detector's threads, as our sweep's views do
                views = detector.detect_views(renderer.render_many(pano, faces))  # type: ignore[attr-defined]
                face_boxes.extend((vd.boxes, vd.scores) for vd in views)
            t2 = time.perf_counter()
            t["image_detection"] += t2 - t1
            laser, laser_z, points, origins, owner = laser_in_base(frame, laser_detector)
            t3 = time.perf_counter()
            t["laser_detection"] += t3 - t2
            laser_xyz = np.c_[laser.xy, laser_z] if len(laser.xy) else np.zeros((0, 3))
            scan_xyz = points[np.isfinite(points[:, 0])].astype(np.float64)
            if camera is not None and use_camera:
                obs = thesis_fuse(face_boxes, faces, camera, laser_xyz, laser.scores, scan_xyz)
            else:  # laser only: every laser detection is a person
                n = len(laser.xy)
                obs = PersonObservations(
                    laser.xy,
                    np.repeat((0.1**2 * np.eye(2))[None], n, 0),
                    laser.scores,
                    ("laser",) * n,
                    ("laser-only",) * n,
                    np.full((n, 4), np.nan),
                    np.full(n, -1),
                    np.arange(n),
                )
            t["fusion"] += time.perf_counter() - t3
            fused.append(FrameResult(frame.index, stamp, frame.robot_pose, obs))
            if on_frame is not None:
                on_frame(frame, laser_frame(frame, stamp, (laser, laser_z, points, origins, owner)))
            if progress is not None:
                progress(len(fused), total)
            tick = time.perf_counter()
    if not fused:
        raise StudioError(f"{recording}: no frame could be built: {report.why_empty()}")
    t4 = time.perf_counter()
    tracker = ThesisTracker()
    labels = []
    for fr in fused:
        o = fr.observations
        est = tracker.step(Observations(fr.stamp_ns, o.xy, o.cov, o.source, o.score, None, np.arange(len(o))))
        people = []
        for e in est:
            if e.state != "confirmed" or e.det_index < 0:
                continue
            x_odom, y_odom = fr.robot_pose.apply(e.xy)
            j = e.det_index
            box = as_box(o.box[j])
            people.append(
                LabelPerson(
                    id=e.track_id,
                    x=float(e.xy[0]),
                    y=float(e.xy[1]),
                    x_odom=float(x_odom),
                    y_odom=float(y_odom),
                    source=o.source[j],
                    box=box,
                    score=float(o.score[j]),
                )
            )
        labels.append(LabelFrame(fr.index, tuple(people), fr.stamp_ns, fr.robot_pose))
    t["tracking"] = time.perf_counter() - t4
    t["pass1_total"] = t4 - t0
    counts = {
        "frames": len(fused),
        "observations": int(sum(len(f.observations) for f in fused)),
        "tracks": len({p.id for lf in labels for p in lf.people}),
        "sync": report.summary(),
    }
    return LabelRun(labels, fused, size, camera, t, counts, ["method: thesis baseline"])
