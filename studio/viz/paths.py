"""Entity paths and timelines of a studio recording (``RUN/recording.rrd``), for the logger and blueprints.

The tree (``*``: one entity per sensor or face; "finish": logged after tracking as whole series)::

    world                                 view coordinates: x forward, y left, z up (static)
    world/odom                            the odometry frame (identity)
    world/odom/robot                      Transform3D T_odom_base, every frame
    world/odom/robot/footprint            LineStrips3D robot outline (static)
    world/odom/robot/sensors/*            sensor poses T_base_sensor + axes (static): camera, lasers
    world/odom/robot/scan/*               Points3D scan points in the base frame at scanner height, per laser
    world/odom/robot/laser_people         Points3D laser people detections (base frame)
    world/odom/robot/people               Points3D fused people, colour = source (finish)
    world/odom/robot/people/covariance    LineStrips3D 2-σ covariance ellipses (finish)
    world/odom/tracks                     Points3D tracked people, labelled with their ids (finish)
    world/odom/trails                     LineStrips3D last seconds of every track (finish)
    world/odom/ground_truth               Points3D ground-truth people, colour of the matched track (finish)
    world/odom/errors                     Points3D false positives (red) / misses (magenta) (finish, with GT)
    camera/panorama                       EncodedImage (JPEG), every frame
    camera/panorama/boxes                 Boxes2D image detections (seam boxes split in two), score labels
    camera/panorama/keypoints             Points2D body keypoints
    camera/panorama/skeletons             LineStrips2D keypoint skeletons
    camera/panorama/scan                  Points2D scan points projected into the panorama, colour = range
    camera/panorama/laser_people          LineStrips2D laser detections as 0–1.8 m vertical segments
    camera/panorama/tracks                LineStrips2D tracked people, labelled with their ids (finish)
    camera/panorama/ground_truth          LineStrips2D ground-truth people (finish, with GT)
    camera/faces/*                        EncodedImage cube faces front/left/back/right (every Nth frame)
    camera/faces/*/scan                   Points2D scan points projected into the face
    metrics/counts/*                      Scalars per frame: observations by source, tracks (finish)
    metrics/calibration/*                 Scalars per frame: box centre − projected laser column / row, px
    metrics/eval/*                        Scalars per frame vs ground truth: tp fp fn id_switches error_m,
                                          running f1 and mota (finish, with GT)
    review                                TextLog: moments where identities are worth checking, as
                                          review.jsonl lists them (finish)
    compare/events                        TextLog: frames where labels and ground truth disagree (finish)
    compare/summary                       TextDocument: the evaluation table (finish, with GT)

Timelines: ``frame`` (sequence, the labeled frame index) and ``time`` (timestamp, the frame's header stamp).

A calibration report (``studio calibrate extrinsics`` → ``*_report.rrd``, :mod:`studio.viz.calibration`) uses
the same tree with ``frame`` = correspondence index: ``camera/panorama/scan/{observed,projected,
projected_before,residuals}``, ``camera/faces/*/scan/{before,after}``, ``world/odom/robot/calibration/points``
and ``metrics/calibration/{col_px,row_px}``.
"""

from __future__ import annotations

__all__ = [
    "APP_ID",
    "CALIBRATION",
    "CAMERA",
    "COMPARE_EVENTS",
    "COMPARE_SUMMARY",
    "FACES",
    "FACE_NAMES",
    "METRICS",
    "ODOM",
    "PANORAMA",
    "REVIEW",
    "ROBOT",
    "TIMELINE_FRAME",
    "TIMELINE_TIME",
    "WORLD",
    "entity_name",
]

APP_ID = "studio"
TIMELINE_FRAME = "frame"
TIMELINE_TIME = "time"

WORLD = "world"
ODOM = "world/odom"
ROBOT = "world/odom/robot"
CAMERA = "camera"
PANORAMA = "camera/panorama"
FACES = "camera/faces"
FACE_NAMES = ("front", "left", "back", "right")
METRICS = "metrics"
CALIBRATION = "metrics/calibration"
REVIEW = "review"
COMPARE_EVENTS = "compare/events"
COMPARE_SUMMARY = "compare/summary"


def entity_name(topic: str) -> str:
    """An entity path part for a ROS topic: ``/scan_front`` → ``scan_front``, ``/a/b`` → ``a_b``."""
    name = topic.strip("/").replace("/", "_")
    return "".join(c if c.isalnum() or c in "_-." else "_" for c in name) or "unnamed"
