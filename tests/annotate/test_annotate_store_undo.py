"""Undo/redo chains, reopening (= the same state), conflicts between clients, history and who changed what."""

from __future__ import annotations

import random
import shutil
from pathlib import Path
from typing import Any

import pytest

from studio.annotate import AnnotationError, AnnotationStore, ConflictError


def snapshot(s: AnnotationStore) -> dict[str, Any]:
    """Everything observable of a store."""
    return {
        "rev": s.rev,
        "frames": s.frames(),
        "frame_rev": [s.frame_rev(n) for n in range(s.num_frames)],
        "reviewed": s.reviewed(),
        "history": s.history(limit=10_000),
        "changed_by": [s.changed_by(n) for n in range(s.num_frames)],
        "can": (s.can_undo, s.can_redo),
    }


def test_undo_redo_chain(run_dir: Path) -> None:
    with AnnotationStore.open(run_dir) as s:
        base = s.frames()
        s.apply({"op": "move", "frame": 1, "id": 1, "x": 0.0, "y": 0.0, "propagate": True})
        after1 = s.frames()
        s.apply({"op": "delete", "frame": 2, "id": 2})
        after2 = s.frames()
        r = s.undo()
        assert (r.rev, r.frames, r.op) == (3, [2], {"op": "undo", "target": 2})
        assert s.frames() == after1
        r = s.undo()
        assert r.op["target"] == 1
        assert r.frames == list(range(1, 10))
        assert s.frames() == base
        with pytest.raises(AnnotationError, match="nothing to undo"):
            s.undo()
        assert s.redo().op == {"op": "redo", "target": 1}
        assert s.frames() == after1
        assert s.redo().op == {"op": "redo", "target": 2}
        assert s.frames() == after2
        with pytest.raises(AnnotationError, match="nothing to redo"):
            s.redo()
        assert s.rev == 6
        hist = s.history()
        assert [h["op"]["op"] for h in hist] == ["redo", "redo", "undo", "undo", "delete", "move"]
        assert not any(h["undone"] for h in hist)


def test_new_op_clears_redo(run_dir: Path) -> None:
    with AnnotationStore.open(run_dir) as s:
        s.apply({"op": "delete", "frame": 2, "id": 2})
        s.apply({"op": "delete", "frame": 3, "id": 2})
        s.undo()
        assert s.can_redo
        s.apply({"op": "delete", "frame": 4, "id": 2})
        assert not s.can_redo
        with pytest.raises(AnnotationError, match="nothing to redo"):
            s.redo()
        assert [p.id for p in s.frame(3).people] == [1, 2, 5]  # the undone delete stays undone
        assert s.history(limit=10)[-2]["undone"] is True  # seq 2
        s.undo()
        s.undo()
        assert [p.id for p in s.frame(2).people] == [1, 2]
        with pytest.raises(AnnotationError, match="nothing to undo"):
            s.undo()


def test_undo_restores_who_changed_what(run_dir: Path) -> None:
    with AnnotationStore.open(run_dir, author="ana") as s:
        s.apply({"op": "move", "frame": 3, "id": 1, "x": 1.0, "y": 1.0}, client="tab-a")
        s.apply({"op": "flag", "frame": 3, "id": 1, "occluded": True}, author="bob")
        who = s.changed_by(3)
        assert set(who) == {1}
        assert (who[1]["author"], who[1]["op"]["op"], who[1]["how"]) == ("bob", "flag", "flag")
        s.undo()
        who = s.changed_by(3)[1]
        assert (who["author"], who["client"], who["op"]["op"], who["how"]) == ("ana", "tab-a", "move", "edit")
        s.undo()
        assert s.changed_by(3) == {}
        assert [h["seq"] for h in s.history(frame=3)] == [4, 3, 2, 1]
        assert s.history(frame=5) == []
        assert len(s.history(limit=2)) == 2


def random_op(rng: random.Random, s: AnnotationStore) -> dict[str, Any]:
    n = rng.randrange(s.num_frames)
    present = [p.id for p in s.frame(n).people]
    k = rng.choice(present) if present else rng.randrange(4)
    a, b = sorted(rng.sample(range(s.num_frames), 2))
    kind = rng.choice(["add", "move", "move", "delete", "set_id", "merge", "swap", "split", "flag", "review"])
    xy = {"x": rng.uniform(-5, 5), "y": rng.uniform(-5, 5)}
    return {
        "add": {"op": "add", "frame": n, "id": rng.randrange(12), **xy},
        "move": {"op": "move", "frame": n, "id": k, **xy, "propagate": rng.random() < 0.5},
        "delete": {"op": "delete", "frame": n, "id": k},
        "set_id": {
            "op": "set_id",
            "id": k,
            "new_id": rng.choice([None, rng.randrange(12)]),
            "start": a,
            "end": b,
        },
        "merge": {
            "op": "merge",
            "ids": rng.sample(range(8), 2),
            "into": rng.randrange(12),
            "start": a,
            "end": b,
        },
        "swap": {"op": "swap", "ids": rng.sample(range(8), 2), "start": a, "end": b},
        "split": {"op": "split", "id": k, "frame": n, "new_id": None, "end": rng.choice([None, b])},
        "flag": {
            "op": "flag",
            "frame": n,
            "id": k,
            "occluded": rng.choice([True, False, None]),
            "uncertain": True,
        },
        "review": {"op": "review", "start": a, "end": b, "reviewed": rng.random() < 0.8},
    }[kind]


@pytest.mark.parametrize("seed", range(4))
def test_random_sequences_reopen_and_replay(run_dir: Path, tmp_path: Path, seed: int) -> None:
    """After random ops/undo/redo, reopening gives the same state, and so does applying only the ops
    that are in effect (the undo stack) to a fresh store."""
    rng = random.Random(seed)
    fresh = tmp_path / "fresh"
    fresh.mkdir()
    shutil.copy(run_dir / "labels.jsonl", fresh / "labels.jsonl")
    s = AnnotationStore.open(run_dir)
    applied = errors = 0
    for _ in range(80):
        r = rng.random()
        try:
            if r < 0.15:
                s.undo()
            elif r < 0.25:
                s.redo()
            else:
                s.apply(random_op(rng, s))
                applied += 1
        except AnnotationError:
            errors += 1
    assert applied > 20
    assert errors > 0
    state = snapshot(s)
    hist = reversed(s.history(limit=10_000))
    in_effect = [h["op"] for h in hist if h["op"]["op"] not in ("undo", "redo") and not h["undone"]]
    s.close()
    with AnnotationStore.open(run_dir) as again:
        assert snapshot(again) == state
    with AnnotationStore.open(fresh) as other:
        for op in in_effect:
            other.apply(op)
        assert other.frames() == state["frames"]
    assert (run_dir / "ground_truth.jsonl").read_text() == (fresh / "ground_truth.jsonl").read_text()
    assert (run_dir / "ground_truth.yaml").read_text() == (fresh / "ground_truth.yaml").read_text()


def test_conflicts_between_two_clients(run_dir: Path) -> None:
    with AnnotationStore.open(run_dir) as s:
        seen_a = seen_b = s.rev  # both tabs loaded rev 0
        r = s.apply({"op": "move", "frame": 3, "id": 1, "x": 1.0, "y": 1.0}, base_rev=seen_a, client="a")
        seen_a = r.rev
        before = (s.frames(), (run_dir / "annotations" / "corrections.jsonl").read_bytes())
        with pytest.raises(ConflictError, match=r"frame 3 was changed at rev 1"):
            s.apply({"op": "delete", "frame": 3, "id": 2}, base_rev=seen_b, client="b")
        with pytest.raises(ConflictError, match="frame 3"):  # a propagation reaching frame 3
            s.apply(
                {"op": "move", "frame": 2, "id": 2, "x": 0.0, "y": 0.0, "propagate": True}, base_rev=seen_b
            )
        with pytest.raises(ConflictError, match="frame 3"):
            s.apply({"op": "review", "start": 0, "end": 9}, base_rev=seen_b)
        with pytest.raises(ConflictError, match="frame 3"):
            s.undo(base_rev=seen_b)
        assert (s.frames(), (run_dir / "annotations" / "corrections.jsonl").read_bytes()) == before
        assert s.rev == 1
        # b edits another frame: no conflict; a is not blocked by b's edit elsewhere
        seen_b = s.apply({"op": "delete", "frame": 7, "id": 5}, base_rev=seen_b).rev
        s.apply({"op": "delete", "frame": 3, "id": 2}, base_rev=seen_a)
        s.apply({"op": "delete", "frame": 3, "id": 5}, base_rev=s.rev)
        with pytest.raises(AnnotationError, match="base_rev"):
            s.apply({"op": "delete", "frame": 4, "id": 5}, base_rev=s.rev + 1)
        with pytest.raises(AnnotationError, match="base_rev"):
            s.apply({"op": "delete", "frame": 4, "id": 5}, base_rev=-1)
        assert s.frame_rev(3) == 4
        assert s.frame_rev(7) == 2
        assert s.frame_rev(0) == 0


def test_conflict_error_names_frame_and_rev(run_dir: Path) -> None:
    with AnnotationStore.open(run_dir) as s:
        s.apply({"op": "delete", "frame": 6, "id": 5})
        with pytest.raises(ConflictError) as info:
            s.apply({"op": "review", "start": 0, "end": 9}, base_rev=0)
        assert (info.value.frame, info.value.frame_rev) == (6, 1)


def test_threads_are_serialised(run_dir: Path) -> None:
    """Web servers call from a thread pool: concurrent ops all land, each once, in a consistent log."""
    import threading

    with AnnotationStore.open(run_dir) as s:

        def worker(t: int) -> None:
            for n in range(10):
                s.apply({"op": "add", "frame": n, "id": 20 + t, "x": float(t), "y": float(n)}, client=f"t{t}")
                s.frames()

        threads = [threading.Thread(target=worker, args=(t,)) for t in range(4)]
        for th in threads:
            th.start()
        for th in threads:
            th.join()
        assert s.rev == 40
        assert all({20, 21, 22, 23} <= {p.id for p in f.people} for f in s.frames())
        state = snapshot(s)
    with AnnotationStore.open(run_dir) as again:
        assert snapshot(again) == state
