"""Geometry of studio: rigid transforms, the 360° equirectangular camera and perspective views of it.

Conventions (details in the module docstrings):

* frames follow REP-103: x forward, y left, z up; angles in radians, yaw/azimuth counter-clockwise
  (left positive); ``T_a_b`` is frame *b* expressed in frame *a* (:mod:`studio.geometry.se`);
* camera frame of the panorama = ROS body convention; azimuth ``atan2(y, x)``, elevation
  ``atan2(z, hypot(x, y))`` (:mod:`studio.geometry.base`);
* pixel coordinates are continuous from the left/top edge, the centre of pixel ``(i, j)`` is
  ``(i + 0.5, j + 0.5)``; panorama ``u = (0.5 - az/2π)·W`` wrapped into ``[0, W)``, ``v = (0.5 - el/π)·H``;
* a panorama box across the 0/360° seam is one box with ``u1`` in ``[0, W)`` and ``u2 > W``.
"""

from __future__ import annotations

from studio.geometry.base import (
    TWO_PI,
    angles_to_pixel,
    angles_to_rays,
    merge_pano_boxes,
    normalize_pano_box,
    pano_box_center_az,
    pano_box_iou,
    pano_box_nms,
    pixel_to_angles,
    rays_to_angles,
    wrap_u,
)
from studio.geometry.equirect import EquirectCamera
from studio.geometry.errors import GeometryError
from studio.geometry.render import ViewRenderer, view_maps
from studio.geometry.se import (
    Pose2,
    Pose3,
    quat_from_rpy,
    rot_from_quat,
    rot_from_rpy,
    rpy_from_rot,
    wrap_angle,
)
from studio.geometry.views import PerspectiveView, cube_faces, horizon_views

__all__ = [
    "TWO_PI",
    "EquirectCamera",
    "GeometryError",
    "PerspectiveView",
    "Pose2",
    "Pose3",
    "ViewRenderer",
    "angles_to_pixel",
    "angles_to_rays",
    "cube_faces",
    "horizon_views",
    "merge_pano_boxes",
    "normalize_pano_box",
    "pano_box_center_az",
    "pano_box_iou",
    "pano_box_nms",
    "pixel_to_angles",
    "quat_from_rpy",
    "rays_to_angles",
    "rot_from_quat",
    "rot_from_rpy",
    "rpy_from_rot",
    "view_maps",
    "wrap_angle",
    "wrap_u",
]
