"""A folder of ROS1 bags is one recording: split recordings (``rosbag record --split``) and one bag per
sensor, merged in log-time order; a bad bag among them is named."""

from __future__ import annotations

from pathlib import Path

import pytest
from io_testdata import bag, split_bag

from studio.io import RecordingError, open_recording


def _records(path: Path) -> tuple[dict[str, tuple[str, int]], list[tuple[int, str, bytes]]]:
    with open_recording(path) as rec:
        topics = {t: (i.msgtype, i.count) for t, i in rec.topics.items()}
        return topics, [(r.log_ns, r.topic, r.rawdata) for r in rec.messages()]


@pytest.mark.parametrize("part_of", ["time", "topic and time"])
def test_a_folder_of_bags_reads_as_the_bag_they_were_split_from(tmp_path: Path, part_of: str) -> None:
    src = bag("legs_labelled/positive_1_extracted.bag")  # three topics
    split_bag(src, tmp_path / "rec", part_of)
    topics, records = _records(src)
    with open_recording(tmp_path / "rec") as rec:
        assert rec.kind == "ros1"
        assert [f.name for f in rec.files] == ["rec_0.bag", "rec_1.bag", "rec_2.bag"]
        with open_recording(src) as whole:
            assert (rec.start_ns, rec.end_ns) == (whole.start_ns, whole.end_ns)
    got_topics, got = _records(tmp_path / "rec")
    assert got_topics == topics
    assert [t for t, *_ in got] == sorted(t for t, *_ in got)  # merged in log-time order
    assert sorted(got) == sorted(records)


def test_unrelated_bags_in_one_folder_are_noted(tmp_path: Path) -> None:
    """Two bags recorded 104 days apart were merged into one recording without a word."""
    import shutil

    folder = tmp_path / "mixed"
    folder.mkdir()
    for name in ("demo_stationary_simple_environment.bag", "negative_2.bag"):
        shutil.copy(bag(name), folder / name)
    with open_recording(folder) as rec:
        assert rec.notes == [
            "demo_stationary_simple_environment.bag begins 104.0 days after negative_2.bag ends: the "
            "folder's bags are read as one recording; are they one?"
        ]
    split_bag(bag("demo_stationary_simple_environment.bag"), tmp_path / "rec", parts=3)
    with open_recording(tmp_path / "rec") as rec:
        assert rec.notes == []  # the pieces of a split recording follow each other


def test_the_bags_of_a_folder_go_in_name_order_with_numbers_as_numbers(tmp_path: Path) -> None:
    parts = split_bag(bag("demo_stationary_simple_environment.bag"), tmp_path / "rec", parts=3)
    for p, name in zip(parts, ["run_2.bag", "run_10.bag", "run_1.bag"], strict=True):
        p.rename(p.parent / name)
    (tmp_path / "rec" / "notes.txt").write_text("not a bag")
    with open_recording(tmp_path / "rec") as rec:
        assert [f.name for f in rec.files] == ["run_1.bag", "run_2.bag", "run_10.bag"]
        assert rec.topics["/scan"].count == 1265


def test_a_truncated_bag_in_a_folder_is_read_as_far_as_it_goes_and_named(tmp_path: Path) -> None:
    parts = split_bag(bag("demo_stationary_simple_environment.bag"), tmp_path / "rec")
    with open_recording(tmp_path / "rec") as rec:
        whole = [(m.topic, m.log_ns) for m in rec.messages()]
    data = parts[1].read_bytes()
    parts[1].write_bytes(data[: len(data) // 2])
    with open_recording(tmp_path / "rec") as rec:
        got = [(m.topic, m.log_ns) for m in rec.messages()]
        assert len(rec.notes) == 1
        assert rec.notes[0].startswith(f"{parts[1]}: a ROS1 bag without its index")
    assert set(got) < set(whole)
    assert got == sorted(got, key=lambda m: m[1])


def test_a_bag_of_a_folder_with_no_whole_message_is_named_and_the_others_are_read(tmp_path: Path) -> None:
    parts = split_bag(bag("demo_stationary_simple_environment.bag"), tmp_path / "rec")
    with open_recording(parts[0]) as first, open_recording(parts[2]) as last:
        expected = sum(1 for _ in first.messages()) + sum(1 for _ in last.messages())
    data = parts[1].read_bytes()
    parts[1].write_bytes(data[:4200] + bytes(range(256)) * 20)  # its header, then no record
    with open_recording(tmp_path / "rec") as rec:
        assert sum(1 for _ in rec.messages()) == expected
        assert len(rec.notes) == 1
        assert rec.notes[0].startswith(f"{parts[1]}: a ROS1 bag without its index")
        assert rec.notes[0].endswith(": 0 whole messages read from its chunks")


def test_a_folder_without_bags_is_one_clear_error(tmp_path: Path) -> None:
    empty = tmp_path / "empty"
    empty.mkdir()
    (empty / "notes.txt").write_text("no bags here")
    with pytest.raises(RecordingError, match=r"must be a ROS2 bag .* or hold ROS1 \.bag files"):
        open_recording(empty)


def test_a_bag_named_active_is_one_of_the_folder(tmp_path: Path) -> None:
    """``.bag.active`` is the name of a bag ``rosbag record`` had not closed: one of the recording (its
    reading without an index: ``tests/io/test_io_unindexed_bags.py``)."""
    rec = tmp_path / "rec"
    parts = split_bag(bag("demo_stationary_simple_environment.bag"), rec, parts=2)
    with open_recording(rec) as whole:
        expected = [(m.topic, m.log_ns, m.rawdata) for m in whole.messages()]
    parts[1].rename(rec / "rec_1.bag.active")
    with open_recording(rec) as r:
        assert r.files == (rec / "rec_0.bag", rec / "rec_1.bag.active")
        assert [(m.topic, m.log_ns, m.rawdata) for m in r.messages()] == expected


def test_a_split_real_recording_labels_as_the_whole(tmp_path: Path) -> None:
    """The first 40 s of demo_stationary as one bag, and as three split by time: the same labels."""
    from studio.io import parse_rig
    from studio.pipeline import LabelOptions
    from studio.pipeline.label import label_recording

    src = bag("demo_stationary_simple_environment.bag")
    (whole,) = split_bag(src, tmp_path / "whole", parts=1, seconds=40.0)
    split_bag(src, tmp_path / "split", parts=3, seconds=40.0)
    rig = parse_rig({"base_frame": "laser", "lasers": [{"topic": "/scan"}]})
    labels = []
    for path in (whole, tmp_path / "split"):
        run = label_recording(path, rig, options=LabelOptions(sources="laser"))
        labels.append([(f.stamp_ns, sorted((p.id, p.x, p.y) for p in f.people)) for f in run.labels])
    assert len(labels[0]) > 350  # 10 Hz
    assert sum(len(people) for _, people in labels[0]) > 100
    assert labels[1] == labels[0]
