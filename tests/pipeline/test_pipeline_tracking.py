"""Offline tracking in the labeling pipeline: people observed only on image frames (``track_all``)."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from studio.fuse.base import PersonObservations
from studio.geometry.se import Pose2
from studio.pipeline import LabelOptions
from studio.pipeline.base import FrameResult
from studio.pipeline.label import PerceptionFrame, track_all, tracking_config
from studio.track.offline import track_offline

T0 = 1_700_000_000_000_000_000
# laser_z, origins, points, scan sizes, scan planes of a frame without scans
NO_SCAN = (
    np.zeros(0),
    np.zeros((0, 2)),
    np.zeros((0, 2), np.float32),
    np.zeros(0, np.int32),
    np.zeros((0, 3)),
)


def _camera_only_run(fps: float, period_s: float, seconds: float = 4.0):
    """A person walking at 0.5 m/s, 3 m from a still robot, seen only by the image detector (beside the
    robot, where its body hides them from the lasers): an image-only observation on the frames where the
    detector runs (every ``period_s``), nothing on the others."""
    n = int(seconds * fps)
    stamps = [T0 + round(k * 1e9 / fps) for k in range(n)]
    pose = Pose2(0.0, 0.0, 0.0)
    frames, fused, last = [], [], None
    for k, t in enumerate(stamps):
        due = last is None or t - last >= period_s * 1e9 - 1e6
        if due:
            last = t
            xy = np.array([[0.0, 3.0 + 0.5 * (t - T0) * 1e-9]])
            obs = PersonObservations(
                xy, (0.15**2 * np.eye(2))[None], np.array([0.8]), ("image",), ("foot-row",),
                np.array([[100.0, 200.0, 140.0, 330.0]]), np.array([0]), np.array([-1]),
            )  # fmt: skip
        else:
            obs = PersonObservations.concat([])
        frames.append(PerceptionFrame(k, t, pose, None, None, None, *NO_SCAN))
        fused.append(FrameResult(k, t, pose, obs, None))
    return frames, fused


@pytest.mark.parametrize(("fps", "period"), [(10.0, 0.2), (30.0, 0.2), (10.0, 0.3), (15.0, 0.4)])
def test_camera_only_person_is_tracked_whatever_the_frame_rate(fps, period):
    frames, fused = _camera_only_run(fps, period)
    options = LabelOptions(image_period_s=period)
    labels, _ = track_all(frames, fused, options, has_camera=True)
    ids = [p.id for lf in labels for p in lf.people]
    assert len(set(ids)) == 1, set(ids)  # one person, one identity
    covered = sum(1 for lf in labels if lf.people) / len(labels)
    assert covered > 0.85, covered  # labeled between the image frames too (smoothed positions)
    truth = {lf.frame: 3.0 + 0.5 * (lf.stamp_ns - T0) * 1e-9 for lf in labels}
    err = [abs(p.y - truth[lf.frame]) for lf in labels for p in lf.people]
    assert np.median(err) < 0.1


@pytest.mark.parametrize(("seconds", "labelled"), [(1.4, False), (1.8, True)])
def test_someone_seen_for_less_than_1_5_s_gets_no_label(seconds, labelled):
    """A track spanning less than 1.5 s is left out (``PIPELINE_TRACKING.min_track_duration_s``): most such
    pieces are a few frames of someone whose own track goes on around them. 1.4 s of observations (seven,
    1.2 s from first to last) passed the pipeline's own ``min_track_s`` of 1 s before session 60."""
    frames, fused = _camera_only_run(10.0, 0.2, seconds=seconds)
    labels, _ = track_all(frames, fused, LabelOptions(image_period_s=0.2), has_camera=True)
    ids = {p.id for lf in labels for p in lf.people}
    assert (len(ids) == 1) == labelled, ids
    assert len(ids) <= 1
    assert LabelOptions().min_track_s < LabelOptions().tracking.min_track_duration_s == 1.5


def test_tracking_windows_follow_the_image_period():
    base = LabelOptions().tracking
    at = {p: tracking_config(LabelOptions(image_period_s=p), has_camera=True) for p in (0.0, 0.2, 0.4)}
    # with a camera, leg pairs are not split in the encounter re-decision, stitching's take-over looks
    # back 1 s and makes no hidden walks, whatever the period
    assert at[0.0] == replace(
        base,
        encounters=replace(base.encounters, split_legs=False),
        stitch=replace(base.stitch, tail_back_s=1.0, hidden_max_error=0.0),
    )
    assert base.stitch.tail_back_s == 0.5
    assert base.stitch.hidden_max_error > 0
    assert not at[0.2].encounters.split_legs
    assert at[0.2].tracker.confirm_window_s == pytest.approx(0.45)
    assert at[0.4].tracker.confirm_window_s == pytest.approx(0.85)
    assert at[0.4].tracker.tentative_max_coast_s == pytest.approx(0.6)
    assert at[0.4].split_gap_s == pytest.approx(0.6)
    # no camera, or the laser alone: the laser observes every frame, nothing to stretch
    assert tracking_config(LabelOptions(image_period_s=0.4), has_camera=False) == base
    assert tracking_config(LabelOptions(image_period_s=0.4, sources="laser"), has_camera=True) == base
    assert base.encounters.split_legs  # the laser alone splits them


def test_a_given_tracker_replaces_the_offline_tracker():
    """``track_all(tracker=...)``: the association a tool passes is what the labels show."""
    from studio.track import tracks_from_hits

    frames, fused = _camera_only_run(10.0, 0.2)
    seen = []

    def first_two_seconds(observations, *, config):
        """The person's observations of the first 2 s only."""
        seen.append(len(observations))
        hits = {0: [(i, 0) for i, o in enumerate(observations) if len(o.xy) and i < 20]}
        return tracks_from_hits(observations, hits, config=config)

    options = LabelOptions(image_period_s=0.2)
    labels, _ = track_all(frames, fused, options, has_camera=True, tracker=first_two_seconds)
    assert seen
    assert all(n == len(frames) for n in seen)
    frames_with_people = [lf.frame for lf in labels if lf.people]
    assert frames_with_people
    assert max(frames_with_people) < 20


def test_colours_of_a_box_with_someone_in_front_do_not_reach_the_tracker() -> None:
    """A box whose middle someone nearer covers (``FrameResult.colours_hidden``) gives its observation no
    colours; the others keep theirs, also where the mask is shorter than the observations (rows appended
    after fusion, the recovered scan clusters, have no entry)."""
    pose = Pose2(0.0, 0.0, 0.0)
    colours = np.array([[40, 10, 10, 20, 0, 0], [60, -10, 20, 30, 5, 5]], np.float32)
    frames, fused = [], []
    for k in range(6):
        t = T0 + k * 100_000_000
        obs = PersonObservations(
            np.array([[5.0, 0.0], [3.5, 0.05]]), np.repeat((0.1**2 * np.eye(2))[None], 2, 0),
            np.array([0.8, 0.8]), ("fused", "fused"), ("laser-detection",) * 2,
            np.array([[100.0, 400.0, 140.0, 560.0], [95.0, 380.0, 150.0, 600.0]]), np.array([0, 1]),
            np.array([0, 1]),
        )  # fmt: skip
        hidden = None if k % 2 == 0 else np.array([True]) if k == 5 else np.array([True, False])
        frames.append(PerceptionFrame(k, t, pose, None, colours, None, *NO_SCAN))
        fused.append(FrameResult(k, t, pose, obs, None, colours_hidden=hidden))
    seen = []

    def capture(observations, config):
        seen.extend(observations)
        return track_offline(observations, config=config)

    track_all(frames, fused, LabelOptions(recover_radius=0.0), has_camera=True, tracker=capture)
    for k, o in enumerate(seen):
        np.testing.assert_array_equal(o.appearance[1], colours[1])
        if k % 2:
            assert np.isnan(o.appearance[0]).all()
        else:
            np.testing.assert_array_equal(o.appearance[0], colours[0])
