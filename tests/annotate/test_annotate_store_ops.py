"""Each operation of the annotation store and each of its errors (state untouched after an error)."""

from __future__ import annotations

import math
from collections.abc import Callable
from pathlib import Path
from typing import Any

import pytest

from studio.annotate import AnnotationError, AnnotationStore
from studio.errors import StudioError

XY = Callable[[int, int], tuple[float, float]]


@pytest.fixture
def store(run_dir: Path):
    s = AnnotationStore.open(run_dir)
    yield s
    s.close()


def people(store: AnnotationStore, n: int) -> dict[int, tuple[float, float]]:
    return {p.id: (p.x, p.y) for p in store.frame(n).people}


def ids(store: AnnotationStore, n: int) -> list[int]:
    return [p.id for p in store.frame(n).people]


def test_open_shows_auto_labels(store: AnnotationStore) -> None:
    assert store.rev == 0
    assert store.num_frames == 10
    assert ids(store, 0) == [1, 2]
    assert ids(store, 3) == [1, 2, 5]
    assert ids(store, 9) == [1, 5]
    assert store.frame_rev(3) == 0
    assert store.reviewed() == set()
    assert store.history() == []


def test_add(store: AnnotationStore) -> None:
    r = store.apply({"op": "add", "frame": 4, "id": 7, "x": 0.5, "y": 1.5})
    assert (r.rev, r.frames) == (1, [4])
    assert ids(store, 4) == [1, 2, 5, 7]  # sorted by id
    p = store.frame(4).people[-1]
    assert (p.x, p.y, p.source) == (0.5, 1.5, "manual")
    pose = store.frame(4).robot_pose
    assert pose is not None
    xo, yo = pose.apply((0.5, 1.5))
    assert p.x_odom == pytest.approx(xo)
    assert p.y_odom == pytest.approx(yo)
    assert store.frame_rev(4) == 1
    assert store.frame_rev(3) == 0


def test_move_without_propagation(store: AnnotationStore, track_xy: XY) -> None:
    r = store.apply({"op": "move", "frame": 2, "id": 1, "x": 9.0, "y": 9.0})
    assert r.frames == [2]
    assert r.op["propagate"] is False
    assert people(store, 2)[1] == (9.0, 9.0)
    assert people(store, 3)[1] == pytest.approx(track_xy(1, 3))
    p = store.frame(2).people[0]
    assert p.source == "manual"
    assert p.cov is None
    assert p.box == (100.0, 50.0, 140.0, 200.0)  # the image box is kept


def test_move_propagates_until_the_track_ends(store: AnnotationStore, track_xy: XY) -> None:
    x0, y0 = track_xy(2, 1)
    r = store.apply({"op": "move", "frame": 1, "id": 2, "x": x0 + 0.3, "y": y0 - 0.1, "propagate": True})
    assert r.frames == [1, 2, 3, 4]  # id 2 lives in frames 0..4
    for n in (2, 3, 4):
        x, y = track_xy(2, n)
        assert people(store, n)[2] == pytest.approx((x + 0.3, y - 0.1))
    assert people(store, 0)[2] == pytest.approx(track_xy(2, 0))  # earlier frames untouched


def test_move_propagation_stops_at_gap_reviewed_and_manual_edit(
    run_dir: Path, tmp_path: Path, make_run: Callable[..., Path], track_xy: XY
) -> None:
    # id 3 present in 0..3 and 5..9: the gap at frame 4 stops propagation
    run = make_run(tmp_path / "gap", tracks={3: (0, 3), 4: (5, 9)})
    with AnnotationStore.open(run) as s:
        s.apply({"op": "set_id", "id": 4, "new_id": 3, "start": 5, "end": 9})
        r = s.apply({"op": "move", "frame": 1, "id": 3, "x": 0.0, "y": 0.0, "propagate": True})
        assert r.frames == [1, 2, 3]
    with AnnotationStore.open(run_dir) as s:
        s.apply({"op": "review", "start": 6, "end": 6})
        s.apply({"op": "move", "frame": 4, "id": 1, "x": 0.0, "y": 0.0})  # a hand edit at frame 4
        r = s.apply({"op": "move", "frame": 1, "id": 1, "x": 5.0, "y": 5.0, "propagate": True})
        assert r.frames == [1, 2, 3]  # stops before the hand-edited frame 4
        assert people(s, 4)[1] == (0.0, 0.0)
        r = s.apply({"op": "move", "frame": 4, "id": 1, "x": 1.0, "y": 0.0, "propagate": True})
        assert r.frames == [4, 5]  # stops before the reviewed frame 6
        assert people(s, 5)[1] == pytest.approx((track_xy(1, 5)[0] + 1.0, track_xy(1, 5)[1]))
        assert people(s, 6)[1] == pytest.approx(track_xy(1, 6))
        # a propagated (not hand-edited) frame does not stop a later propagation
        r = s.apply({"op": "move", "frame": 3, "id": 1, "x": 2.0, "y": 2.0, "propagate": True})
        assert r.frames == [3]  # frame 4 is a hand edit
        assert s.changed_by(5)[1]["how"] == "propagate"


def test_delete(store: AnnotationStore) -> None:
    r = store.apply({"op": "delete", "frame": 3, "id": 2})
    assert (r.frames, ids(store, 3)) == ([3], [1, 5])
    assert store.changed_by(3)[2]["how"] == "delete"


def test_set_id_range(store: AnnotationStore, track_xy: XY) -> None:
    r = store.apply({"op": "set_id", "id": 1, "new_id": 8, "start": 2, "end": 5})
    assert r.frames == [2, 3, 4, 5]
    assert ids(store, 1) == [1, 2]
    assert ids(store, 2) == [2, 8]
    assert ids(store, 5) == [5, 8]
    assert ids(store, 6) == [1, 5]
    assert people(store, 3)[8] == pytest.approx(track_xy(1, 3))


def test_set_id_picks_smallest_unused_id(store: AnnotationStore) -> None:
    r = store.apply({"op": "set_id", "id": 5, "new_id": None, "start": 0, "end": 9})
    assert r.op["new_id"] == 0  # ids 1, 2, 5 are used: 0 is free
    r = store.apply({"op": "set_id", "id": 2, "start": 0, "end": 9})
    assert r.op["new_id"] == 2 + 1  # 0, 1 used (2 is the one renamed) → 3


def test_merge(store: AnnotationStore) -> None:
    r = store.apply({"op": "set_id", "id": 5, "new_id": 6, "start": 5, "end": 9})
    r = store.apply({"op": "delete", "frame": 3, "id": 5})
    r = store.apply({"op": "delete", "frame": 4, "id": 5})
    # now id 2 in 0..4 and id 6 in 5..9: one person
    r = store.apply({"op": "merge", "ids": [2, 6], "into": 2, "start": 0, "end": 9})
    assert r.frames == [5, 6, 7, 8, 9]
    assert all(2 in ids(store, n) for n in range(10))
    assert all(6 not in ids(store, n) for n in range(10))


def test_swap(store: AnnotationStore, track_xy: XY) -> None:
    # ids 1 (0..9) and 5 (3..9) exchanged people from frame 6 on; id 2 (0..4) takes id 1 where 1 is gone
    r = store.apply({"op": "swap", "ids": [1, 5], "start": 6, "end": 9})
    assert r.frames == [6, 7, 8, 9]
    assert people(store, 5)[1] == pytest.approx(track_xy(1, 5))
    assert people(store, 6)[5] == pytest.approx(track_xy(1, 6))
    assert people(store, 6)[1] == pytest.approx(track_xy(5, 6))
    assert store.changed_by(7)[1]["how"] == "identity"
    r = store.apply({"op": "swap", "ids": [2, 5], "start": 0, "end": 2})  # only id 2 there: it becomes 5
    assert r.frames == [0, 1, 2]
    assert ids(store, 1) == [1, 5]
    store.undo()
    store.undo()
    assert people(store, 6) == {1: pytest.approx(track_xy(1, 6)), 5: pytest.approx(track_xy(5, 6))}
    assert ids(store, 1) == [1, 2]


def test_split(store: AnnotationStore) -> None:
    r = store.apply({"op": "split", "id": 1, "frame": 6, "new_id": 9})
    assert r.op["end"] is None
    assert r.frames == [6, 7, 8, 9]
    assert ids(store, 5) == [1, 5]
    assert ids(store, 9) == [5, 9]
    r = store.apply({"op": "split", "id": 5, "frame": 4, "end": 5, "new_id": None})
    assert r.op["new_id"] == 0
    assert r.frames == [4, 5]
    assert ids(store, 6) == [5, 9]


def test_flag(store: AnnotationStore) -> None:
    store.apply({"op": "flag", "frame": 3, "id": 2, "occluded": True})
    p = store.frame(3).people[1]
    assert p.extra == {"occluded": True}
    store.apply({"op": "flag", "frame": 3, "id": 2, "uncertain": True, "occluded": None})
    assert store.frame(3).people[1].extra == {"occluded": True, "uncertain": True}
    store.apply({"op": "flag", "frame": 3, "id": 2, "occluded": False})
    assert store.frame(3).people[1].extra == {"uncertain": True}


def test_review(store: AnnotationStore) -> None:
    r = store.apply({"op": "review", "start": 2, "end": 4})
    assert r.frames == [2, 3, 4]
    assert store.reviewed() == {2, 3, 4}
    assert store.frame(3).extra == {"reviewed": True}
    r = store.apply({"op": "review", "start": 3, "end": 9, "reviewed": False})
    assert r.frames == [3, 4]
    assert store.reviewed() == {2}


X = {"x": 1.0, "y": 2.0}
ERRORS: list[tuple[dict[str, Any], str]] = [
    ({"op": "jump", "frame": 1}, "unknown op"),
    ({"frame": 1}, "unknown op"),
    ({"op": "add", "frame": 1, "id": 3, "x": 1.0}, "missing key"),
    ({"op": "add", "frame": 1, "id": 3, **X, "z": 0.0}, "unknown key"),
    ({"op": "add", "frame": 99, "id": 3, **X}, "unknown frame 99"),
    ({"op": "add", "frame": -1, "id": 3, **X}, "non-negative"),
    ({"op": "add", "frame": 1, "id": -3, **X}, "non-negative"),
    ({"op": "add", "frame": 1, "id": True, **X}, "integer"),
    ({"op": "add", "frame": 1, "id": 3.0, **X}, "integer"),
    ({"op": "add", "frame": 1.0, "id": 3, **X}, "integer"),
    ({"op": "add", "frame": "1", "id": 3, **X}, "integer"),
    ({"op": "add", "frame": 1, "id": 3, "x": math.nan, "y": 0.0}, "finite"),
    ({"op": "add", "frame": 1, "id": 3, "x": 0.0, "y": math.inf}, "finite"),
    ({"op": "add", "frame": 1, "id": 3, "x": "1", "y": 0.0}, "number"),
    ({"op": "add", "frame": 1, "id": 3, "x": True, "y": 0.0}, "number"),
    ({"op": "add", "frame": 1, "id": 1, **X}, "already exists"),
    ({"op": "move", "frame": 1, "id": 5, **X}, "no person id 5"),
    ({"op": "move", "frame": 1, "id": 1, **X, "propagate": 1}, "propagate"),
    ({"op": "delete", "frame": 9, "id": 2}, "no person id 2"),
    ({"op": "set_id", "id": 1, "new_id": 2, "start": 0, "end": 9}, "already in frame 0"),
    ({"op": "set_id", "id": 1, "new_id": 5, "start": 2, "end": 9}, "already in frame 3"),
    ({"op": "set_id", "id": 1, "new_id": 1, "start": 0, "end": 9}, "equals"),
    ({"op": "set_id", "id": 4, "new_id": 7, "start": 0, "end": 9}, "no id 4"),
    ({"op": "set_id", "id": 2, "new_id": 7, "start": 5, "end": 9}, "no id 2 in frames 5..9"),
    ({"op": "set_id", "id": 1, "new_id": 7, "start": 5, "end": 2}, "before"),
    ({"op": "set_id", "id": 1, "new_id": 7, "start": 0, "end": 10}, "unknown end 10"),
    ({"op": "merge", "ids": [1, 2], "into": 1, "start": 0, "end": 9}, "frame 0"),
    ({"op": "merge", "ids": [2, 5], "into": 9, "start": 0, "end": 9}, "frame 3"),
    ({"op": "merge", "ids": [1], "into": 9, "start": 0, "end": 9}, "at least two"),
    ({"op": "merge", "ids": [1, 1], "into": 9, "start": 0, "end": 9}, "duplicates"),
    ({"op": "merge", "ids": "12", "into": 9, "start": 0, "end": 9}, "list"),
    ({"op": "swap", "ids": [1, 1], "start": 0, "end": 9}, "same id twice"),
    ({"op": "swap", "ids": [1, 2, 5], "start": 0, "end": 9}, "two ids"),
    ({"op": "swap", "ids": 1, "start": 0, "end": 9}, "two ids"),
    ({"op": "swap", "ids": [2, 7], "start": 5, "end": 9}, "no id 2 or 7 in frames 5..9"),
    ({"op": "swap", "ids": [1, 5], "start": 0, "end": 10}, "unknown end 10"),
    ({"op": "split", "id": 2, "frame": 6, "new_id": 7}, "no id 2 in frames 6..9"),
    ({"op": "split", "id": 1, "frame": 5, "end": 2, "new_id": 9}, "end 2 comes before frame 5"),
    ({"op": "split", "id": 1, "frame": 5, "end": 12, "new_id": 9}, "unknown end 12"),
    ({"op": "split", "id": 1, "frame": 3, "new_id": 5}, "already in frame 3"),
    ({"op": "flag", "frame": 1, "id": 1}, "occluded"),
    ({"op": "flag", "frame": 1, "id": 1, "occluded": "yes"}, "true, false or null"),
    ({"op": "flag", "frame": 1, "id": 7, "occluded": True}, "no person id 7"),
    ({"op": "review", "start": 0, "end": 3, "reviewed": None}, "reviewed"),
    ({"op": "review", "start": 0}, "missing key"),
    ({"op": "undo"}, "undo()"),
]


@pytest.mark.parametrize(("op", "message"), ERRORS, ids=[f"{o.get('op')}-{m}" for o, m in ERRORS])
def test_invalid_ops_leave_state_untouched(run_dir: Path, op: dict[str, Any], message: str) -> None:
    log = run_dir / "annotations" / "corrections.jsonl"
    with AnnotationStore.open(run_dir) as s:
        before = (s.frames(), log.read_bytes(), (run_dir / "ground_truth.jsonl").read_bytes())
        with pytest.raises(AnnotationError, match=message) as info:
            s.apply(op)
        assert isinstance(info.value, StudioError)
        assert s.rev == 0
        assert (s.frames(), log.read_bytes(), (run_dir / "ground_truth.jsonl").read_bytes()) == before
        assert s.history() == []


def test_non_dict_op(store: AnnotationStore) -> None:
    with pytest.raises(AnnotationError, match="JSON object"):
        store.apply([1, 2])  # type: ignore[arg-type]


def test_unknown_frame_queries(store: AnnotationStore) -> None:
    for fn in (store.frame, store.frame_rev, store.changed_by):
        with pytest.raises(AnnotationError, match="unknown frame"):
            fn(10)
    with pytest.raises(AnnotationError, match="unknown frame"):
        store.history(frame=-1)


def test_propagation_stops_at_manual_people_of_a_ground_truth_base(run_dir: Path, tmp_path: Path) -> None:
    from studio.labels import LabelFrame, LabelPerson, write_labels_jsonl

    frames = [
        LabelFrame(
            frame=n, people=(LabelPerson(id=1, x=float(n), y=0.0, source="manual" if n == 5 else "gt"),)
        )
        for n in range(10)
    ]
    write_labels_jsonl(tmp_path / "gt.jsonl", frames)
    with AnnotationStore.open(run_dir, base=tmp_path / "gt.jsonl") as s:
        r = s.apply({"op": "move", "frame": 2, "id": 1, "x": 2.5, "y": 0.0, "propagate": True})
        assert r.frames == [2, 3, 4]
        assert people(s, 4)[1] == (4.5, 0.0)
        assert people(s, 5)[1] == (5.0, 0.0)
