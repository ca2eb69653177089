"""Label files: thesis YAML and JSONL round trips, and clear errors on bad files."""

from __future__ import annotations

import json

import pytest

from studio.geometry.se import Pose2
from studio.labels import (
    LabelError,
    LabelFrame,
    LabelPerson,
    dumps_yaml,
    read_labels,
    write_labels_jsonl,
    write_labels_yaml,
)


def _frames() -> list[LabelFrame]:
    return [
        LabelFrame(
            frame=0,
            stamp_ns=1_683_731_234_000_000_000,
            robot_pose=Pose2(1.0, 2.0, 0.5),
            people=(
                LabelPerson(
                    id=3,
                    x=2.605,
                    y=0.748,
                    x_odom=3.0,
                    y_odom=4.0,
                    cov=((0.01, 0), (0, 0.02)),
                    source="fused",
                    box=(1900.0, 300.0, 1990.0, 600.0),
                    score=0.9,
                    extra={"visible": {"camera": True}},
                ),
                LabelPerson(id=7, x=-1.0, y=0.0),
            ),
        ),
        LabelFrame(frame=1, stamp_ns=1_683_731_234_100_000_000, people=()),
    ]


def test_yaml_is_the_thesis_format() -> None:
    text = dumps_yaml(_frames())
    assert text == "frame 0:\n- id3: {x: 2.605, y: 0.748}\n- id7: {x: -1.0, y: 0.0}\nframe 1: []\n"


def test_yaml_round_trip(tmp_path) -> None:
    p = tmp_path / "labels.yaml"
    write_labels_yaml(p, _frames())
    back = read_labels(p)
    assert [f.frame for f in back] == [0, 1]
    assert [(q.id, q.x, q.y) for q in back.frames[0].people] == [(3, 2.605, 0.748), (7, -1.0, 0.0)]
    assert back.frames[1].people == ()


def test_jsonl_round_trip_keeps_every_field(tmp_path) -> None:
    p = tmp_path / "labels.jsonl"
    write_labels_jsonl(p, _frames())
    back = read_labels(p)
    f0 = back.frames[0]
    assert f0.stamp_ns == 1_683_731_234_000_000_000
    assert f0.robot_pose == Pose2(1.0, 2.0, 0.5)
    person = f0.people[0]
    assert person == _frames()[0].people[0]
    assert person.extra == {"visible": {"camera": True}}
    first = json.loads(p.read_text().splitlines()[0])
    assert set(first) == {"frame", "stamp_ns", "robot_pose", "people"}
    assert set(first["people"][0]) >= {"id", "x", "y", "x_odom", "y_odom", "cov", "source", "box", "score"}


@pytest.mark.parametrize(
    ("name", "text", "message"),
    [
        ("a.yaml", "frame 0:\n- person: {x: 1, y: 2}\n", "idK"),
        ("a.yaml", "frame 0:\n- id1: {x: 1}\n", "needs x and y"),
        ("a.yaml", "frames: 3\n", "expected 'frame N'"),
        ("a.yaml", "frame 0: [\n", "not valid YAML"),
        ("a.yaml", "frame 0:\n- id1: {x: 1, y: 2}\n- id1: {x: 3, y: 2}\n", "duplicate person ids"),
        ("a.jsonl", '{"frame": 0, "people": [{"id": 1, "x": 1}]}\n', "a.jsonl:1: people[0] has no 'y'"),
        ("a.jsonl", '{"frame": 0}\n{"frame": 1, "people": [}\n', "a.jsonl:2"),
        ("a.jsonl", '{"frame": 0, "stamp_ns": 1.5}\n', "stamp_ns"),
        ("a.jsonl", '{"frame": 0, "people": [{"id": "a", "x": 1, "y": 2}]}\n', "id must be an integer"),
        ("a.jsonl", '{"frame": 0, "people": [{"id": 1, "x": NaN, "y": 2}]}\n', "finite"),
        ("a.txt", "", "unknown label format"),
    ],
)
def test_bad_files_give_one_clear_error(tmp_path, name: str, text: str, message: str) -> None:
    p = tmp_path / name
    p.write_text(text)
    with pytest.raises(LabelError, match=message.replace("[", r"\[").replace("(", r"\(")):
        read_labels(p)


def test_missing_file(tmp_path) -> None:
    with pytest.raises(LabelError, match="no such file"):
        read_labels(tmp_path / "nope.jsonl")


def test_a_frame_listed_twice_in_yaml_is_refused(tmp_path) -> None:
    """The later entry once won silently: a hand-edited ground truth lost a frame's people."""
    p = tmp_path / "gt.yaml"
    p.write_text("frame 0:\n  - id1: {x: 1.0, y: 2.0}\nframe 0:\n  - id2: {x: 3e-1, y: 2.0}\n")
    with pytest.raises(LabelError, match=r"the key 'frame 0' is given twice \(line 3, column 1\)"):
        read_labels(p)
    p.write_text("frame 0:\n  - id1: {x: 1.0, y: 2.0}\nframe 1:\n  - id2: {x: 3e-1, y: 2.0}\n")
    assert read_labels(p).frames[1].people[0].x == pytest.approx(0.3)  # an exponent is a number
