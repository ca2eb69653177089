"""Files of the store: materialised ground truth (fed to the evaluator), bases, log header checks, the run
lock, torn and corrupt log lines, stale materialised files."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from collections.abc import Callable
from pathlib import Path

import pytest

from studio.annotate import AnnotationError, AnnotationStore
from studio.evaluate import evaluate
from studio.labels import LabelFrame, LabelPerson, read_labels, read_labels_jsonl, write_labels_yaml

LOG = "annotations/corrections.jsonl"


def test_materialised_files_follow_every_op(run_dir: Path) -> None:
    labels_bytes = (run_dir / "labels.jsonl").read_bytes()
    with AnnotationStore.open(run_dir) as s:
        gt_jsonl, gt_yaml = run_dir / "ground_truth.jsonl", run_dir / "ground_truth.yaml"
        assert read_labels(gt_jsonl).frames == read_labels_jsonl(run_dir / "labels.jsonl").frames
        s.apply({"op": "add", "frame": 2, "id": 9, "x": -1.0, "y": 2.0})
        s.apply({"op": "review", "start": 0, "end": 1})
        s.apply({"op": "flag", "frame": 2, "id": 9, "uncertain": True})
        on_disk = read_labels(gt_jsonl).frames
        assert on_disk == tuple(s.frames())
        assert [f.frame for f in on_disk] == list(range(10))
        assert on_disk[0].extra == {"reviewed": True}
        assert on_disk[0].stamp_ns == 1_700_000_000_000_000_000
        assert on_disk[2].robot_pose is not None
        p9 = on_disk[2].people[-1]
        assert (p9.id, p9.source, p9.extra) == (9, "manual", {"uncertain": True})
        yaml_frames = read_labels(gt_yaml).frames
        assert [(p.id, p.x, p.y) for p in yaml_frames[2].people] == [
            (p.id, round(p.x, 3), round(p.y, 3)) for p in s.frame(2).people
        ]
        assert not [p for p in run_dir.iterdir() if p.name.endswith(".tmp")]
    assert (run_dir / "labels.jsonl").read_bytes() == labels_bytes  # auto-labels never modified


def test_evaluator_numbers_move_as_the_edits_imply(run_dir: Path) -> None:
    pred = run_dir / "labels.jsonl"
    gt = run_dir / "ground_truth.jsonl"

    def counts() -> tuple[int, int, int]:
        m = evaluate(pred, gt).metrics()
        return m["tp"], m["fp"], m["fn"]

    with AnnotationStore.open(run_dir) as s:
        assert counts() == (22, 0, 0)  # id 1: 10 frames, id 2: 5, id 5: 7
        s.apply({"op": "delete", "frame": 3, "id": 2})  # a correct person removed from GT → 1 FP
        assert counts() == (21, 1, 0)
        p = s.frame(5).people[0]
        s.apply({"op": "move", "frame": 5, "id": 1, "x": p.x + 1.0, "y": p.y})  # 1 m away → FP + FN
        assert counts() == (20, 2, 1)
        s.apply({"op": "add", "frame": 0, "id": 9, "x": -4.0, "y": -4.0})  # a person auto-labels missed
        assert counts() == (20, 2, 2)
        p = s.frame(6).people[1]
        s.apply({"op": "move", "frame": 6, "id": 5, "x": p.x + 0.1, "y": p.y})  # within 0.2 m: still TP
        assert counts() == (20, 2, 2)
        assert evaluate(pred, gt).metrics()["num_gt_tracks"] == 4
        s.apply({"op": "set_id", "id": 1, "new_id": 7, "start": 6, "end": 9})  # one more GT track
        m = evaluate(pred, gt).metrics()
        assert m["num_gt_tracks"] == 5
        assert m["idf1"] < 1.0
        s.undo()  # set_id
        s.undo()  # small move
        s.undo()  # add
        assert counts() == (20, 2, 1)
        s.undo()  # big move
        assert counts() == (21, 1, 0)
        assert evaluate(pred, gt).frame_matching == "stamp"


def test_empty_base(run_dir: Path) -> None:
    with AnnotationStore.open(run_dir, base="empty") as s:
        assert all(not f.people for f in s.frames())
        assert s.frame(4).stamp_ns == 1_700_000_000_400_000_000
        s.apply({"op": "add", "frame": 4, "id": 0, "x": 1.0, "y": 1.0})
    with AnnotationStore.open(run_dir) as s:  # the header remembers the base
        assert s.header["base"]["kind"] == "empty"
        assert [p.id for p in s.frame(4).people] == [0]
    with pytest.raises(AnnotationError, match="starts from base 'empty'"):
        AnnotationStore.open(run_dir, base="auto")


def test_file_base_yaml_gets_stamps_and_missing_frames(run_dir: Path, tmp_path: Path) -> None:
    gt_file = tmp_path / "gt.yaml"
    write_labels_yaml(gt_file, [LabelFrame(frame=1, people=(LabelPerson(id=4, x=1.0, y=2.0),))])
    with AnnotationStore.open(run_dir, base=gt_file) as s:
        assert s.num_frames == 10
        assert [p.id for p in s.frame(1).people] == [4]
        assert s.frame(0).people == ()
        assert s.frame(1).stamp_ns == 1_700_000_000_100_000_000
        assert s.frame(1).robot_pose is not None
        s.apply({"op": "move", "frame": 1, "id": 4, "x": 1.5, "y": 2.0})
    with AnnotationStore.open(run_dir, base=gt_file) as s:  # same base given again: fine
        assert s.frame(1).people[0].x == 1.5
    gt_file.write_text(gt_file.read_text() + "frame 2: []\n")
    with pytest.raises(AnnotationError, match="changed since"):
        AnnotationStore.open(run_dir)
    gt_file.unlink()
    with pytest.raises(AnnotationError, match="missing"):
        AnnotationStore.open(run_dir)


def test_own_ground_truth_as_base_is_copied(run_dir: Path) -> None:
    with AnnotationStore.open(run_dir) as s:
        s.apply({"op": "delete", "frame": 0, "id": 1})
    (run_dir / "annotations" / "corrections.jsonl").rename(run_dir / "old.jsonl")
    with AnnotationStore.open(run_dir, base=run_dir / "ground_truth.jsonl") as s:
        assert s.header["base"]["path"] == "annotations/base.jsonl"
        assert [p.id for p in s.frame(0).people] == [2]
        s.apply({"op": "delete", "frame": 0, "id": 2})
    with AnnotationStore.open(run_dir) as s:  # ground_truth.jsonl was rewritten: the base copy was not
        assert s.frame(0).people == ()
        assert s.rev == 1


@pytest.mark.parametrize(
    ("base", "message"),
    [("nothing.yaml", "no such file"), ("bad.yaml", "not valid YAML"), ("bad.txt", "unknown label format")],
)
def test_bad_base_files(run_dir: Path, base: str, message: str) -> None:
    (run_dir / "bad.yaml").write_text("frame 0: [\n")
    (run_dir / "bad.txt").write_text("")
    with pytest.raises(Exception, match=message) as info:
        AnnotationStore.open(run_dir, base=run_dir / base)
    assert "StudioError" in [c.__name__ for c in type(info.value).__mro__]
    assert not (run_dir / LOG).exists()


def test_not_a_run_and_changed_labels(tmp_path: Path, run_dir: Path, make_run: Callable[..., Path]) -> None:
    with pytest.raises(AnnotationError, match=r"no labels\.jsonl"):
        AnnotationStore.open(tmp_path / "nowhere")
    AnnotationStore.open(run_dir).close()
    make_run(run_dir, num_frames=12)
    with pytest.raises(AnnotationError, match=r"labels.jsonl changed"):
        AnnotationStore.open(run_dir)


def test_second_open_is_refused_until_close(run_dir: Path) -> None:
    s = AnnotationStore.open(run_dir)
    with pytest.raises(AnnotationError, match=f"already open by pid {os.getpid()}"):
        AnnotationStore.open(run_dir)
    code = (
        "import sys; from studio.annotate import AnnotationStore as S\n"
        "try:\n S.open(sys.argv[1])\nexcept Exception as e:\n print(e)"
    )
    out = subprocess.run(
        [sys.executable, "-c", code, str(run_dir)], capture_output=True, text=True, check=True
    )
    assert f"already open by pid {os.getpid()}" in out.stdout
    s.close()
    s.close()  # idempotent
    with pytest.raises(AnnotationError, match="closed"):
        s.apply({"op": "delete", "frame": 0, "id": 1})
    AnnotationStore.open(run_dir).close()


def test_torn_last_line_is_dropped(run_dir: Path) -> None:
    with AnnotationStore.open(run_dir) as s:
        s.apply({"op": "delete", "frame": 0, "id": 1})
        s.apply({"op": "delete", "frame": 1, "id": 1})
        state = s.frames()
        line = json.dumps({"seq": 3, "op": {"op": "delete", "frame": 2, "id": 1}})
    log = run_dir / LOG
    good = log.read_bytes()
    for torn in (line[:17], line[:-1], line + "}\n"[:1]):  # no newline: never acknowledged
        log.write_bytes(good + torn.encode())
        with AnnotationStore.open(run_dir) as s:
            assert s.rev == 2
            assert s.frames() == state
        assert log.read_bytes() == good  # cut back to the last whole line
    log.write_bytes(good + b'{"seq": 3, "op": {"op": "dele\n')  # newline but garbled: torn as well
    with AnnotationStore.open(run_dir) as s:
        assert s.rev == 2
        r = s.apply({"op": "delete", "frame": 2, "id": 1})
        assert r.rev == 3
    with AnnotationStore.open(run_dir) as s:
        assert s.rev == 3


def test_corrupt_log_is_an_error(run_dir: Path) -> None:
    with AnnotationStore.open(run_dir) as s:
        s.apply({"op": "delete", "frame": 0, "id": 1})
        s.apply({"op": "delete", "frame": 1, "id": 1})
    log = run_dir / LOG
    lines = log.read_text().splitlines(keepends=True)
    log.write_text(lines[0] + "garbage\n" + lines[2])
    with pytest.raises(AnnotationError, match=":2: corrupt"):
        AnnotationStore.open(run_dir)
    bad = json.loads(lines[1])
    bad["op"]["frame"] = 77
    log.write_text(lines[0] + json.dumps(bad) + "\n" + lines[2])
    with pytest.raises(AnnotationError, match="record 1 does not replay: unknown frame 77"):
        AnnotationStore.open(run_dir)
    log.write_text(lines[0] + lines[2])
    with pytest.raises(AnnotationError, match="out of order"):
        AnnotationStore.open(run_dir)
    log.write_text('{"hello": 1}\n')
    with pytest.raises(AnnotationError, match="not a studio corrections log"):
        AnnotationStore.open(run_dir)


def test_stale_or_missing_materialised_files_are_rebuilt(run_dir: Path) -> None:
    with AnnotationStore.open(run_dir) as s:
        s.apply({"op": "delete", "frame": 0, "id": 1})
    want = (run_dir / "ground_truth.jsonl").read_bytes(), (run_dir / "ground_truth.yaml").read_bytes()
    (run_dir / "ground_truth.jsonl").unlink()
    (run_dir / "ground_truth.yaml").write_text("frame 0: []\n")
    AnnotationStore.open(run_dir).close()
    assert (
        (run_dir / "ground_truth.jsonl").read_bytes(),
        (run_dir / "ground_truth.yaml").read_bytes(),
    ) == want


@pytest.mark.parametrize(
    ("line", "message"),
    [
        ('{"frame": 3, "people": [{"id": 1, "x": "far", "y": 0}]}', r"labels.jsonl:4: people\[0\].x"),
        ("not json", "labels.jsonl:4:"),
        ('{"people": []}', "labels.jsonl:4: missing integer 'frame'"),
        ('{"frame": 1, "people": []}', "labels.jsonl:4: duplicate frame 1"),
    ],
)
def test_bad_labels_fail_on_first_open_without_a_log(
    tmp_path: Path, make_run: Callable[..., Path], line: str, message: str
) -> None:
    run = make_run(tmp_path / "run", num_frames=3)
    with (run / "labels.jsonl").open("a") as f:
        f.write(line + "\n")
    with pytest.raises(Exception, match=message) as info:
        AnnotationStore.open(run)
    assert "StudioError" in [c.__name__ for c in type(info.value).__mro__]
    assert not (run / LOG).exists()
    assert not (run / "ground_truth.jsonl").exists()
    if "far" in line:  # an empty base does not use the auto-labels' people
        with AnnotationStore.open(run, base="empty") as s:
            assert s.frame(3).people == ()


def test_failed_log_write_is_cut_off_and_not_applied(run_dir: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    from studio.annotate import log as annotate_log

    real = annotate_log.append_line

    def half_then_fail(fd: int, data: bytes) -> None:
        os.write(fd, data[: len(data) // 2])
        raise OSError(28, "No space left on device")

    with AnnotationStore.open(run_dir) as s:
        s.apply({"op": "delete", "frame": 0, "id": 1})
        before = s.frames()
        monkeypatch.setattr(annotate_log, "append_line", half_then_fail)
        with pytest.raises(AnnotationError, match=r"No space left.*op not applied"):
            s.apply({"op": "delete", "frame": 1, "id": 1})
        assert (s.rev, s.frames()) == (1, before)
        monkeypatch.setattr(annotate_log, "append_line", real)
        s.apply({"op": "delete", "frame": 2, "id": 1})
        state = s.frames()
    with AnnotationStore.open(run_dir) as s:
        assert (s.rev, s.frames()) == (2, state)


def test_failed_rewrite_is_reported_and_repaired(run_dir: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    from studio.annotate import gtfiles

    real = gtfiles.write

    def fail(*args: object, **kwargs: object) -> None:
        raise OSError(28, "No space left on device")

    with AnnotationStore.open(run_dir) as s:
        monkeypatch.setattr(gtfiles, "write", fail)
        with pytest.raises(AnnotationError, match="op 1 is saved"):
            s.apply({"op": "delete", "frame": 0, "id": 1})
        assert s.rev == 1
        monkeypatch.setattr(gtfiles, "write", real)
        s.apply({"op": "delete", "frame": 1, "id": 1})
        assert read_labels(run_dir / "ground_truth.jsonl").frames == tuple(s.frames())
