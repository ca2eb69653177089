"""Frame alignment (stamps vs indices), splits and several sequences."""

from __future__ import annotations

import numpy as np
import pytest
from evalfixtures import frame, random_sequence

from studio.evaluate import (
    FrameAlignmentError,
    align_frames,
    evaluate,
    evaluate_sequences,
    robot_motion,
)
from studio.evaluate.align import interpolate_frame
from studio.geometry.se import Pose2
from studio.labels import LabelError, LabelFrame, LabelPerson, LabelSet, write_labels

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
        align_frames(pred, _gt(), interpolate_gap_ns=0)
    al = align_frames(pred, _gt(), stamp_tolerance_ns=25_000_000)
    assert (al.num_matched, al.num_interpolated) == (5, 0)
    # 20 ms off, one period apart: frames 1-4 lie between two predicted frames, frame 0 before the first
    al = align_frames(pred, _gt())
    assert (al.num_matched, al.num_interpolated, al.num_pred_unmatched) == (4, 4, 0)
    assert al.pairs[0][1] is None
    # each interpolated frame has the GT stamp and the index of the nearer predicted frame (20 ms vs 80 ms)
    assert [(p.stamp_ns - T0, p.frame) for _, p in al.pairs[1:]] == [(k * DT, k) for k in range(1, 5)]  # type: ignore[union-attr]


def _walker(k: int, t_ns: int, *, turn: float = 1.0, speed: float = 1.2) -> LabelFrame:
    """A predicted frame at ``t_ns``: the robot turns on the spot at ``turn`` rad/s; person 7 stands at
    (5, 0) in the odom frame, person 8 walks along y at ``speed`` m/s from (2, -1)."""
    t = (t_ns - T0) / 1e9
    pose = Pose2(0.0, 0.0, turn * t)
    odom = {7: (5.0, 0.0), 8: (2.0, -1.0 + speed * t)}
    inv = pose.inverse()
    people = tuple(
        LabelPerson(i, *(float(v) for v in inv.apply(np.array(xy))), x_odom=xy[0], y_odom=xy[1])
        for i, xy in odom.items()
    )
    return LabelFrame(k, people, t_ns, pose)


def test_ground_truth_between_two_predicted_frames_is_compared_with_interpolated_predictions() -> None:
    # predictions at 5 Hz, ground truth at 10 Hz on stamps 45 ms off the predictions': before, no frame
    # was shared; now every ground-truth frame between two predicted frames is measured (the last two
    # lie after the last predicted frame)
    pred = LabelSet.from_frames([_walker(k, T0 + k * 2 * DT) for k in range(5)])  # 0 … 0.8 s
    gt = LabelSet.from_frames([_walker(100 + k, T0 + k * DT + 45_000_000) for k in range(10)])
    al = align_frames(pred, gt)
    assert al.mode == "stamp"
    assert (al.num_matched, al.num_interpolated, al.num_pred_unmatched) == (8, 8, 0)
    for g, p in al.pairs[:8]:
        assert p is not None
        assert p.stamp_ns == g.stamp_ns
        # exact for the standing person (odom frame + interpolated robot pose), within a mm for the walker
        np.testing.assert_allclose(p.xy(), g.xy(), atol=1e-3)
        assert p.robot_pose is not None
        assert g.robot_pose is not None
        assert p.robot_pose.yaw == pytest.approx(g.robot_pose.yaw)
    ev = evaluate(pred, gt, radius=0.05)
    assert (ev.detection.tp, ev.detection.fn, ev.detection.fp) == (16, 4, 0)
    assert ev.num_frames_interpolated == 8
    assert ev.to_json()["num_frames_interpolated"] == 8
    assert "8 ground-truth frames lie between two predicted frames" in ev.table()
    assert "2 ground-truth frames have no predicted frame" in ev.table()
    # without the odom frame, base-frame positions are interpolated: on the chord of the turn, 17 mm off
    bare = LabelSet.from_frames(
        [
            LabelFrame(f.frame, tuple(p.with_(x_odom=None, y_odom=None) for p in f.people), f.stamp_ns)
            for f in pred.frames
        ]
    )
    p = align_frames(bare, gt).pairs[0][1]
    assert p is not None
    assert p.robot_pose is None
    err = np.hypot(*(p.xy()[0] - gt.frames[0].xy()[0]))
    assert 0.01 < err < 0.03


def test_a_track_between_two_frames_and_the_largest_gap() -> None:
    a = frame(0, {1: (1.0, 0.0), 2: (3.0, 0.0)}, stamp_ns=T0)
    b = frame(1, {1: (2.0, 0.0), 3: (5.0, 0.0)}, stamp_ns=T0 + DT)
    near_a = interpolate_frame(a, b, T0 + 30_000_000)
    assert {p.id: p.xy for p in near_a.people} == {1: pytest.approx((1.3, 0.0)), 2: (3.0, 0.0)}
    assert near_a.frame == 0
    assert near_a.stamp_ns == T0 + 30_000_000
    near_b = interpolate_frame(a, b, T0 + 70_000_000)
    assert {p.id: p.xy for p in near_b.people} == {1: pytest.approx((1.7, 0.0)), 3: (5.0, 0.0)}
    # boxes are not interpolated (they belong to an image)
    boxed = LabelFrame(0, (LabelPerson(1, 1.0, 0.0, box=(1.0, 2.0, 3.0, 4.0)),), T0)
    assert interpolate_frame(boxed, b, T0 + 10).people[0].box is None
    # predicted frames further apart than the gap: the ground truth between them has no prediction
    pred = LabelSet.from_frames(
        [a, frame(1, {1: (2.0, 0.0)}, stamp_ns=T0 + 10 * DT), b.__class__(2, (), T0 + 11 * DT)]
    )
    gt = LabelSet.from_frames(
        [frame(k, {1: (1.5, 0.0)}, stamp_ns=T0 + k * DT + 50_000_000) for k in range(11)]
    )
    al = align_frames(pred, gt)  # median spacing 0.5 s: gaps up to 1.25 s are interpolated
    assert al.num_interpolated == 11
    al = align_frames(pred, gt, interpolate_gap_ns=2 * DT)
    assert [p is not None for _, p in al.pairs] == [False] * 10 + [True]
    # two ground-truth frames on one predicted stamp: the second gets nothing, at the first predicted
    # stamp as elsewhere (not a copy of the frame the first one took)
    pred3 = LabelSet.from_frames([frame(k, {1: (1.0, 0.0)}, stamp_ns=T0 + k * DT) for k in range(3)])
    for s in (T0, T0 + DT):
        gt2 = LabelSet.from_frames(
            [frame(0, {1: (1.0, 0.0)}, stamp_ns=s), frame(1, {1: (1.0, 0.0)}, stamp_ns=s)]
        )
        al = align_frames(pred3, gt2)
        assert [p is not None for _, p in al.pairs] == [True, False]
        assert al.num_interpolated == 0


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
