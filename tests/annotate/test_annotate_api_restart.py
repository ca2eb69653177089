"""`studio annotate` as a process: edits over HTTP, SIGKILL mid-session, restart: every acknowledged edit
is there."""

from __future__ import annotations

import json
import os
import signal
import socket
import subprocess
import sys
import time
import urllib.error
import urllib.request
from pathlib import Path
from typing import Any

import pytest

from studio.labels import read_labels


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def _start(run: Path, port: int) -> subprocess.Popen[str]:
    proc = subprocess.Popen(
        [sys.executable, "-m", "studio.cli", "annotate", str(run), "--port", str(port)],
        stdout=subprocess.PIPE,
        stderr=subprocess.STDOUT,
        text=True,
    )
    assert proc.stdout is not None
    deadline = time.monotonic() + 60
    lines = []
    while time.monotonic() < deadline:
        line = proc.stdout.readline()
        lines.append(line)
        if f"http://127.0.0.1:{port}/" in line:
            break
        if proc.poll() is not None:
            raise AssertionError("server exited: " + "".join(lines))
    for _ in range(100):  # the socket is bound before the URL is printed; wait until it answers
        try:
            _get(port, "/api/meta")
            return proc
        except (urllib.error.URLError, ConnectionError):
            time.sleep(0.1)
    raise AssertionError("server does not answer: " + "".join(lines))


def _get(port: int, path: str) -> Any:
    with urllib.request.urlopen(f"http://127.0.0.1:{port}{path}", timeout=30) as r:
        return json.loads(r.read())


def _post(port: int, path: str, body: dict[str, Any]) -> tuple[int, Any]:
    req = urllib.request.Request(
        f"http://127.0.0.1:{port}{path}",
        data=json.dumps(body).encode(),
        headers={"Content-Type": "application/json"},
    )
    try:
        with urllib.request.urlopen(req, timeout=30) as r:
            return r.status, json.loads(r.read())
    except urllib.error.HTTPError as exc:
        return exc.code, json.loads(exc.read())


@pytest.fixture
def run_dir_copy(tmp_path_factory: pytest.TempPathFactory, tmp_path: Path) -> Path:
    import shutil

    from test_annotate_api import make_sim_run  # same session cache as the API tests

    src = make_sim_run(tmp_path_factory.getbasetemp() / "annotate_sim")
    dst = tmp_path / "run"
    shutil.copytree(src, dst)
    return dst


def test_kill_and_restart_keeps_every_acknowledged_edit(run_dir_copy: Path) -> None:
    run = run_dir_copy
    port = _free_port()
    proc = _start(run, port)
    acked: list[dict[str, Any]] = []
    try:
        rev = _get(port, "/api/meta")["rev"]
        edits = [
            {"op": "move", "frame": 4, "id": 0, "x": 1.25, "y": 2.5},
            {"op": "add", "frame": 7, "id": 31, "x": -1.0, "y": 0.75},
            {"op": "delete", "frame": 9, "id": 2},
            {"op": "split", "id": 1, "frame": 40, "new_id": 41},
            {"op": "review", "start": 0, "end": 19},
            {"op": "move", "frame": 25, "id": 3, "x": 3.0, "y": -3.0, "propagate": True},
        ]
        for e in edits:
            status, body = _post(port, "/api/op", {"op": e, "base_rev": rev, "client": "killer"})
            assert status == 200, body
            rev = body["rev"]
            acked.append(e)
        assert (
            _post(
                port, "/api/op", {"op": {"op": "move", "frame": 4, "id": 0, "x": 0, "y": 0}, "base_rev": 0}
            )[0]
            == 409
        )
        assert _post(port, "/api/op", {"op": {"op": "delete", "frame": 4, "id": 999}})[0] == 422
    finally:
        os.kill(proc.pid, signal.SIGKILL)  # no clean shutdown
        proc.wait(timeout=30)
    assert proc.returncode == -signal.SIGKILL

    proc = _start(run, port)
    try:
        meta = _get(port, "/api/meta")
        assert meta["rev"] == len(acked)
        assert meta["reviewed"] == list(range(20))
        f4 = {p["id"]: p for p in _get(port, "/api/frame/4")["gt"]}
        assert (f4[0]["x"], f4[0]["y"]) == (1.25, 2.5)
        f7 = {p["id"]: p for p in _get(port, "/api/frame/7")["gt"]}
        assert (f7[31]["x"], f7[31]["y"]) == (-1.0, 0.75)
        assert 2 not in {p["id"] for p in _get(port, "/api/frame/9")["gt"]}
        ids45 = {p["id"] for p in _get(port, "/api/frame/45")["gt"]}
        assert 41 in ids45
        assert 1 not in ids45
        f25 = {p["id"]: p for p in _get(port, "/api/frame/25")["gt"]}
        assert (f25[3]["x"], f25[3]["y"]) == (3.0, -3.0)
        hist = _get(port, "/api/history?limit=100")["history"]
        assert [h["op"]["op"] for h in reversed(hist)] == [e["op"] for e in acked]
        # and the materialised ground truth the evaluator reads agrees
        gt = read_labels(run / "ground_truth.jsonl").by_frame()
        assert {p.id: (p.x, p.y) for p in gt[4].people}[0] == (1.25, 2.5)
        assert 31 in {p.id for p in gt[7].people}
    finally:
        proc.send_signal(signal.SIGINT)  # Ctrl-C: a clean exit with status 0
        assert proc.wait(timeout=30) == 0
