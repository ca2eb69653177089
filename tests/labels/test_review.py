"""Review points: the moments of a run's labels where identities are worth checking."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from studio.labels import (
    LabelError,
    LabelFrame,
    LabelPerson,
    ReviewConfig,
    read_review,
    review_points,
    write_review,
)

T0 = 1_700_000_000_000_000_000
DT = 100_000_000  # 10 Hz


def frames_of(
    tracks: dict[int, dict[int, tuple[float, float] | tuple[float, float, bool]]], n: int
) -> list[LabelFrame]:
    """``n`` frames at 10 Hz; ``tracks[id][frame] = (x, y)`` or ``(x, y, interpolated)``."""
    out = []
    for k in range(n):
        people = []
        for tid, where in tracks.items():
            if k in where:
                x, y, *rest = where[k]
                extra = {"interpolated": True} if rest and rest[0] else {}
                people.append(LabelPerson(tid, x, y, extra=extra))
        out.append(LabelFrame(k, tuple(people), T0 + k * DT))
    return out


def walk(x0: float, vx: float, frames: range, y: float = 0.0) -> dict[int, tuple[float, float]]:
    return {k: (x0 + vx * 0.1 * k, y) for k in frames}


def test_two_tracks_that_met_give_one_point_where_they_part() -> None:
    # two people walking towards each other along y = ±0.15 m: closer than 0.5 m for frames 18..22
    a = walk(0.0, 1.0, range(40), y=0.15)
    b = walk(4.0, -1.0, range(40), y=-0.15)
    close = [k for k in range(40) if ((a[k][0] - b[k][0]) ** 2 + 0.3**2) ** 0.5 < 0.5]
    points = review_points(frames_of({1: a, 2: b}, 40))
    assert [(p.frame, p.ids, p.kind) for p in points] == [(close[-1], (1, 2), "encounter")]
    assert "tracks 1 and 2 came within 0.30 m" in points[0].note
    # farther apart than encounter_m: nothing to check
    far = walk(4.0, -1.0, range(40), y=-0.5)
    assert review_points(frames_of({1: a, 2: far}, 40)) == []


def test_a_track_seen_again_after_a_gap_is_a_point() -> None:
    # observed 0-9, interpolated 10-24, observed again from 25 (1.6 s after its last observation)
    t = dict.fromkeys(range(10), (1.0, 2.0))
    t |= dict.fromkeys(range(10, 25), (1.0, 2.0, True))
    t |= dict.fromkeys(range(25, 40), (1.0, 2.0))
    # a second track absent (not even interpolated) for frames 10-29
    u = dict.fromkeys([*range(10), *range(30, 40)], (5.0, -2.0))
    points = review_points(frames_of({1: t, 2: u}, 40))
    assert [(p.frame, p.ids, p.kind) for p in points] == [(25, (1,), "gap"), (30, (2,), "gap")]
    assert "seen again after 1.6 s" in points[0].note
    # a short gap (0.5 s) is no point
    short = dict.fromkeys([*range(10), *range(15, 40)], (1.0, 2.0))
    assert review_points(frames_of({1: short}, 40)) == []


def test_a_track_that_begins_inside_the_run_is_a_point() -> None:
    early = dict.fromkeys(range(5, 40), (1.0, 0.0))  # begins 0.5 s in: there from the start, in effect
    late = dict.fromkeys(range(30, 40), (3.0, 3.0))  # begins 3 s in
    points = review_points(frames_of({1: early, 2: late}, 40))
    assert [(p.frame, p.ids, p.kind) for p in points] == [(30, (2,), "start")]


def test_one_tracks_points_close_in_time_are_one() -> None:
    # a track begins at frame 30 and is seen again at 41 after an unobserved second
    t = dict.fromkeys([30, *range(41, 60)], (3.0, 3.0))
    kinds = [p.kind for p in review_points(frames_of({1: t}, 60))]
    assert kinds == ["start", "gap"]
    kinds = [p.kind for p in review_points(frames_of({1: t}, 60), ReviewConfig(merge_s=2.0))]
    assert kinds == ["start"]


def test_points_need_stamps_and_sane_options() -> None:
    assert review_points([]) == []
    with pytest.raises(ValueError, match="stamped"):
        review_points([LabelFrame(0, (LabelPerson(1, 0.0, 0.0),))])
    with pytest.raises(ValueError, match="positive"):
        ReviewConfig(gap_s=0.0)


def test_review_file_round_trip_and_bad_lines(tmp_path: Path) -> None:
    a = walk(0.0, 1.0, range(40), y=0.1)
    b = walk(4.0, -1.0, range(40), y=-0.1)
    points = review_points(frames_of({1: a, 2: b, 3: dict.fromkeys(range(20, 40), (0.0, 5.0))}, 40))
    assert len(points) == 2
    path = tmp_path / "review.jsonl"
    write_review(path, points)
    assert read_review(path) == points
    assert read_review(tmp_path / "none.jsonl") == []  # a run made before review.jsonl existed
    # a file from before session 71: no doubt, read as 0.5
    old = {k: v for k, v in points[0].to_json().items() if k != "doubt"}
    path.write_text(json.dumps(old) + "\n")
    assert read_review(path)[0].doubt == 0.5
    path.write_text(json.dumps(points[0].to_json() | {"doubt": 1.5}) + "\n")
    with pytest.raises(LabelError, match=r"review.jsonl:1: not a review point \(doubt 1.5 not in \[0, 1\]\)"):
        read_review(path)
    write_review(path, points)
    path.write_text(path.read_text() + '{"frame": 3, "ids": "x"}\n')
    with pytest.raises(LabelError, match=r"review.jsonl:3: not a review point"):
        read_review(path)


def test_doubt_ranks_the_likelier_errors_first() -> None:
    """Far encounters over near ones, long jumps over standing still, a start where a track ended."""
    near = review_points(
        frames_of({1: walk(0.0, 1.0, range(40), 0.1), 2: walk(4.0, -1.0, range(40), -0.1)}, 40)
    )
    far = review_points(
        frames_of({1: walk(6.0, 1.0, range(40), 0.1), 2: walk(10.0, -1.0, range(40), -0.1)}, 40)
    )
    assert near[0].doubt < far[0].doubt == 0.6  # 8 m or more from the robot: the most an encounter gets
    # a gap: standing still, or 2 m further on after 1.5 s
    still = dict.fromkeys(range(10), (1.0, 2.0)) | dict.fromkeys(range(25, 40), (1.0, 2.0))
    moved = dict.fromkeys(range(10), (1.0, 2.0)) | dict.fromkeys(range(25, 40), (3.0, 2.0))
    (a,) = review_points(frames_of({1: still}, 40))
    (b,) = review_points(frames_of({1: moved}, 40))
    assert (a.kind, b.kind) == ("gap", "gap")
    assert a.doubt == pytest.approx(0.1 * 1.5 / 20, abs=0.005)  # hundredths
    assert b.doubt == pytest.approx(0.3 + 0.1 * 1.5 / 20, abs=0.005)
    # a track beginning 2 m from where another was last observed 1 s before; one beginning far from any
    ended = dict.fromkeys(range(10), (1.0, 2.0))
    (start,) = review_points(frames_of({1: ended, 2: dict.fromkeys(range(20, 40), (1.0, 4.0))}, 40))
    (alone,) = review_points(frames_of({1: ended, 2: dict.fromkeys(range(20, 40), (1.0, 8.0))}, 40))
    assert (start.kind, start.doubt, alone.doubt) == ("start", 0.4, 0.2)
