"""The annotation server's HTTP API on a real simulated run (laser-labeled, so that it is quick to make)."""

from __future__ import annotations

import json
import shutil
import subprocess
import sys
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pytest

pytest.importorskip("fastapi")
from fastapi.testclient import TestClient

from studio.annotate.app import create_app
from studio.annotate.server import AnnotateServer
from studio.evaluate import evaluate


def make_sim_run(base: Path) -> Path:
    """Simulate a 6 s 'moving' recording and label it from the lasers (shared by the page tests)."""
    run = base / "run"
    if (run / "labels.jsonl").is_file():
        return run
    from studio.sim import simulate

    sim = base / "sim"
    simulate("moving", out=sim, seconds=6, seed=3)
    cmd = [
        sys.executable,
        "-m",
        "studio.cli",
        "label",
        str(sim / "recording.mcap"),
        "--rig",
        str(sim / "rig.yaml"),
    ]
    subprocess.run(
        [*cmd, "--out", str(run), "--sources", "laser", "--no-rrd"], check=True, capture_output=True
    )
    return run


@pytest.fixture(scope="session")
def sim_run(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return make_sim_run(tmp_path_factory.getbasetemp() / "annotate_sim")


@pytest.fixture
def run_copy(sim_run: Path, tmp_path: Path) -> Path:
    dst = tmp_path / "run"
    shutil.copytree(sim_run, dst)
    return dst


@pytest.fixture
def api(run_copy: Path) -> Iterator[tuple[TestClient, AnnotateServer]]:
    state = AnnotateServer(run_copy, author="tester")
    with TestClient(create_app(state)) as client:
        yield client, state
    state.close()


def op(client: TestClient, body: dict[str, Any], base_rev: int | None = None, client_id: str = "t1") -> Any:
    return client.post("/api/op", json={"op": body, "base_rev": base_rev, "client": client_id})


def gt_person(client: TestClient, frame: int, pid: int) -> dict[str, Any] | None:
    people = client.get(f"/api/frame/{frame}").json()["gt"]
    return next((p for p in people if p["id"] == pid), None)


def test_meta_frame_and_panorama(api: tuple[TestClient, AnnotateServer], run_copy: Path) -> None:
    import cv2

    client, _state = api
    meta = client.get("/api/meta").json()
    assert meta["num_frames"] == 60
    assert meta["frames"][:3] == [0, 1, 2]
    assert meta["has_camera"]
    assert meta["image_size"] == [1920, 960]
    assert meta["media_problem"] is None
    body = client.get("/api/frame/5").json()
    assert body["frame"] == 5
    assert body["rev"] == 0
    assert not body["reviewed"]
    assert [p["id"] for p in body["gt"]] == [p["id"] for p in body["auto"]]  # ground truth starts as auto
    assert len(body["scan"]["xy"]) == len(body["scan"]["uv"]) > 500
    r = client.get("/api/frame/5/panorama.jpg")
    assert r.status_code == 200
    assert r.headers["content-type"] == "image/jpeg"
    img = cv2.imdecode(np.frombuffer(r.content, np.uint8), cv2.IMREAD_COLOR)
    assert img.shape == (960, 1920, 3)
    assert list((run_copy / "annotations" / "cache").glob("000005_*.jpg"))  # disk cache
    # a person's panorama marker: foot below head, inside the image
    u, v_top, v_foot = body["gt"][0]["pano"]
    assert 0 <= u < 1920
    assert 0 <= v_top < v_foot < 960


def test_scan_points_in_base_frame_touch_the_people(api: tuple[TestClient, AnnotateServer]) -> None:
    """Each laser-detected person has scan points (legs) within 0.4 m: the laser poses are applied."""
    client, _ = api
    for n in (0, 30, 59):
        body = client.get(f"/api/frame/{n}").json()
        xy = np.array(body["scan"]["xy"])
        laser = np.array(body["scan"]["laser"])
        assert set(laser.tolist()) == {0, 1}  # front and rear laser
        for p in body["auto"]:
            d = np.hypot(xy[:, 0] - p["x"], xy[:, 1] - p["y"]).min()
            assert d < 0.4, (n, p["id"], d)
        uv = np.array([q for q in body["scan"]["uv"] if q is not None])
        assert uv[:, 0].min() >= 0
        assert uv[:, 0].max() < 1920
        assert np.median(uv[:, 1]) > 480  # laser plane is below the camera: below the horizon


BAD: list[tuple[str, str, Any, int, str]] = [
    ("GET", "/api/frame/999", None, 404, "unknown frame 999"),
    ("GET", "/api/frame/-1", None, 404, "unknown frame"),
    ("GET", "/api/frame/abc", None, 400, "frame must be an integer"),
    ("GET", "/api/frame/999/panorama.jpg", None, 404, "unknown frame"),
    ("GET", "/static/../run.json", None, 404, ""),
    ("GET", "/static/..%2Frun.json", None, 404, ""),
    ("GET", "/static/%2Fetc%2Fpasswd", None, 404, ""),
    ("GET", "/api/frame/..%2F..%2Frun.json", None, 404, ""),
    ("GET", "/../labels.jsonl", None, 404, ""),
    ("GET", "/api/history?frame=1e9", None, 400, "frame must be an integer"),
    ("GET", "/api/next?kind=nope&start=0", None, 400, "kind must be"),
    ("POST", "/api/op", b"{not json", 400, "malformed JSON"),
    ("POST", "/api/op", b"[1, 2]", 400, "JSON object"),
    ("POST", "/api/op", {"op": {"op": "teleport", "frame": 1}}, 422, "teleport"),
    ("POST", "/api/op", {"op": {"op": "move", "frame": 3, "id": 4242, "x": 1, "y": 1}}, 422, "4242"),
    ("POST", "/api/op", {"op": {"op": "move", "frame": 3, "id": "x", "x": 1, "y": 1}}, 422, "id"),
    ("POST", "/api/op", {"op": {"op": "move", "frame": 999, "id": 0, "x": 1, "y": 1}}, 422, "999"),
    ("POST", "/api/op", {"op": {"op": "delete", "frame": 1, "id": 0}, "base_rev": "abc"}, 400, "base_rev"),
    ("POST", "/api/undo", {"base_rev": 0}, 422, "nothing to undo"),
]


@pytest.mark.parametrize(("method", "path", "body", "status", "message"), BAD)
def test_bad_requests_are_4xx_and_leave_the_state_intact(
    api: tuple[TestClient, AnnotateServer], method: str, path: str, body: Any, status: int, message: str
) -> None:
    client, state = api
    before = client.get("/api/frame/3").json()["gt"]
    if method == "GET":
        r = client.get(path)
    elif isinstance(body, bytes):
        r = client.post(path, content=body, headers={"Content-Type": "application/json"})
    else:
        r = client.post(path, json=body)
    assert r.status_code == status, r.text
    err = r.json()["error"]
    assert message in err
    assert "Traceback" not in err
    assert state.store.rev == 0
    assert client.get("/api/frame/3").json()["gt"] == before
    assert client.get("/api/history").json()["history"] == []


def test_second_tab_sees_a_conflict_and_nothing_is_overwritten(
    api: tuple[TestClient, AnnotateServer],
) -> None:
    client, _ = api
    rev = client.get("/api/meta").json()["rev"]
    r1 = op(client, {"op": "move", "frame": 10, "id": 0, "x": 1.0, "y": 1.0}, rev, "tab-a")
    assert r1.status_code == 200
    assert r1.json()["rev"] == rev + 1
    r2 = op(client, {"op": "move", "frame": 10, "id": 0, "x": 3.0, "y": 3.0}, rev, "tab-b")
    assert r2.status_code == 409
    assert "reload" in r2.json()["error"]
    assert r2.json()["rev"] == rev + 1
    p = gt_person(client, 10, 0)
    assert p is not None
    assert (p["x"], p["y"]) == (1.0, 1.0)
    # an edit of another frame from the stale tab is fine
    assert (
        op(client, {"op": "move", "frame": 20, "id": 0, "x": 2.0, "y": 2.0}, rev, "tab-b").status_code == 200
    )
    hist = client.get("/api/history?frame=10").json()["history"]
    assert [h["client"] for h in hist] == ["tab-a"]
    assert hist[0]["author"] == "tester"
    who = client.get("/api/frame/10").json()["gt"]
    assert next(q for q in who if q["id"] == 0)["changed"]["how"] == "edit"


def wait_metrics(client: TestClient) -> dict[str, Any]:
    m = client.get("/api/metrics?wait=30").json()
    assert not m["stale"]
    return dict(m)


def test_metrics_and_flags_move_as_the_edits_imply(
    api: tuple[TestClient, AnnotateServer], run_copy: Path
) -> None:
    client, _ = api
    assert wait_metrics(client)["metrics"] is None  # nothing reviewed yet
    assert op(client, {"op": "review", "start": 0, "end": 59}).status_code == 200
    m = wait_metrics(client)
    assert m["reviewed_frames"] == 60
    assert m["flagged"] == []
    assert m["metrics"]["precision"] == 1.0
    assert m["metrics"]["recall"] == 1.0
    assert m["metrics"]["idf1"] == 1.0
    n_gt = m["metrics"]["tp"]
    # a person moved by 1 m in one frame: one FP and one FN there, flagged
    p = gt_person(client, 12, 1)
    assert p is not None
    assert op(client, {"op": "move", "frame": 12, "id": 1, "x": p["x"] + 1.0, "y": p["y"]}).status_code == 200
    m = wait_metrics(client)
    assert (m["metrics"]["tp"], m["metrics"]["fp"], m["metrics"]["fn"]) == (n_gt - 1, 1, 1)
    assert m["flagged"] == [12]
    assert client.get("/api/next?kind=flag&start=0").json()["frame"] == 12
    assert client.get("/api/next?kind=flag&start=12").json()["frame"] is None
    flags = client.get("/api/frame/12").json()["flags"]
    assert flags["fp"] == [1]
    assert flags["fn"] == [1]
    # a missed person added by hand: one more FN
    assert op(client, {"op": "add", "frame": 30, "id": 40, "x": -2.0, "y": 0.5}).status_code == 200
    m = wait_metrics(client)
    assert (m["metrics"]["fp"], m["metrics"]["fn"]) == (1, 2)
    assert m["flagged"] == [12, 30]
    # the evaluator on the files gives the same numbers (ground_truth.jsonl holds every frame)
    ev = evaluate(run_copy / "labels.jsonl", run_copy / "ground_truth.jsonl").to_json()
    assert (ev["tp"], ev["fp"], ev["fn"]) == (n_gt - 1, 1, 2)
    out = subprocess.run(
        [
            sys.executable,
            "-m",
            "studio.cli",
            "evaluate",
            str(run_copy / "labels.jsonl"),
            str(run_copy / "ground_truth.jsonl"),
        ],
        capture_output=True,
        text=True,
    )
    assert out.returncode == 0, out.stderr
    # undo both: back to perfect; redo one
    rev = client.get("/api/meta").json()["rev"]
    assert client.post("/api/undo", json={"base_rev": rev}).status_code == 200
    assert client.post("/api/undo", json={}).status_code == 200
    assert wait_metrics(client)["metrics"]["f1"] == 1.0
    assert client.post("/api/redo", json={}).status_code == 200
    assert wait_metrics(client)["flagged"] == [12]


def test_split_and_merge_change_identity_metrics(api: tuple[TestClient, AnnotateServer]) -> None:
    client, _ = api
    op(client, {"op": "review", "start": 0, "end": 59})
    assert op(client, {"op": "split", "id": 0, "frame": 30, "new_id": 50}).status_code == 200
    m = wait_metrics(client)["metrics"]
    assert m["idf1"] < 0.95
    assert m["f1"] == 1.0
    assert m["num_gt_tracks"] == 6
    assert gt_person(client, 40, 50) is not None
    assert gt_person(client, 40, 0) is None
    r = op(client, {"op": "merge", "ids": [0, 50], "into": 0, "start": 0, "end": 59})
    assert r.status_code == 200, r.text
    m = wait_metrics(client)["metrics"]
    assert m["idf1"] == 1.0
    assert m["num_gt_tracks"] == 5


def test_next_unreviewed(api: tuple[TestClient, AnnotateServer]) -> None:
    client, _ = api
    op(client, {"op": "review", "start": 0, "end": 9})
    op(client, {"op": "review", "start": 12, "end": 12})
    assert client.get("/api/next?kind=unreviewed&start=0").json() == {"frame": 10, "remaining": 49}
    assert client.get("/api/next?kind=unreviewed&start=10").json()["frame"] == 11
    assert client.get("/api/next?kind=unreviewed&start=11").json()["frame"] == 13
    assert client.get("/api/next?kind=unreviewed&start=13&dir=-1").json()["frame"] == 11
    assert client.get("/api/frame/12").json()["reviewed"] is True


def test_static_files_and_page(api: tuple[TestClient, AnnotateServer]) -> None:
    client, _ = api
    page = client.get("/")
    assert page.status_code == 200
    assert "app.js" in page.text
    for name, kind in (("app.js", "javascript"), ("style.css", "css")):
        r = client.get(f"/static/{name}")
        assert r.status_code == 200
        assert kind in r.headers["content-type"]
    assert "http" not in client.get("/static/app.js").text.replace("http://127.0.0.1", "")  # nothing external


def test_laser_only_rig(run_copy: Path) -> None:
    """A rig without a camera: no panorama (404 with a reason), scans still served."""
    info = json.loads((run_copy / "run.json").read_text())
    rig_path = Path(info["rig"])
    if not rig_path.is_absolute():
        rig_path = (Path.cwd() / rig_path) if (Path.cwd() / rig_path).exists() else run_copy.parent / rig_path
    text = rig_path.read_text()
    start = text.index("camera:")
    end = text.index("lasers:")
    rig2 = run_copy / "rig_laser.yaml"
    rig2.write_text(text[:start] + text[end:])
    rec = Path(info["recording"])
    info.update(
        rig=str(rig2),
        recording=str(rec if rec.is_absolute() else rig_path.parent / rec.name),
        image_size=None,
    )
    (run_copy / "run.json").write_text(json.dumps(info))
    state = AnnotateServer(run_copy)
    try:
        with TestClient(create_app(state)) as client:
            meta = client.get("/api/meta").json()
            assert meta["has_camera"] is False
            assert meta["media_problem"] is None
            body = client.get("/api/frame/3").json()
            assert len(body["scan"]["xy"]) > 500
            assert body["scan"]["uv"] is None
            assert all("pano" not in p for p in body["gt"])
            r = client.get("/api/frame/3/panorama.jpg")
            assert r.status_code == 404
            assert "no camera" in r.json()["error"]
    finally:
        state.close()


def test_a_large_run_serves_frames_and_edits(tmp_path: Path, make_run: Callable[..., Path]) -> None:
    """2 000 frames, 12 tracks, no sensor data: frames are served and a propagated edit goes through while
    the metrics come in the background (their speed: ``bench/bench_annotate_store.py --api``)."""
    run = tmp_path / "big"
    run.mkdir()
    make_run(run, num_frames=2000, tracks={k: (k * 90, min(1999, k * 90 + 900)) for k in range(12)})
    state = AnnotateServer(run)
    try:
        with TestClient(create_app(state)) as client:
            meta = client.get("/api/meta").json()
            assert meta["num_frames"] == 2000
            assert meta["media_problem"]
            assert not client.get("/api/metrics?wait=60").json()["stale"]  # the startup evaluation is done
            for n in range(1000, 1020):
                assert client.get(f"/api/frame/{n}").status_code == 200
            r = op(client, {"op": "move", "frame": 1000, "id": 5, "x": 0.0, "y": 3.0, "propagate": True})
            assert r.status_code == 200
            assert len(r.json()["frames"]) > 100
            assert client.get("/api/frame/1001").status_code == 200
            m = client.get("/api/metrics?wait=60").json()
            assert not m["stale"]
            assert 1000 in m["flagged"]
    finally:
        state.close()


def test_doubts_are_the_runs_review_points(sim_run: Path, run_copy: Path) -> None:
    """The run's review.jsonl: its frames in the meta, its notes on each frame, ``next?kind=doubt`` from
    one to the next; a broken file stops the server with one line."""
    from studio.annotate.server import ServerError
    from studio.labels import ReviewPoint, read_labels, read_review, review_points, write_review

    # the real run's points are the labels' own
    made = read_review(sim_run / "review.jsonl")
    assert made == review_points(read_labels(sim_run / "labels.jsonl").frames)
    stamps = {f.frame: f.stamp_ns for f in read_labels(run_copy / "labels.jsonl").frames}
    points = [
        ReviewPoint(7, stamps[7], (1,), "gap", "track 1 seen again after 1.2 s: the same person?", 0.2),
        ReviewPoint(20, stamps[20], (1, 2), "encounter", "tracks 1 and 2 came within 0.31 m: ...", 0.6),
        ReviewPoint(20, stamps[20], (3,), "start", "track 3 begins: is it someone labelled before?", 0.2),
    ]
    write_review(run_copy / "review.jsonl", points)
    state = AnnotateServer(run_copy, author="tester")
    try:
        with TestClient(create_app(state)) as client:
            assert client.get("/api/meta").json()["doubts"] == [7, 20]
            assert client.get("/api/next?kind=doubt&start=0").json() == {"frame": 7, "remaining": 2}
            assert client.get("/api/next?kind=doubt&start=7").json()["frame"] == 20
            assert client.get("/api/next?kind=doubt&start=20").json()["frame"] is None
            assert client.get("/api/next?kind=doubt&start=20&dir=-1").json()["frame"] == 7
            # the most doubtful first, from wherever one is
            assert client.get("/api/next?kind=worst&start=30").json() == {"frame": 20, "remaining": 2}
            # a doubt whose frame was marked reviewed is checked off
            assert op(client, {"op": "review", "start": 7, "end": 7}).status_code == 200
            assert client.get("/api/next?kind=doubt&start=0").json() == {"frame": 20, "remaining": 1}
            doubts = client.get("/api/frame/20").json()["doubts"]
            assert [d["ids"] for d in doubts] == [[1, 2], [3]]
            assert doubts[0]["kind"] == "encounter"
            assert [d["doubt"] for d in doubts] == [0.6, 0.2]
            assert op(client, {"op": "review", "start": 20, "end": 20}).status_code == 200
            assert client.get("/api/next?kind=worst&start=0").json() == {"frame": None, "remaining": 0}
            assert client.get("/api/frame/8").json()["doubts"] == []
            r = client.get("/api/next?kind=doubts&start=0")
            assert r.status_code == 400
            assert "'worst'" in r.json()["error"]
    finally:
        state.close()
    (run_copy / "review.jsonl").write_text('{"frame": 1}\n')
    with pytest.raises(ServerError, match=r"review\.jsonl:1: not a review point"):
        AnnotateServer(run_copy, author="tester")
