"""Frame alignment (stamps vs indices), splits and several sequences."""

from __future__ import annotations

import pytest
from evalfixtures import frame, random_sequence

from studio.evaluate import (
    FrameAlignmentError,
    align_frames,
    evaluate,
    evaluate_sequences,
    robot_motion,
)
from studio.geometry.se import Pose2
from studio.labels import LabelError, LabelSet, write_labels

T0 = 1_683_731_234_000_000_000
DT = 100_000_000  # 10 Hz


def _gt(n: int = 5, *, stamps: bool = True) -> LabelSet:
    return LabelSet.from_frames(
        [frame(k, {1: (1.0, 0.0)}, stamp_ns=T0 + k * DT if stamps else None) for k in range(n)]
    )


def test_stamps_take_precedence_over_indices() -> None:
    # predicted frame indices are shifted by 100, stamps are 2 ms late: aligned by stamp
    pred = LabelSet.from_frames(
        [frame(k + 100, {5: (1.0, 0.0)}, stamp_ns=T0 + k * DT + 2_000_000) for k in range(5)]
    )
    al = align_frames(pred, _gt())
    assert al.mode == "stamp"
    assert al.num_matched == 5
    assert [p.frame for _, p in al.pairs] == [100, 101, 102, 103, 104]  # type: ignore[union-attr]
    ev = evaluate(pred, _gt())
    assert ev.frame_matching == "stamp"
    assert ev.detection.tp == 5


def test_exact_stamp_wins_over_a_nearer_neighbour_claim() -> None:
    gt = LabelSet.from_frames([frame(0, {}, stamp_ns=T0), frame(1, {}, stamp_ns=T0 + 4_000_000)])
    pred = LabelSet.from_frames(
        [frame(7, {}, stamp_ns=T0 + 4_000_000), frame(8, {}, stamp_ns=T0 + 9_000_000)]
    )
    al = align_frames(pred, gt)
    # frame 1 has an exact twin (7); frame 0 takes the nearest remaining within 10 ms (8, 9 ms away)
    assert [p.frame for _, p in al.pairs] == [8, 7]  # type: ignore[union-attr]


def test_stamp_tolerance() -> None:
    pred = LabelSet.from_frames(
        [frame(k, {5: (1.0, 0.0)}, stamp_ns=T0 + k * DT + 20_000_000) for k in range(5)]
    )
    with pytest.raises(FrameAlignmentError, match="share no frame"):
        align_frames(pred, _gt())
    al = align_frames(pred, _gt(), stamp_tolerance_ns=25_000_000)
    assert al.num_matched == 5


def test_index_alignment_when_a_side_has_no_stamps() -> None:
    pred = LabelSet.from_frames([frame(k, {5: (1.0, 0.0)}) for k in range(2, 5)])
    al = align_frames(pred, _gt())
    assert al.mode == "index"
    assert [p is None for _, p in al.pairs] == [True, True, False, False, False]
    ev = evaluate(pred, _gt())
    # GT frames 0, 1 have no prediction: their people are misses
    assert (ev.detection.tp, ev.detection.fn) == (3, 2)
    assert [f.pred_frame for f in ev.frames] == [None, None, 2, 3, 4]


def test_prediction_frames_without_ground_truth_are_ignored() -> None:
    gt = LabelSet.from_frames([frame(k, {1: (1.0, 0.0)}) for k in (3, 4)])
    pred = LabelSet.from_frames([frame(k, {5: (1.0, 0.0)}) for k in range(10)])
    ev = evaluate(pred, gt)
    assert ev.detection.fp == 0
    assert ev.clear.num_frames == 2
    assert ev.num_pred_frames_unmatched == 8


def test_no_shared_frame_is_a_label_error() -> None:
    pred = LabelSet.from_frames([frame(k, {5: (1.0, 0.0)}) for k in range(10, 12)])
    with pytest.raises(LabelError, match="share no frame"):
        evaluate(pred, _gt(stamps=False))
    with pytest.raises(LabelError, match="no frames"):
        evaluate(pred, LabelSet.from_frames([]))


def test_static_and_moving_split() -> None:
    gt = _gt(6)
    # robot still for frames 0-2, then driving at 0.5 m/s
    xs = [0.0, 0.0, 0.0, 0.05, 0.10, 0.15]
    pred = LabelSet.from_frames(
        [
            frame(
                k, {5: (1.0, 0.0)} if k != 4 else {}, stamp_ns=T0 + k * DT, robot_pose=Pose2(xs[k], 0.0, 0.0)
            )
            for k in range(6)
        ]
    )
    motion = robot_motion(pred)
    assert [motion[k] for k in range(6)] == [False, False, False, True, True, True]
    ev = evaluate(pred, gt)
    assert ev.splits["static"].num_frames == 3
    assert ev.splits["static"].recall == 1.0
    assert ev.splits["moving"].num_frames == 3
    assert ev.splits["moving"].fn == 1
    js = ev.to_json()
    assert js["splits"]["moving"]["tp"] == 2
    # turning on the spot counts as moving
    turning = LabelSet.from_frames(
        [frame(k, {}, stamp_ns=T0 + k * DT, robot_pose=Pose2(0.0, 0.0, 0.05 * k)) for k in range(3)]
    )
    assert set(robot_motion(turning).values()) == {True}
    # no poses → no split
    assert evaluate(LabelSet.from_frames([frame(0, {5: (1.0, 0.0)})]), _gt(stamps=False)).splits == {}


def test_several_sequences_sum_up(tmp_path) -> None:
    seqs = {}
    singles = {}
    for s in (1, 2, 6):
        gts, preds = random_sequence(s)
        p = LabelSet.from_frames([x for x in preds if x is not None])
        write_labels(tmp_path / f"gt{s}.jsonl", gts)
        seqs[f"seq{s}"] = (p, tmp_path / f"gt{s}.jsonl")
        singles[f"seq{s}"] = evaluate(p, tmp_path / f"gt{s}.jsonl")
    ev = evaluate_sequences(seqs)
    assert set(ev.sequences) == set(singles)
    for key in ("tp", "fp", "fn", "id_switches", "num_frames", "num_gt_tracks", "mot_fp", "mot_fn", "frag"):
        assert ev.to_json()[key] == sum(e.to_json()[key] for e in singles.values()), key
    for name, e in singles.items():
        assert ev.sequences[name].to_json() == e.to_json()
    idtp = sum(e.identity.idtp for e in singles.values())
    assert ev.identity.idtp == idtp
    assert {f.sequence for f in ev.frames} == set(seqs)
    assert "seq1" in ev.table()
