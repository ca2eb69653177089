"""Log a calibration result to Rerun, under the entities the ``calibration`` blueprint shows.

Entities (all static except the residual series)::

    camera/panorama                         the panorama (when given), else nothing
    camera/panorama/scan/frame              Boxes2D the panorama's outline (extent without an image)
    camera/panorama/scan/observed           Points2D observed pixels (green inlier, red rejected outlier)
    camera/panorama/scan/projected          Points2D the points projected with the fitted pose ("after")
    camera/panorama/scan/projected_before   Points2D projected with the starting pose ("before"), if given
    camera/panorama/scan/residuals          Arrows2D observed → projected (held-out when cross-validated)
    camera/faces/*                          cube faces of the panorama (when given)
    camera/faces/*/scan/{before,after}      Points2D the points projected into the face with each pose
    world/odom/robot/calibration/points     Points3D the correspondences' 3-D points (base frame)
    world/odom/robot/sensors/camera         Transform3D + axes, the fitted camera pose
    metrics/calibration/{col_px,row_px}     Scalars, one per correspondence on the ``frame`` timeline
                                            (frame = correspondence index), held-out errors when available

Only this module and the rest of :mod:`studio.viz` import rerun; algorithms hand their results here.
"""

from __future__ import annotations

import contextlib
import os
import tempfile
from pathlib import Path
from typing import Any

import cv2
import numpy as np
import rerun as rr
from numpy.typing import ArrayLike, NDArray

from studio.calibrate.extrinsics import CrossValidation, ExtrinsicsFit, project_points
from studio.geometry import EquirectCamera, ViewRenderer, cube_faces
from studio.geometry.se import Pose3
from studio.viz import paths as ep

__all__ = ["log_calibration", "write_calibration_rrd"]

_INLIER = (90, 220, 90)
_OUTLIER = (235, 60, 60)
_AFTER = (60, 170, 255)
_BEFORE = (255, 170, 40)


def _face_points(
    rec: rr.RecordingStream,
    path: str,
    face: Any,
    pose: Pose3,
    xyz: NDArray[np.float64],
    color: tuple[int, int, int],
    lens_offset: float = 0.0,
) -> None:
    p_cam = pose.inverse().apply(xyz)
    if lens_offset:  # the dual-lens model (studio.geometry.equirect): seen from the nearer lens centre
        p_cam[:, 0] -= np.sign(p_cam[:, 0]) * lens_offset
    uv = face.pixel_of_rays(p_cam)
    ok = np.all(np.isfinite(uv), axis=1) & (uv[:, 0] >= 0) & (uv[:, 0] < face.width)
    ok &= (uv[:, 1] >= 0) & (uv[:, 1] < face.height)
    rec.log(path, rr.Points2D(uv[ok], colors=[color], radii=[3.0]), static=True)


def log_calibration(
    rec: rr.RecordingStream,
    result: CrossValidation | ExtrinsicsFit,
    xyz: ArrayLike,
    uv: ArrayLike,
    *,
    panorama: NDArray[np.uint8] | None = None,
    before: Pose3 | None = None,
    face_size: int = 384,
) -> None:
    """Log correspondences, their projections before/after, residuals and the camera pose.

    Args:
        rec: the recording stream to log to (explicit, never the global one).
        result: a cross-validation (residuals are its held-out errors) or a plain fit.
        xyz: ``(N, 3)`` points, metres, base frame; uv: ``(N, 2)`` observed pixels, px.
        panorama: the BGR panorama the pixels belong to (``W × H``); also renders cube faces.
        before: the pose before calibration (e.g. the rig's), drawn in orange.
        face_size: cube face size, px.
    """
    fit = result.fit if isinstance(result, CrossValidation) else result
    W, H = fit.image_size
    p = np.asarray(xyz, dtype=np.float64).reshape(-1, 3)
    q = np.asarray(uv, dtype=np.float64).reshape(-1, 2)
    if isinstance(result, CrossValidation):
        res = np.stack([result.col_err_px, result.row_err_px], axis=1)
    else:
        res = fit.residual_px
    colors = np.where(fit.inliers[:, None], _INLIER, _OUTLIER).astype(np.uint8)
    labels = [f"{i + 1}" for i in range(len(p))]

    if panorama is not None:
        EquirectCamera(W, H).check_image(panorama)
        ok, buf = cv2.imencode(".jpg", panorama, [cv2.IMWRITE_JPEG_QUALITY, 90])
        if ok:
            rec.log(
                ep.PANORAMA, rr.EncodedImage(contents=buf.tobytes(), media_type="image/jpeg"), static=True
            )
    scan = f"{ep.PANORAMA}/scan"
    px = max(3.0, W / 1000.0)  # marker radius, panorama px
    rec.log(
        f"{scan}/frame", rr.Boxes2D(mins=[[0.0, 0.0]], sizes=[[W, H]], colors=[(120, 120, 120)]), static=True
    )
    rec.log(f"{scan}/observed", rr.Points2D(q, colors=colors, radii=[1.5 * px], labels=labels), static=True)
    lens = float(getattr(fit, "lens_offset", 0.0) or 0.0)
    after = project_points(fit.pose, p, image_size=(W, H), lens_offset=lens)
    rec.log(f"{scan}/projected", rr.Points2D(after, colors=[_AFTER], radii=[px]), static=True)
    if before is not None:
        pb = project_points(before, p, image_size=(W, H))
        rec.log(f"{scan}/projected_before", rr.Points2D(pb, colors=[_BEFORE], radii=[px]), static=True)
    rec.log(
        f"{scan}/residuals", rr.Arrows2D(origins=q, vectors=res, colors=colors, radii=[0.4 * px]), static=True
    )

    if panorama is not None:
        faces = cube_faces(int(face_size))
        views = [faces[n] for n in ep.FACE_NAMES]
        for face, img in zip(views, ViewRenderer(max_entries=4).render_many(panorama, views), strict=True):
            path = f"{ep.FACES}/{face.name}"
            ok, buf = cv2.imencode(".jpg", img, [cv2.IMWRITE_JPEG_QUALITY, 90])
            if ok:
                rec.log(path, rr.EncodedImage(contents=buf.tobytes(), media_type="image/jpeg"), static=True)
            _face_points(rec, f"{path}/scan/after", face, fit.pose, p, _AFTER, lens)
            if before is not None:
                _face_points(rec, f"{path}/scan/before", face, before, p, _BEFORE)

    rec.log(ep.WORLD, rr.ViewCoordinates.RIGHT_HAND_Z_UP, static=True)
    rec.log(
        f"{ep.ROBOT}/calibration/points",
        rr.Points3D(p, colors=colors, radii=[0.03], labels=labels),
        static=True,
    )
    rec.log(
        f"{ep.ROBOT}/sensors/camera",
        rr.Transform3D(translation=fit.pose.t, mat3x3=fit.pose.R),
        rr.TransformAxes3D(axis_length=0.2),
        static=True,
    )
    idx = rr.TimeColumn(ep.TIMELINE_FRAME, sequence=np.arange(len(p), dtype=np.int64))
    for name, col, color in (("col_px", res[:, 0], _AFTER), ("row_px", res[:, 1], _BEFORE)):
        rec.log(f"{ep.CALIBRATION}/{name}", rr.SeriesPoints(names=[name], colors=[color]), static=True)
        rec.send_columns(
            f"{ep.CALIBRATION}/{name}",
            indexes=[idx],
            columns=rr.Scalars.columns(scalars=col.astype(np.float64)),
        )


def write_calibration_rrd(
    path: str | os.PathLike[str],
    result: CrossValidation | ExtrinsicsFit,
    xyz: ArrayLike,
    uv: ArrayLike,
    **kwargs: Any,
) -> None:
    """Write :func:`log_calibration`'s entities to an ``.rrd`` file (``studio view FILE --blueprint
    calibration`` opens it), atomically; ``kwargs`` go to :func:`log_calibration`."""
    target = Path(path)
    target.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{target.name}.", suffix=".tmp", dir=target.parent)
    os.close(fd)
    rec = rr.RecordingStream(ep.APP_ID)
    rec.save(tmp)
    try:
        log_calibration(rec, result, xyz, uv, **kwargs)
        rec.flush()
        rec.disconnect()
        umask = os.umask(0)
        os.umask(umask)
        os.chmod(tmp, 0o666 & ~umask)  # mkstemp made it private
        os.replace(tmp, target)
    finally:
        rec.disconnect()
        with contextlib.suppress(FileNotFoundError):
            os.unlink(tmp)
