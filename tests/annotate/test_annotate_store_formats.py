"""The store's fast paths give exactly what studio.labels gives: parsing a base frame, serialising a frame,
copying a person; and the materialised files are reused on reopen only when they match the log."""

from __future__ import annotations

import json
import math
import os
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from studio.annotate import AnnotationStore
from studio.annotate.bases import parse_frame
from studio.annotate.gtfiles import jsonl_line
from studio.annotate.ops import person_with
from studio.geometry.se import Pose2
from studio.labels import LabelFrame, LabelPerson, dumps_jsonl, frame_from_json

P = {"id": 3, "x": 1.25, "y": -0.5}
FRAMES: list[dict[str, Any]] = [
    {"frame": 0, "people": []},
    {"frame": 1, "stamp_ns": 17, "robot_pose": {"x": 1.0, "y": 2.0, "yaw": 0.1}, "people": [P]},
    {"frame": 2, "people": [{**P, "x": 1, "y": 2}]},  # ints
    {"frame": 3, "people": [{**P, "x_odom": 2.0, "y_odom": 3}, {**P, "id": 4, "x_odom": 1.0}]},
    {
        "frame": 4,
        "people": [
            {
                **P,
                "cov": [[0.01, 0.0], [0.0, 0.02]],
                "source": "fused",
                "box": [1, 2.5, 3, 4],
                "score": 0.5,
                "interpolated": True,
                "visible": {"camera": True, "laser": [1, 2]},
            }
        ],
        "reviewed": True,
        "note": "x",
    },
    {"frame": 5, "people": [{**P, "score": None, "box": None, "cov": None, "x_odom": None}]},
    {"frame": 6, "people": [{**P, "x": 1e300}, {**P, "id": 0, "x": -0.0}]},
]
BAD: list[dict[str, Any]] = [
    {"frame": 0, "people": [{**P, "x": math.nan}]},
    {"frame": 0, "people": [{**P, "x": math.inf}]},
    {"frame": 0, "people": [{**P, "x": True}]},
    {"frame": 0, "people": [{**P, "x": "1"}]},
    {"frame": 0, "people": [{"id": 1, "x": 1.0}]},
    {"frame": 0, "people": [{**P, "id": 1.0}]},
    {"frame": 0, "people": [P, P]},
    {"frame": 0, "people": [{**P, "cov": [[1.0, 0.0], [0.0]]}]},
    {"frame": 0, "people": [{**P, "cov": [[1.0, math.nan], [0.0, 1.0]]}]},
    {"frame": 0, "people": [{**P, "box": [1.0, 2.0, 3.0]}]},
    {"frame": 0, "people": [{**P, "score": "high"}]},
    {"frame": 0, "people": "nobody"},
    {"frame": 0, "people": [[1, 2]]},
]


@pytest.mark.parametrize("obj", FRAMES)
def test_fast_parse_equals_frame_from_json(obj: dict[str, Any]) -> None:
    obj = json.loads(json.dumps(obj))
    fast, ref = parse_frame(obj), frame_from_json(obj)
    assert fast == ref
    assert [p.__dict__ for p in fast.people] == [p.__dict__ for p in ref.people]
    assert jsonl_line(fast) == dumps_jsonl([ref])


@pytest.mark.parametrize("obj", BAD)
def test_fast_parse_rejects_what_frame_from_json_rejects(obj: dict[str, Any]) -> None:
    with pytest.raises(ValueError, match=r".") as ref:
        frame_from_json(obj)
    with pytest.raises(ValueError, match=r".") as fast:
        parse_frame(obj)
    assert str(fast.value) == str(ref.value)


def test_jsonl_line_equals_dumps_jsonl_on_varied_frames() -> None:
    rng = np.random.default_rng(0)
    for n in range(200):
        people = tuple(
            LabelPerson(
                id=k,
                x=float(rng.normal() * 10.0 ** rng.integers(-8, 4)),
                y=float(rng.normal()),
                x_odom=float(rng.normal()) if k % 2 else None,
                y_odom=float(rng.normal()) if k % 2 else None,
                cov=rng.normal(size=(2, 2)) if k % 3 else None,
                source=["fused", "laser", None][k % 3],
                box=tuple(rng.uniform(0, 2000, 4)) if k % 4 else None,
                score=float(rng.uniform()) if k % 5 else None,
                extra={"interpolated": True, "w": np.float32(1.5), "v": [np.float64(0.1234567891), math.nan]}
                if k % 6 == 0
                else {},
            )
            for k in range(int(rng.integers(0, 6)))
        )
        f = LabelFrame(
            frame=n,
            people=people,
            stamp_ns=int(rng.integers(0, 2**62)) if n % 2 else None,
            robot_pose=Pose2(float(rng.normal()), float(rng.normal()), float(rng.normal()))
            if n % 3
            else None,
            extra={"reviewed": True, "k": np.int64(3)} if n % 5 == 0 else {},
        )
        assert jsonl_line(f) == dumps_jsonl([f])


def test_person_with_equals_with_() -> None:
    p = LabelPerson(id=1, x=1.0, y=2.0, cov=((1.0, 0.0), (0.0, 1.0)), source="fused", extra={"a": 1})
    for changes in ({"x": 3.0, "cov": None}, {"id": 7, "source": "manual"}, {"extra": {"occluded": True}}):
        assert person_with(p, **changes) == p.with_(**changes)
    assert p.x == 1.0  # the original is untouched
    with pytest.raises(TypeError, match="no field"):
        person_with(p, z=1.0)


def test_materialised_files_reused_only_when_they_match_the_log(run_dir: Path) -> None:
    with AnnotationStore.open(run_dir) as s:
        s.apply({"op": "delete", "frame": 0, "id": 1})
        s.apply({"op": "review", "start": 2, "end": 3})
        want = s.frames()
    gt = run_dir / "ground_truth.jsonl"
    text, mtime = gt.read_text(), gt.stat().st_mtime_ns
    with AnnotationStore.open(run_dir) as s:  # reused: not rewritten
        assert s.frames() == want
        assert s.reviewed() == {2, 3}
    assert gt.stat().st_mtime_ns == mtime
    # a file changed behind the store's back (same size): rebuilt
    gt.write_text(text.replace('"frame":5,', '"frame":8,'))
    with AnnotationStore.open(run_dir) as s:
        assert s.frames() == want
    assert gt.read_text() == text
    # a log record the files never saw (killed before the rewrite): rebuilt
    with AnnotationStore.open(run_dir) as s:
        s.apply({"op": "delete", "frame": 1, "id": 1})
        want = s.frames()
    gt.write_text(text)
    os.utime(gt, ns=(mtime, mtime))
    stamp = json.loads((run_dir / "annotations" / "materialized.json").read_text())
    stamp["rev"] = 2
    stamp["ground_truth.jsonl"] = [gt.stat().st_size, mtime]
    log = run_dir / "annotations" / "corrections.jsonl"
    stamp["log_bytes"] = log.stat().st_size - len(log.read_bytes().splitlines(keepends=True)[-1])
    (run_dir / "annotations" / "materialized.json").write_text(json.dumps(stamp))
    with AnnotationStore.open(run_dir) as s:
        assert s.rev == 3
        assert s.frames() == want
    assert '"frame":1,' in gt.read_text()
    assert [p.id for p in frame_from_json(json.loads(gt.read_text().splitlines()[1])).people] == [2]
