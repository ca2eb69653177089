"""Simulate → label → evaluate, for our method and the thesis baseline; regression guard on accuracy.

The thresholds would fail if fusion, odometry compensation or tracking broke: the baselines in
``baselines.json`` were measured with this exact scenario, and a drop of more than ``MARGIN`` fails.
"""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from studio.commands.label import run_label
from studio.evaluate import evaluate
from studio.labels import read_labels, read_review
from studio.pipeline import LabelOptions

pytestmark = pytest.mark.slow

BASELINES = json.loads((Path(__file__).with_name("baselines.json")).read_text())
MARGIN = 0.03


@pytest.fixture(scope="module")
def runs(sim_moving: Path, tmp_path_factory: pytest.TempPathFactory) -> dict[str, dict]:
    out: dict[str, dict] = {}
    for method in ("studio", "thesis"):
        run = tmp_path_factory.mktemp("run") / method
        info = run_label(
            sim_moving / "recording.mcap",
            sim_moving / "rig.yaml",
            run,
            options=LabelOptions(method=method),
            write_rrd=method == "studio",
            ground_truth=sim_moving / "ground_truth.jsonl",
            quiet=True,
        )
        ev = evaluate(run / "labels.jsonl", sim_moving / "ground_truth.jsonl")
        out[method] = {"run": run, "info": info, "metrics": ev.metrics()}
    return out


def test_run_directory_has_every_contract_file(runs: dict[str, dict]) -> None:
    run = runs["studio"]["run"]
    for name in (
        "labels.yaml",
        "labels.jsonl",
        "detections.yaml",
        "tracks_mot.csv",
        "boxes_coco.json",
        "review.jsonl",
        "run.json",
        "recording.rrd",
    ):
        assert (run / name).is_file(), name
    info = json.loads((run / "run.json").read_text())
    assert {"timings_s", "versions", "options", "counts"} <= set(info)
    points = read_review(run / "review.jsonl")
    assert info["counts"]["review_points"] == len(points) > 0
    frames = {f.frame: {p.id for p in f.people} for f in read_labels(run / "labels.jsonl").frames}
    assert all(set(p.ids) <= frames[p.frame] for p in points)  # each point names tracks of its frame
    coco = json.loads((run / "boxes_coco.json").read_text())
    assert coco["annotations"]
    assert all("track_id" in a and "position_base" in a for a in coco["annotations"])


def test_accuracy_does_not_regress(runs: dict[str, dict]) -> None:
    m = runs["studio"]["metrics"]
    base = BASELINES["studio"]
    assert m["f1"] >= base["f1"] - MARGIN, m
    assert m["mota"] >= base["mota"] - MARGIN, m
    assert m["id_switches"] <= base["id_switches"] + 1, m


def test_studio_beats_the_thesis_method_on_the_same_recording(runs: dict[str, dict]) -> None:
    ours, thesis = runs["studio"]["metrics"], runs["thesis"]["metrics"]
    assert ours["mota"] > thesis["mota"] + 0.05, (ours, thesis)
    assert ours["idf1"] > thesis["idf1"], (ours, thesis)
    assert ours["id_switches"] <= thesis["id_switches"], (ours, thesis)
