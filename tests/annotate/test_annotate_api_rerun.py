"""The Rerun link: corrected ground truth is logged into the run's recording after each edit."""

from __future__ import annotations

import shutil
from pathlib import Path

import numpy as np
import pytest

rr = pytest.importorskip("rerun")
from fastapi.testclient import TestClient  # noqa: E402

from studio.annotate.app import create_app  # noqa: E402
from studio.annotate.rerun_sync import RerunLink, run_recording_id  # noqa: E402
from studio.annotate.server import AnnotateServer  # noqa: E402
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


def _viewer_available() -> bool:
    import glob
    import sys

    exe = Path(sys.executable).parent / "rerun"
    return (exe.exists() or shutil.which("rerun") is not None) and bool(
        glob.glob("/usr/share/vulkan/icd.d/lvp_icd*.json")
        or glob.glob("/usr/share/vulkan/icd.d/nvidia*.json")
    )


@pytest.mark.viewer
@pytest.mark.skipif(not _viewer_available(), reason="needs the rerun viewer and a Vulkan driver")
def test_page_and_viewer_time_cursors_follow_each_other(
    tmp_path_factory: pytest.TempPathFactory, tmp_path: Path
) -> None:
    import time

    from rerun.experimental import ViewerClient
    from test_annotate_api import make_sim_run

    from studio.viz.viewer import _free_port, _quiet_viewer_env, _rerun_exe

    run = tmp_path / "run"
    shutil.copytree(make_sim_run(tmp_path_factory.getbasetemp() / "annotate_sim"), run)
    state = AnnotateServer(run)
    frames = state.frame_ids
    # a recording.rrd for the run, with the run's frame timeline (as `studio label` writes it)
    rec = rr.RecordingStream("studio", recording_id="cursor-test")
    rec.save(run / "recording.rrd")
    for m in frames:
        rec.set_time("frame", sequence=m)
        rec.log("world/odom/marker", rr.Points3D([[float(m), 0.0, 0.0]]))
    rec.flush()
    rec.disconnect()
    port = _free_port()
    with _quiet_viewer_env():
        viewer = ViewerClient.spawn(
            headless=True, port=port, hide_welcome_screen=True, executable_path=_rerun_exe()
        )
    link = None
    try:
        viewer.open(str((run / "recording.rrd").resolve()))
        link = RerunLink.connect(state, url=f"rerun+http://127.0.0.1:{port}/proxy")
        state.rerun, state.on_change = link, link.log_frames
        assert link.status()["can_follow"] is True

        def viewer_frame() -> int | None:
            recs = viewer.get_state().recordings
            r = next((r for r in recs if str(r.store_id).endswith(":cursor-test")), None)
            return None if r is None or r.current_timeline != "frame" else r.current_time

        with TestClient(create_app(state)) as client:
            target = frames[len(frames) // 2]
            r = client.post("/api/rerun/time", json={"frame": target})  # the page moves the viewer
            assert r.status_code == 200
            assert r.json()["moved"] is True
            t_end = time.monotonic() + 20
            while viewer_frame() != target and time.monotonic() < t_end:
                time.sleep(0.2)
            assert viewer_frame() == target
            other = frames[3]
            store = link._store_id()
            viewer.set_time("frame", sequence=other, play_state="paused", recording=store)  # the user scrubs
            t_end = time.monotonic() + 20
            while client.get("/api/rerun").json()["frame"] != other and time.monotonic() < t_end:
                time.sleep(0.2)
            assert client.get("/api/rerun").json()["frame"] == other  # the page sees it
    finally:
        if link is not None:
            link.close()
        state.close()
        viewer.quit()
