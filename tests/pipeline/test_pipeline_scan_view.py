"""A frame's scans become what the offline tracker knows the scanners saw (:mod:`studio.track.sight`), in
the world frame, and it outlives the beams."""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from studio.detect.laser import LaserDetections
from studio.geometry.se import Pose2
from studio.pipeline import LabelOptions
from studio.pipeline.label import fuse_all, track_all
from studio.pipeline.perceive import PerceptionFrame, compact_beams


def _frame(pose: Pose2) -> PerceptionFrame:
    # one scanner at the base's origin, a round wall 5 m off all around, nobody
    a = np.linspace(-np.pi, np.pi, 1440, endpoint=False)
    pts = np.zeros((len(a), 3), np.float32)
    pts[:, 0], pts[:, 1], pts[:, 2] = 5.0 * np.cos(a), 5.0 * np.sin(a), 0.3
    return PerceptionFrame(
        0,
        0,
        pose,
        None,
        None,
        LaserDetections.empty(with_segments=True),
        np.zeros(0),
        np.zeros((1, 2)),
        *compact_beams(pts, np.zeros(len(a), np.int16), 1),
    )


def test_the_view_is_in_the_world_frame_and_outlives_the_beams() -> None:
    f = _frame(Pose2(10.0, 0.0, np.pi / 2))  # the base at (10, 0), facing world +y
    view = f.scan_view()
    assert view is not None
    np.testing.assert_allclose(view.origins, [[10.0, 0.0]], atol=1e-9)
    assert view.sees_empty(np.array([10.0, 2.0]))  # 2 m ahead of the robot
    assert not view.sees_empty(np.array([10.0, 6.0]))  # behind the wall
    bare = f.without_beams()
    assert bare.points.shape == (0, 2)
    kept = bare.scan_view()
    assert kept is not None
    np.testing.assert_array_equal(kept.ranges, view.ranges)
    # a frame without scanners has no view
    none = replace(
        f, points=np.zeros((0, 2), np.float32), scan_sizes=np.zeros(0, np.int32), origins=np.zeros((0, 2))
    )
    assert none.scan_view() is None


def test_the_tracker_is_given_each_frames_view() -> None:
    options = replace(LabelOptions(), static_filter=False, sources="laser")
    frames = [replace(_frame(Pose2(0.1 * k, 0.0, 0.0)), index=k, stamp_ns=k * 100_000_000) for k in range(3)]
    fused = fuse_all(frames, None, options)
    seen = []

    def tracker(observations, config):
        from studio.track.offline import track_offline

        seen.append([o.view for o in observations])
        return track_offline(observations, config=config)

    track_all([f.without_beams() for f in frames], fused, options, has_camera=False, tracker=tracker)
    assert seen
    views = seen[0]
    assert all(v is not None for v in views)
    np.testing.assert_allclose([v.origins[0] for v in views], [[0.0, 0.0], [0.1, 0.0], [0.2, 0.0]], atol=1e-9)
