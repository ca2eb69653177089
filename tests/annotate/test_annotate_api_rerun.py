"""The Rerun link: corrected ground truth is logged into the run's recording after each edit."""

from __future__ import annotations

import shutil
from pathlib import Path

import numpy as np
import pytest

rr = pytest.importorskip("rerun")
from fastapi.testclient import TestClient  # noqa: E402

from studio.annotate.rerun_sync import RerunLink, run_recording_id  # noqa: E402
from studio.annotate.server import AnnotateServer, create_app  # noqa: E402
from studio.geometry.se import Pose2  # noqa: E402


def _positions(rrd: Path, entity: str) -> np.ndarray:
    pts = []
    for chunk in rr.chunk.RrdReader(rrd).stream():
        if chunk.entity_path != "/" + entity and chunk.entity_path != entity:
            continue
        rb = chunk.to_record_batch()
        for name in rb.schema.names:
            if name.endswith("positions"):
                for row in rb.column(name).to_pylist():
                    pts.extend(row or [])
    return np.array(pts, dtype=float).reshape(-1, 3)


def test_edits_are_logged_as_ground_truth(tmp_path_factory: pytest.TempPathFactory, tmp_path: Path) -> None:
    from test_annotate_api import make_sim_run  # same session cache as the API tests

    run = tmp_path / "run"
    shutil.copytree(make_sim_run(tmp_path_factory.getbasetemp() / "annotate_sim"), run)
    assert run_recording_id(run) is None  # labeled with --no-rrd: nothing to attach a viewer link to
    state = AnnotateServer(run)
    rrd = tmp_path / "link.rrd"
    rec = rr.RecordingStream("studio", recording_id="annotate-test")
    rec.save(rrd)
    link = RerunLink(state, rec, url="file")
    state.rerun, state.on_change = link, link.log_frames
    try:
        assert link.wait_idle(60)
        assert link.error is None
        assert link.logged_rev == 0
        with TestClient(create_app(state)) as client:
            assert client.get("/api/meta").json()["rerun"]["can_follow"] is False
            r = client.post("/api/rerun/time", json={"frame": 3})
            assert r.status_code == 200
            assert r.json()["moved"] is False
            body = client.get("/api/frame/12").json()
            p = next(q for q in body["gt"] if q["id"] == 1)
            r = client.post(
                "/api/op", json={"op": {"op": "move", "frame": 12, "id": 1, "x": p["x"] + 1.0, "y": p["y"]}}
            )
            assert r.status_code == 200
        assert link.wait_idle(60)
        assert link.error is None
        assert link.logged_rev == 1
    finally:
        state.close()
    pose = body["robot_pose"]
    want = Pose2(pose["x"], pose["y"], pose["yaw"]).apply([[p["x"] + 1.0, p["y"]]])[0]
    gt = _positions(rrd, "world/odom/ground_truth")
    assert len(gt) > 0
    d = np.hypot(gt[:, 0] - want[0], gt[:, 1] - want[1]).min()
    assert d < 1e-3, d  # the corrected position reached the recording
