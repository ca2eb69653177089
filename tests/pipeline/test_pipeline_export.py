"""``--export-frames``: the run directory is a self-contained dataset (panoramas, COCO boxes with track ids,
the labels, a dataset card)."""

from __future__ import annotations

import json
from dataclasses import replace
from pathlib import Path

import cv2
import pytest

from studio.commands.label import run_label
from studio.labels import read_labels
from studio.pipeline import LabelOptions
from tests.io.io_testdata import bag


@pytest.fixture(scope="module")
def run(recording: Path, tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("export") / "run"
    run_label(
        recording / "recording.mcap",
        recording / "rig.yaml",
        out,
        options=LabelOptions(export_frames=True),
        write_rrd=False,
        quiet=True,
    )
    return out


def test_every_labelled_frame_has_its_panorama(run: Path) -> None:
    coco = json.loads((run / "boxes_coco.json").read_text())
    labels = read_labels(run / "labels.jsonl")
    assert len(coco["images"]) == len(labels) > 0
    for image in coco["images"]:
        pano = cv2.imread(str(run / image["file_name"]))
        assert pano is not None, image["file_name"]
        assert pano.shape[:2] == (image["height"], image["width"]) == (960, 1920)
    assert len(list((run / "frames").glob("*.jpg"))) == len(coco["images"])


def test_boxes_carry_track_ids_and_world_positions(run: Path) -> None:
    coco = json.loads((run / "boxes_coco.json").read_text())
    assert coco["annotations"]
    ids = {p.id for f in read_labels(run / "labels.jsonl") for p in f.people}
    for a in coco["annotations"]:
        assert a["track_id"] in ids
        assert len(a["position_base"]) == 2
        assert a["image_id"] in {im["id"] for im in coco["images"]}


def test_the_dataset_card_says_how_the_labels_were_made(run: Path) -> None:
    card = (run / "DATASET.md").read_text()
    for part in ("## How the labels were produced", "## Known limits", "person labels; by source"):
        assert part in card
    assert "movenet" in card
    assert "bridge a gap of up to 3 s with the smoother" in card  # the run's own tracking setting
    assert "A track spanning less than 1.5 s is left out" in card
    # the simulated scanners' beams, and which leg model they got
    assert card.count("beams 0.25° apart (leg model for fine beams)") == 2


def test_run_json_gives_each_lasers_beam_step(run: Path) -> None:
    counts = json.loads((run / "run.json").read_text())["counts"]
    assert counts["laser_beam_deg"] == {"/scan_front": pytest.approx(0.25), "/scan_rear": pytest.approx(0.25)}
    assert counts["laser_sweep_ms"] == {"/scan_front": 0.0, "/scan_rear": 0.0}  # the simulator's: instant


def test_the_dataset_card_says_how_each_laser_s_beams_were_timed() -> None:
    from types import SimpleNamespace

    from studio.pipeline.export import dataset_card

    rig = SimpleNamespace(
        base_frame="laser",
        camera=None,
        odometry=None,
        lasers=[SimpleNamespace(topic=t, pose=None) for t in ("/a", "/b")],
    )
    counts = {"laser_beam_deg": {"/a": 0.35, "/b": 0.35}, "laser_sweep_ms": {"/a": 49.9, "/b": 0.0}}
    result = SimpleNamespace(labels=[], notes=[], image_size=None, counts=counts)
    card = dataset_card(result, options=LabelOptions(), recording=Path("r.bag"), rig=rig, n_images=0)
    a = next(line for line in card.splitlines() if line.startswith("- laser `/a`"))
    b = next(line for line in card.splitlines() if line.startswith("- laser `/b`"))
    assert a.endswith(
        "beams 0.35° apart (leg model for fine beams), swept in 49.9 ms "
        "(each beam placed and timed by its own measurement time)"
    )
    assert b.endswith("no beam timing in its scans (all beams taken at the scan's stamp)")


def _card(
    options: LabelOptions, lasers: list[str], beam_deg: dict[str, float], notes: tuple[str, ...] = ()
) -> str:
    """The dataset card of a run without labels, on a rig without a camera."""
    from types import SimpleNamespace

    from studio.pipeline.export import dataset_card

    rig = SimpleNamespace(
        base_frame="base_link",
        camera=None,
        odometry=None,
        lasers=[SimpleNamespace(topic=t, pose=None) for t in lasers],
    )
    result = SimpleNamespace(
        labels=[], notes=list(notes), image_size=None, counts={"laser_beam_deg": beam_deg}
    )
    return dataset_card(result, options=options, recording=Path("r.bag"), rig=rig, n_images=0)


@pytest.mark.parametrize(
    ("step", "model"),
    [(0.25, "leg model for fine beams"), (0.35, "leg model for fine beams"), (1.0, "coarse-beam")],
)
def test_the_dataset_card_names_the_leg_model_of_each_laser(step: float, model: str) -> None:
    card = _card(LabelOptions(sources="laser"), ["/scan"], {"/scan": step})
    assert f"- laser `/scan`, pose: from TF in the recording, beams {step:.2f}° apart ({model}" in card


def test_the_dataset_card_of_a_rig_without_a_camera_says_laser_only() -> None:
    assert "sources `both` (the rig has no camera: laser only)" in _card(LabelOptions(), [], {})


def test_the_dataset_card_of_a_laser_only_run_says_who_stood_still_is_missing() -> None:
    limit = "a track is kept only if it walked 1 m somewhere"
    assert limit in _card(LabelOptions(), [], {})
    assert limit not in _card(replace(LabelOptions(), min_walk_m=0.0), [], {})


def test_the_dataset_card_says_when_the_recording_was_cut_short(tmp_path: Path) -> None:
    from studio.io import open_recording

    data = bag("positive/positive_3.bag").read_bytes()
    cut = tmp_path / "cut.bag"
    cut.write_bytes(data[: len(data) // 2])
    with open_recording(cut) as rec:
        notes = tuple(rec.notes)
    card = _card(LabelOptions(), ["right_scan"], {}, notes)
    assert (
        f"- The recording did not end as a recorder ends it, and was read as far as it goes: {cut}: a ROS1"
        in card
    )
    assert "read as far as it goes" not in _card(LabelOptions(), [], {}, ("some other note",))
