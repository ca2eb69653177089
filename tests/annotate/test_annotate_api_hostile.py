"""Hostile requests and broken run directories (issue #6 review): each is refused with a clear 4xx or a
clear start-up error, and the state stays intact."""

from __future__ import annotations

import http.client
import json
import os
import signal
import threading
import time
import urllib.error
import urllib.request
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import pytest

pytest.importorskip("fastapi")
from fastapi.testclient import TestClient

from studio.annotate import AnnotationError, AnnotationStore
from studio.annotate.app import create_app
from studio.annotate.server import AnnotateServer, ServerError
from studio.labels import read_labels


@pytest.fixture
def api(run_dir: Path) -> Iterator[tuple[TestClient, AnnotateServer]]:
    state = AnnotateServer(run_dir, author="tester")
    with TestClient(create_app(state)) as client:
        yield client, state
    state.close()


def _post_raw(client: TestClient, path: str, raw: bytes) -> Any:
    return client.post(path, content=raw, headers={"Content-Type": "application/json"})


def _snapshot(client: TestClient) -> list[Any]:
    return [client.get(f"/api/frame/{n}").json()["gt"] for n in range(10)]


HOSTILE: list[tuple[bytes, int, str]] = [
    (b'{"op": {"op": "add", "frame": 1, "id": 100000000000000000000, "x": 1, "y": 1}}', 422, "at most"),
    (b'{"op": {"op": "add", "frame": 1, "id": 7, "x": 1e308, "y": 1}}', 422, "within"),
    (b'{"op": {"op": "move", "frame": 1, "id": 1, "x": 0, "y": -5000}}', 422, "within"),
    (b'{"op": {"op": "set_id", "id": 1, "start": 0, "end": 9, "new_id": 4294967296}}', 422, "at most"),
    (b'{"op": {"op": "add", "frame": 1, "id": 7, "x": 1, "y": 1}, "client": "\\ud800"}', 400, "surrogate"),
    (b'{"op": {"op": "add", "frame": 1, "id": 7, "x": 1, "y": 1}, "author": "\\udfff x"}', 400, "surrogate"),
    (b'{"op": {"op": "add", "frame": 1, "id": 7, "x": 1, "y": 1}, "client": "a\\u0000b"}', 400, "control"),
    (
        b'{"op": {"op": "add", "frame": 1, "id": 7, "x": 1, "y": 1}, "client": "' + b"c" * 300 + b'"}',
        400,
        "200",
    ),
    (b'{"op": {"op": "add", "frame": 1, "id": 7, "x": 1, "y": 1}, "client": 5}', 400, "string"),
    (b'{"client": "\\ud800"}', 400, "surrogate"),  # undo (see the test)
]


@pytest.mark.parametrize(("raw", "status", "message"), HOSTILE)
def test_hostile_values_are_refused_and_nothing_changes(
    api: tuple[TestClient, AnnotateServer], raw: bytes, status: int, message: str
) -> None:
    client, state = api
    assert client.post("/api/op", json={"op": {"op": "review", "start": 0, "end": 9}}).status_code == 200
    before = _snapshot(client)
    path = "/api/undo" if raw.startswith(b'{"client"') else "/api/op"
    r = _post_raw(client, path, raw)
    assert r.status_code == status, r.text
    assert message in r.json()["error"]
    assert state.store.rev == 1
    assert _snapshot(client) == before
    assert client.get("/api/history").status_code == 200
    assert client.get("/api/metrics?wait=30").json()["metrics"] is not None


def test_names_are_kept_as_unicode_and_undo_records_the_client(
    api: tuple[TestClient, AnnotateServer],
) -> None:
    client, state = api
    body = {"op": {"op": "add", "frame": 1, "id": 7, "x": 1, "y": 1}, "client": "tab ü 日本", "author": "Zoë"}
    assert client.post("/api/op", json=body).status_code == 200
    assert client.post("/api/undo", json={"client": "tab ü 日本", "base_rev": 1}).status_code == 200
    hist = client.get("/api/history").json()["history"]
    assert [(h["author"], h["client"]) for h in hist] == [("tester", "tab ü 日本"), ("Zoë", "tab ü 日本")]
    assert client.get("/api/frame/1").status_code == 200
    state.close()
    with AnnotationStore.open(state.run_dir) as again:  # the log reads back
        assert [h["client"] for h in again.history()] == ["tab ü 日本", "tab ü 日本"]


def test_store_refuses_bad_names(run_dir: Path) -> None:
    with pytest.raises(AnnotationError, match="surrogate"):
        AnnotationStore.open(run_dir, author="\ud800")
    with AnnotationStore.open(run_dir) as store:
        with pytest.raises(AnnotationError, match="client"):
            store.apply({"op": "delete", "frame": 1, "id": 1}, client="x" * 201)
        assert store.rev == 0


def test_body_size_is_limited(api: tuple[TestClient, AnnotateServer]) -> None:
    client, state = api
    big = json.dumps({"op": {"op": "add", "frame": 1, "id": 7, "x": 1, "y": 1}, "pad": "x" * 400_000})
    r = _post_raw(client, "/api/op", big.encode())
    assert r.status_code == 413
    assert "too large" in r.json()["error"]
    assert state.store.rev == 0

    def chunks() -> Iterator[bytes]:  # no Content-Length: the limit holds while streaming
        yield b'{"op": {"op": "add", "frame": 1, "id": 7, "x": 1, "y": 1}, "pad": "'
        for _ in range(40):
            yield b"y" * 10_000
        yield b'"}'

    r = client.post("/api/op", content=chunks(), headers={"Content-Type": "application/json"})
    assert r.status_code == 413
    assert state.store.rev == 0


def test_evaluation_survives_a_failure(
    api: tuple[TestClient, AnnotateServer], monkeypatch: pytest.MonkeyPatch
) -> None:
    client, _ = api
    import studio.evaluate

    real = studio.evaluate.evaluate
    calls = {"n": 0}

    def flaky(*args: Any, **kwargs: Any) -> Any:
        calls["n"] += 1
        if calls["n"] <= 2:
            raise OverflowError("boom")
        return real(*args, **kwargs)

    monkeypatch.setattr(studio.evaluate, "evaluate", flaky)
    assert client.post("/api/op", json={"op": {"op": "review", "start": 0, "end": 9}}).status_code == 200
    m = client.get("/api/metrics?wait=30").json()
    if m["metrics"] is None:  # the failing evaluation: reported, not fatal
        assert "OverflowError: boom" in m["metrics_error"]
        assert client.post("/api/op", json={"op": {"op": "delete", "frame": 1, "id": 1}}).status_code == 200
        m = client.get("/api/metrics?wait=30").json()
    assert m["metrics"] is not None, m
    assert m["metrics_error"] is None
    assert not m["stale"]


def test_polled_state_is_small_whatever_the_run_length(tmp_path: Path, make_run: Callable[..., Path]) -> None:
    sizes = []
    for n in (10, 2000):
        state = AnnotateServer(make_run(tmp_path / f"run{n}", num_frames=n), author="t")
        try:
            with TestClient(create_app(state)) as client:
                client.post("/api/op", json={"op": {"op": "review", "start": 0, "end": 5}})
                body = client.get("/api/state")
                assert body.status_code == 200
                assert set(body.json()) == {"rev", "metrics_rev", "reviewed_frames", "rerun"}
                assert body.json()["rev"] == 1
                assert body.json()["reviewed_frames"] == 6
                sizes.append(len(body.content))
                frame = client.get(f"/api/frame/{n // 2}")
                assert len(frame.content) < 20_000  # one frame's people, trails and scan: not O(run)
        finally:
            state.close()
    assert sizes[1] <= sizes[0] + 8


def test_empty_labels_refused_before_anything_is_written(tmp_path: Path) -> None:
    run = tmp_path / "run"
    run.mkdir()
    (run / "labels.jsonl").write_text("")
    with pytest.raises(ServerError, match="no frames"):
        AnnotateServer(run)
    assert not (run / "annotations").exists()


def test_read_only_run_is_a_clear_error(run_dir: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    real = os.access
    monkeypatch.setattr(os, "access", lambda p, mode: False if mode == os.W_OK else real(p, mode))
    with pytest.raises(AnnotationError, match="read-only"):
        AnnotateServer(run_dir)
    assert not (run_dir / "annotations").exists()


def test_missing_recording_is_reported_in_meta(api: tuple[TestClient, AnnotateServer], run_dir: Path) -> None:
    client, _ = api
    meta = client.get("/api/meta").json()
    assert meta["media_problem"]  # this run has no run.json: labels only
    assert client.get("/api/frame/3").json()["scan"] is None
    assert client.post("/api/op", json={"op": {"op": "delete", "frame": 3, "id": 1}}).status_code == 200


# ---------------------------------------------------------------- a burst of concurrent posts, then SIGKILL


def _post(port: int, body: dict[str, Any]) -> dict[str, Any]:
    req = urllib.request.Request(
        f"http://127.0.0.1:{port}/api/op",
        data=json.dumps(body).encode(),
        headers={"Content-Type": "application/json"},
    )
    with urllib.request.urlopen(req, timeout=30) as r:
        return dict(json.loads(r.read()))


def test_sigkill_during_a_concurrent_burst_keeps_every_acknowledged_edit(
    tmp_path: Path, make_run: Callable[..., Path]
) -> None:
    from test_annotate_api_restart import _free_port, _start

    run = make_run(tmp_path / "run", num_frames=200, tracks={1: (0, 199), 2: (0, 199)})
    port = _free_port()
    proc = _start(run, port)
    acked: list[tuple[int, dict[str, Any]]] = []
    lock = threading.Lock()
    stop = threading.Event()

    def worker(w: int) -> None:
        i = 0
        while not stop.is_set():
            i += 1
            op = {
                "op": "add",
                "frame": (7 * i + w) % 200,
                "id": 1000 * (w + 1) + i,
                "x": 0.5 * w,
                "y": 0.01 * i,
            }
            try:
                res = _post(port, {"op": op, "client": f"w{w}"})
            except (OSError, urllib.error.URLError, http.client.HTTPException):
                return  # the server died mid-request: not acknowledged
            with lock:
                acked.append((res["rev"], op))

    threads = [threading.Thread(target=worker, args=(w,)) for w in range(4)]
    for t in threads:
        t.start()
    deadline = time.monotonic() + 30
    while len(acked) < 40 and time.monotonic() < deadline:
        time.sleep(0.05)
    os.kill(proc.pid, signal.SIGKILL)
    stop.set()
    for t in threads:
        t.join(timeout=30)
    proc.wait(timeout=30)
    assert len(acked) >= 40
    assert sorted(r for r, _ in acked) == sorted({r for r, _ in acked})  # one revision per acknowledged op

    with AnnotationStore.open(run) as store:
        assert store.rev >= max(r for r, _ in acked)  # an op in flight may have landed too
        for _, op in acked:
            people = {p.id: p for p in store.frame(op["frame"]).people}
            assert (people[op["id"]].x, people[op["id"]].y) == (op["x"], op["y"])
        frames = store.frames()
    # the files the evaluator reads parse and equal the store (the thesis YAML keeps millimetres)
    for name, tol in (("ground_truth.jsonl", 1e-6), ("ground_truth.yaml", 5.01e-4)):
        files = read_labels(run / name).by_frame()
        assert sorted(files) == [f.frame for f in frames]
        for f in frames:
            got = {p.id: (p.x, p.y) for p in files[f.frame].people}
            assert sorted(got) == sorted(p.id for p in f.people), (name, f.frame)
            for p in f.people:
                assert abs(got[p.id][0] - p.x) <= tol, name
                assert abs(got[p.id][1] - p.y) <= tol, name


def test_logs_written_before_the_limits_still_open(run_dir: Path) -> None:
    with AnnotationStore.open(run_dir) as store:
        store.apply({"op": "add", "frame": 1, "id": 7, "x": 1.0, "y": 1.0})
    log = run_dir / "annotations" / "corrections.jsonl"
    log.write_text(log.read_text().replace('"id":7,"x":1.0', '"id":100000000000000000000,"x":1e300'))
    state = AnnotateServer(run_dir)  # replays without the new limits
    try:
        with TestClient(create_app(state)) as client:
            people = {p["id"]: p for p in client.get("/api/frame/1").json()["gt"]}
            assert people[10**20]["x"] == 1e300
            assert (
                client.post("/api/op", json={"op": {"op": "review", "start": 0, "end": 9}}).status_code == 200
            )
            m = client.get("/api/metrics?wait=30").json()  # the evaluator cannot take such an id: reported
            assert m["metrics"] is None
            assert m["metrics_error"]
            assert (
                client.post("/api/op", json={"op": {"op": "delete", "frame": 1, "id": 10**20}}).status_code
                == 200
            )
            assert client.get("/api/metrics?wait=30").json()["metrics"] is not None
    finally:
        state.close()


@pytest.mark.parametrize("n", ["1_0", "+1", "%20%31", "%D9%A1", "--1", "1.0", "99999999999999999999999"])
def test_frame_numbers_in_paths_are_plain_ascii_integers(
    api: tuple[TestClient, AnnotateServer], n: str
) -> None:
    client, _ = api
    r = client.get(f"/api/frame/{n}")
    assert r.status_code == 400, r.text
    assert "frame must be an integer" in r.json()["error"]
    assert client.get("/api/frame/-1").status_code == 404
    assert client.get("/api/frame/3").status_code == 200
