"""``max_range``: ground truth annotated within a range of the robot only (an annotator's or a simulator's
limit); what lies beyond counts only where it matches."""

from __future__ import annotations

from pathlib import Path

import pytest
from evalfixtures import frame

from studio.cli import main
from studio.evaluate import evaluate
from studio.labels import LabelSet, write_labels

NEAR, FAR = (4.0, 0.0), (12.0, 0.0)  # metres from the robot, in its base frame


def _ev(gt: list[dict], pred: list[dict], max_range: float | None = 10.0):
    gts = LabelSet.from_frames([frame(k, g) for k, g in enumerate(gt)])
    preds = LabelSet.from_frames([frame(k, p) for k, p in enumerate(pred)])
    return evaluate(preds, gts, max_range=max_range)


@pytest.mark.parametrize(
    ("name", "gt", "pred", "counts"),
    [
        # a right label of someone the ground truth does not list (beyond its range) is no false positive
        ("label beyond the range", {1: NEAR}, {7: NEAR, 8: FAR}, (1, 0, 0)),
        # someone listed beyond the range (a file that lists everyone) is no miss
        ("person beyond the range", {1: NEAR, 2: FAR}, {7: NEAR}, (1, 0, 0)),
        # a false positive inside the range still counts
        ("false positive inside", {1: NEAR}, {7: NEAR, 8: (0.0, 5.0)}, (1, 1, 0)),
        # a miss inside the range still counts
        ("miss inside", {1: NEAR, 2: (0.0, 5.0)}, {7: NEAR}, (1, 0, 1)),
        # across the border: a person listed at 9.95 m matches a label at 10.05 m ...
        ("listed person, label beyond", {1: (9.95, 0.0)}, {7: (10.05, 0.0)}, (1, 0, 0)),
        # ... and a label at 9.98 m of a person at 10.05 m, not listed, is neither
        ("label inside, person beyond", {1: NEAR, 2: (10.05, 0.0)}, {7: NEAR, 8: (9.98, 0.0)}, (1, 0, 0)),
    ],
)
def test_what_lies_beyond_the_range_counts_only_where_it_matches(name, gt, pred, counts):
    ev = _ev([gt] * 3, [pred] * 3)
    d = ev.detection
    assert (d.tp, d.fp, d.fn) == tuple(3 * c for c in counts)
    # the track metrics see the same people: nothing else was found or missed
    assert ev.clear.fp == d.fp
    assert ev.clear.fn == d.fn
    assert ev.metrics()["max_range"] == 10.0


def test_without_a_range_everything_counts():
    ev = _ev([{1: NEAR}] * 3, [{7: NEAR, 8: FAR}] * 3, max_range=None)
    assert (ev.detection.tp, ev.detection.fp) == (3, 3)
    assert ev.metrics()["max_range"] is None


def test_bad_ranges_are_refused():
    with pytest.raises(ValueError, match="max_range"):
        _ev([{1: NEAR}], [{7: NEAR}], max_range=0.0)
    gts = LabelSet.from_frames([frame(0, {1: NEAR})])
    with pytest.raises(ValueError, match="base frame"):
        evaluate(gts, gts, frame="odom", max_range=10.0)


def test_cli(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    write_labels(tmp_path / "gt.jsonl", [frame(k, {1: NEAR}) for k in range(3)])
    write_labels(tmp_path / "pred.jsonl", [frame(k, {7: NEAR, 8: FAR}) for k in range(3)])
    args = ["evaluate", str(tmp_path / "pred.jsonl"), str(tmp_path / "gt.jsonl")]
    assert main([*args, "--max-range", "10"]) == 0
    text = capsys.readouterr().out
    assert "within 10 m of the robot" in text
    assert "FP 0," in text
    assert main(args) == 0
    assert "FP 3," in capsys.readouterr().out
    for bad in (["--max-range", "-1"], ["--max-range", "10", "--frame", "odom"]):
        try:
            code = main([*args, *bad])
        except SystemExit as e:  # argparse refuses a bad number itself
            code = e.code
        assert code == 2
    err = capsys.readouterr().err
    assert "Traceback" not in err
    assert "max-range" in err
