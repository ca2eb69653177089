"""RunLogger: entity paths, timelines and counts of a tiny synthetic run, read back from the saved .rrd."""

from __future__ import annotations

from collections import defaultdict
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import rerun as rr
import viz_synth as vs

from studio.geometry.se import Pose2
from studio.io.base import Frame
from studio.viz.colors import id_color

Rows = dict[str, list[dict[str, Any]]]


def read_rows(rrd: Path) -> tuple[Rows, dict[str, set[str]]]:
    """Every row of every entity (component name → value), and the timelines of each entity."""
    rows: Rows = defaultdict(list)
    timelines: dict[str, set[str]] = defaultdict(set)
    for chunk in rr.chunk.RrdReader(rrd).stream():
        rb = chunk.to_record_batch()
        timelines[chunk.entity_path].update(chunk.timeline_names)
        data = {f.name: rb.column(f.name).to_pylist() for f in rb.schema}
        for r in range(rb.num_rows):
            rows[chunk.entity_path].append({k: v[r] for k, v in data.items()})
    for v in rows.values():
        v.sort(key=lambda row: row.get("frame") if row.get("frame") is not None else -1)
    return rows, timelines


@pytest.fixture(scope="module")
def logged(tmp_path_factory: pytest.TempPathFactory) -> tuple[Rows, dict[str, set[str]], Any, vs.Synthetic]:
    tmp = tmp_path_factory.mktemp("run")
    syn = vs.build(tmp)
    logger = vs.log_run(tmp / "recording.rrd", syn, ground_truth=syn.gt_path, faces_every=2)
    rows, timelines = read_rows(tmp / "recording.rrd")
    return rows, timelines, logger, syn


EXPECTED_TEMPORAL = [
    "/world/odom/robot",
    "/world/odom/robot/scan/scan_front",
    "/world/odom/robot/scan/scan_rear",
    "/world/odom/robot/laser_people",
    "/world/odom/robot/people",
    "/world/odom/robot/people/covariance",
    "/world/odom/tracks",
    "/world/odom/trails",
    "/world/odom/ground_truth",
    "/world/odom/errors",
    "/camera/panorama",
    "/camera/panorama/boxes",
    "/camera/panorama/keypoints",
    "/camera/panorama/skeletons",
    "/camera/panorama/scan/scan_front",
    "/camera/panorama/laser_people",
    "/camera/panorama/tracks",
    "/camera/panorama/ground_truth",
    *[f"/camera/faces/{n}" for n in ("front", "left", "back", "right")],
    "/metrics/counts/fused",
    "/metrics/counts/tracks",
    "/metrics/calibration/column_px",
    "/metrics/eval/tp",
    "/metrics/eval/running_f1",
    "/metrics/eval/error_m",
    "/compare/events",
]
EXPECTED_STATIC = [
    "/world",
    "/world/odom/robot/footprint",
    "/world/odom/robot/sensors/camera",
    "/world/odom/robot/sensors/scan_front",
    "/compare/summary",
]


def test_entity_tree_and_timelines(logged: Any) -> None:
    rows, timelines, logger, _ = logged
    for path in EXPECTED_TEMPORAL:
        assert path in rows, path
        assert timelines[path] == {"frame", "time"}, (path, timelines[path])
    for path in EXPECTED_STATIC:
        assert path in rows, path
    assert logger.seconds > 0


def _n(rows: Rows, path: str, comp: str) -> list[int]:
    """Number of instances of ``comp`` per temporal row."""
    return [len(r[comp] or []) for r in rows[path] if r.get("frame") is not None]


def test_per_frame_counts(logged: Any) -> None:
    rows, _, _, syn = logged
    n = vs.N_FRAMES
    frames = [r["frame"] for r in rows["/camera/panorama"]]
    assert frames == list(range(n))
    times = [r["time"] for r in rows["/camera/panorama"]]
    assert [t.value for t in times] == [vs.T0 + k * vs.DT for k in range(n)]
    # the panorama is the original JPEG
    assert bytes(rows["/camera/panorama"][0]["EncodedImage:blob"][0]) == syn.frames[0].panorama.encoded
    # faces every 2nd frame
    assert [r["frame"] for r in rows["/camera/faces/front"] if r.get("frame") is not None] == [0, 2, 4]
    # the box across the seam is drawn as two boxes
    assert _n(rows, "/camera/panorama/boxes", "Boxes2D:half_sizes") == [3] * n
    # scans: valid beams only; the rear scanner is missing at frame 3 and logged empty there
    valid = int(np.isfinite(syn.perception[0].points[:, 0]).sum() // 2)
    valid = (valid + 1) // 2  # every 2nd beam is logged in 3D (scan_step=2)
    assert _n(rows, "/world/odom/robot/scan/scan_front", "Points3D:positions") == [valid] * n
    rear = _n(rows, "/world/odom/robot/scan/scan_rear", "Points3D:positions")
    assert rear[3] == 0
    assert rear[2] == valid
    # fused people and ellipses, tracks (id 2 from frame 2 on), trails need two points
    assert _n(rows, "/world/odom/robot/people", "Points3D:positions") == [2] * n
    assert _n(rows, "/world/odom/robot/people/covariance", "LineStrips3D:strips") == [2] * n
    assert _n(rows, "/world/odom/tracks", "Points3D:positions") == [1, 1, 2, 2, 2, 2]
    assert _n(rows, "/world/odom/trails", "LineStrips3D:strips") == [0, 1, 1, 2, 2, 2]
    labels = [r["Points3D:labels"] for r in rows["/world/odom/tracks"] if r.get("frame") is not None]
    assert labels[-1] == ["1", "2"]
    assert len(rows["/world/odom/robot"]) == n


def test_tracks_in_odom_frame(logged: Any) -> None:
    rows, _, _, syn = logged
    last = next(r for r in rows["/world/odom/tracks"] if r.get("frame") == vs.N_FRAMES - 1)
    pose: Pose2 = syn.run.labels[-1].robot_pose
    # track 2 has no odom position in the labels: derived from the robot pose
    np.testing.assert_allclose(
        last["Points3D:positions"][1][:2], pose.apply(np.array([-1.0, 1.0])), atol=1e-5
    )


def test_ground_truth_compare(logged: Any) -> None:
    rows, _, _, _ = logged
    gt = next(r for r in rows["/world/odom/ground_truth"] if r.get("frame") == 0)
    assert gt["Points3D:labels"] == ["GT 11", "GT 12"]
    # GT 11 is matched by track 1: same colour; GT 12 is never matched
    rgba = gt["Points3D:colors"][0]
    assert ((rgba >> 24) & 255, (rgba >> 16) & 255, (rgba >> 8) & 255) == id_color(1)
    # every frame misses GT 12; from frame 2 on, track 2 is a false positive
    events = [r for r in rows["/compare/events"] if r.get("frame") is not None]
    assert [r["frame"] for r in events] == list(range(vs.N_FRAMES))
    assert "missed (GT 12)" in events[0]["TextLog:text"][0]
    assert "false positive" in events[2]["TextLog:text"][0]
    fp = [r["Scalars:scalars"][0] for r in rows["/metrics/eval/fp"] if r.get("frame") is not None]
    assert fp == [0, 0, 1, 1, 1, 1]
    err = [r["Scalars:scalars"][0] for r in rows["/metrics/eval/error_m"] if r.get("frame") is not None]
    np.testing.assert_allclose(err, 0.05, atol=1e-9)


def test_laser_only_run(tmp_path: Path) -> None:
    syn = vs.build(tmp_path, with_gt=False)
    frames = [Frame(f.index, f.stamp_ns, None, f.scans, f.robot_pose) for f in syn.frames]
    syn.frames[:] = frames
    syn.run.camera = None
    syn.run.image_size = None
    vs.log_run(tmp_path / "r.rrd", syn)
    rows, _ = read_rows(tmp_path / "r.rrd")
    assert not any(p.startswith("/camera") for p in rows)
    assert "/world/odom/tracks" in rows
    assert "/metrics/calibration/column_px" not in rows


def test_ground_truth_yaml_without_stamps(tmp_path: Path) -> None:
    # the thesis format has no stamps: frames are aligned by index and placed at the run's stamps
    from studio.labels.formats import read_labels, write_labels

    syn = vs.build(tmp_path)
    gt = tmp_path / "gt.yaml"
    write_labels(gt, read_labels(syn.gt_path).frames)
    vs.log_run(tmp_path / "r.rrd", syn, ground_truth=gt)
    rows, _ = read_rows(tmp_path / "r.rrd")
    gt_rows = [r for r in rows["/world/odom/ground_truth"] if r.get("frame") is not None]
    assert [r["frame"] for r in gt_rows] == list(range(vs.N_FRAMES))
    assert [r["time"].value for r in gt_rows] == [vs.T0 + k * vs.DT for k in range(vs.N_FRAMES)]
    # without odom positions in the file, the run's robot pose places them in the odom frame
    pose = syn.run.labels[-1].robot_pose
    np.testing.assert_allclose(
        gt_rows[-1]["Points3D:positions"][0][:2], pose.apply(np.array([2.05, 0.5])), atol=1e-5
    )


def test_missing_ground_truth_file_is_a_user_error(tmp_path: Path) -> None:
    from studio.errors import StudioError

    syn = vs.build(tmp_path, with_gt=False)
    with pytest.raises(StudioError):
        vs.log_run(tmp_path / "r.rrd", syn, ground_truth=tmp_path / "nope.jsonl")
    assert (tmp_path / "r.rrd").exists()  # closed and readable even after the error
    read_rows(tmp_path / "r.rrd")


def test_panorama_without_image_detections(tmp_path: Path) -> None:
    # the thesis baseline detects on cube faces and hands pass one no panorama detections
    from dataclasses import replace

    syn = vs.build(tmp_path, with_gt=False)
    syn.perception[:] = [replace(pf, image=None, laser=None) for pf in syn.perception]
    vs.log_run(tmp_path / "r.rrd", syn)
    rows, _ = read_rows(tmp_path / "r.rrd")
    assert _n(rows, "/camera/panorama/boxes", "Boxes2D:half_sizes") == [0] * vs.N_FRAMES
    assert _n(rows, "/world/odom/robot/laser_people", "Points3D:positions") == [0] * vs.N_FRAMES
    assert len([r for r in rows["/camera/panorama"] if r.get("frame") is not None]) == vs.N_FRAMES


def test_review_points_as_a_text_log(tmp_path: Path) -> None:
    """The moments review.jsonl lists are a text log at their frames (click to jump in the viewer)."""
    from dataclasses import replace

    from studio.labels.base import LabelPerson

    syn = vs.build(tmp_path, with_gt=False)
    # track 2 walks up to track 1 (within 0.5 m in frames 3-5): one encounter, at the last of them
    labels = []
    for f in syn.run.labels:
        people = [p for p in f.people if p.id == 1]
        if f.frame >= 2:
            people.append(LabelPerson(2, 2.0, 0.5 + (0.35 if f.frame >= 3 else 1.0)))
        labels.append(replace(f, people=tuple(people)))
    syn.run.labels = labels
    vs.log_run(tmp_path / "r.rrd", syn)
    rows, timelines = read_rows(tmp_path / "r.rrd")
    logged = [r for r in rows["/review"] if r.get("frame") is not None]
    assert [r["frame"] for r in logged] == [vs.N_FRAMES - 1]
    assert "tracks 1 and 2 came within 0.35 m" in logged[0]["TextLog:text"][0]
    # 2.2 m from the robot: doubt 0.3 + 0.3 * 2.2 / 8, at or above 0.3: a warning
    assert "(encounter, doubt 0.38)" in logged[0]["TextLog:text"][0]
    assert logged[0]["TextLog:level"] == ["WARN"]
    assert timelines["/review"] == {"frame", "time"}
    # nothing to check: no entity
    syn.run.labels = [replace(f, people=tuple(p for p in f.people if p.id == 1)) for f in labels]
    vs.log_run(tmp_path / "r2.rrd", syn)
    assert "/review" not in read_rows(tmp_path / "r2.rrd")[0]
