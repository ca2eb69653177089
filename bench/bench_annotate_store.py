"""Annotation store speed on a long run: open + replay, and one op (fsync + rewrite of both GT files).

Targets (issue #6): 2 000 frames × ~10 people, open + replay of 1 000 ops < 2 s, one op < 50 ms.

    .venv/bin/python bench/bench_annotate_store.py [--frames 2000] [--people 10] [--ops 1000]
    .venv/bin/python bench/bench_annotate_store.py --api

``--api`` times the annotation server instead (no sensor data, through FastAPI's test client): one frame
request, a move propagated over hundreds of frames, and a frame request right after it, which must not
wait for the metrics that are recomputed in the background (until session 18 a unit test timed these).
"""

from __future__ import annotations

import argparse
import os
import random
import statistics
import tempfile
import time
from pathlib import Path
from typing import Any

from studio.annotate import AnnotationError, AnnotationStore
from studio.geometry.se import Pose2
from studio.labels import LabelFrame, LabelPerson, write_labels_jsonl


def make_labels(path: Path, *, frames: int, people: int, seed: int = 0) -> None:
    """Auto-labels like a tracker's: ``people`` tracks at a time, each living 50–400 frames."""
    rng = random.Random(seed)
    out, next_id = [], 0
    alive: dict[int, list[float]] = {}  # id → [x, y, frames left]
    for n in range(frames):
        while len(alive) < people:
            alive[next_id] = [rng.uniform(-8, 8), rng.uniform(-8, 8), rng.randint(50, 400)]
            next_id += 1
        pose = Pose2(0.05 * n, 0.0, 0.001 * n)
        ps = []
        for k, st in sorted(alive.items()):
            st[0] += rng.gauss(0, 0.02)
            st[1] += rng.gauss(0, 0.02)
            xo, yo = pose.apply((st[0], st[1]))
            ps.append(
                LabelPerson(
                    id=k, x=st[0], y=st[1], x_odom=float(xo), y_odom=float(yo),
                    cov=((0.02, 0.0), (0.0, 0.02)), source="fused",
                    box=(10.0 * k, 300.0, 10.0 * k + 60.0, 600.0), score=0.8,
                )
            )  # fmt: skip
            st[2] -= 1
        alive = {k: st for k, st in alive.items() if st[2] > 0}
        out.append(LabelFrame(frame=n, people=tuple(ps), stamp_ns=10**18 + n * 10**8, robot_pose=pose))
    write_labels_jsonl(path, out)


def random_op(rng: random.Random, s: AnnotationStore) -> dict[str, Any]:
    n = rng.randrange(s.num_frames)
    ids = [p.id for p in s.frame(n).people] or [0]
    k = rng.choice(ids)
    r = rng.random()
    if r < 0.5:
        return {"op": "move", "frame": n, "id": k, "x": rng.uniform(-8, 8), "y": rng.uniform(-8, 8),
                "propagate": rng.random() < 0.3}  # fmt: skip
    if r < 0.65:
        return {"op": "add", "frame": n, "id": 10_000 + rng.randrange(1000), "x": 1.0, "y": 1.0}
    if r < 0.75:
        return {"op": "delete", "frame": n, "id": k}
    if r < 0.85:
        return {"op": "flag", "frame": n, "id": k, "occluded": True}
    if r < 0.95:
        return {"op": "set_id", "id": k, "new_id": None, "start": max(0, n - 50), "end": n + 0}
    return {"op": "review", "start": n, "end": min(s.num_frames - 1, n + 100)}


def api(frames: int, people: int) -> None:
    """Time the annotation server's frame requests and a propagated move on a generated run."""
    from fastapi.testclient import TestClient

    from studio.annotate.app import create_app
    from studio.annotate.server import AnnotateServer

    with tempfile.TemporaryDirectory() as tmp:
        run = Path(tmp) / "run"
        run.mkdir()
        make_labels(run / "labels.jsonl", frames=frames, people=people)
        state = AnnotateServer(run)
        try:
            with TestClient(create_app(state)) as client:
                client.get("/api/metrics?wait=60")  # the startup evaluation
                mid = frames // 2
                t0 = time.perf_counter()
                for n in range(mid, mid + 20):
                    client.get(f"/api/frame/{n}").raise_for_status()
                per_frame = (time.perf_counter() - t0) / 20
                ids = [p["id"] for p in client.get(f"/api/frame/{mid}").json()["auto"]]
                later = {p["id"] for p in client.get(f"/api/frame/{mid + 200}").json()["auto"]}
                pid = next((k for k in ids if k in later), ids[0])  # one who lives on: a long propagation
                body = {"op": "move", "frame": mid, "id": pid, "x": 0.0, "y": 3.0, "propagate": True}
                t0 = time.perf_counter()
                r = client.post("/api/op", json={"op": body, "base_rev": None, "client": "bench"})
                t_op = time.perf_counter() - t0
                r.raise_for_status()
                t0 = time.perf_counter()
                client.get(f"/api/frame/{mid + 1}").raise_for_status()
                t_after = time.perf_counter() - t0
        finally:
            state.close()
    print(f"run: {frames} frames, ~{people} people/frame; load average {os.getloadavg()[0]:.1f}")
    print(f"one frame request: {1000 * per_frame:.1f} ms  (target < 100 ms)")
    print(f"a move propagated over {len(r.json()['frames'])} frames: {1000 * t_op:.0f} ms  (target < 2 s)")
    print(f"the next frame request, metrics recomputing: {1000 * t_after:.1f} ms  (target < 200 ms)")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--frames", type=int, default=2000)
    ap.add_argument("--people", type=int, default=10)
    ap.add_argument("--ops", type=int, default=1000)
    ap.add_argument("--api", action="store_true", help="time the annotation server instead of the store")
    args = ap.parse_args()
    if args.api:
        api(args.frames, args.people)
        return
    with tempfile.TemporaryDirectory() as tmp:
        run = Path(tmp) / "run"
        run.mkdir()
        make_labels(run / "labels.jsonl", frames=args.frames, people=args.people)
        size = (run / "labels.jsonl").stat().st_size
        t0, c0 = time.perf_counter(), time.process_time()
        s = AnnotationStore.open(run)
        t_first, c_first = time.perf_counter() - t0, time.process_time() - c0
        rng = random.Random(1)
        times, cpu, done = [], [], 0
        while done < args.ops:
            op = random_op(rng, s)
            t, c = time.perf_counter(), time.process_time()
            try:
                if rng.random() < 0.05 and s.can_undo:
                    s.undo()
                else:
                    s.apply(op, base_rev=s.rev)
            except AnnotationError:
                continue
            times.append(time.perf_counter() - t)
            cpu.append(time.process_time() - c)
            done += 1
        rev = s.rev
        s.close()
        t0, c0 = time.perf_counter(), time.process_time()
        s = AnnotationStore.open(run)
        t_reopen, c_reopen = time.perf_counter() - t0, time.process_time() - c0
        assert s.rev == rev
        s.close()
        gt = (run / "ground_truth.jsonl").stat().st_size
        ms = sorted(1000 * t for t in times)
        cms = sorted(1000 * t for t in cpu)
        print(f"run: {args.frames} frames, ~{args.people} people/frame, labels.jsonl {size / 1e6:.1f} MB, "
              f"ground_truth.jsonl {gt / 1e6:.1f} MB")  # fmt: skip
        print(f"load average: {' '.join(f'{v:.1f}' for v in os.getloadavg())} on {os.cpu_count()} CPUs "
              "(wall times grow with the load; CPU times much less)")  # fmt: skip
        print(f"first open (no log, writes both GT files): {t_first:.3f} s wall, {c_first:.3f} s CPU")
        print(f"one op incl. fsync + rewrite of both GT files, {len(ms)} ops: "
              f"median {statistics.median(ms):.1f} ms, p95 {ms[int(0.95 * len(ms))]:.1f} ms, "
              f"max {ms[-1]:.1f} ms wall; CPU median {statistics.median(cms):.1f} ms, "
              f"p95 {cms[int(0.95 * len(cms))]:.1f} ms  (target < 50 ms)")  # fmt: skip
        print(
            f"reopen + replay of {rev} records: {t_reopen:.3f} s wall, {c_reopen:.3f} s CPU  (target < 2 s)"
        )


if __name__ == "__main__":
    main()
