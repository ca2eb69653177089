"""A camera whose images show nobody the detector can find (a covered lens, thumbnails) while the lasers see
people: with a camera a track needs a box, so the labels come out empty, and the run says why."""

from __future__ import annotations

from pathlib import Path

from studio.io import load_rig
from studio.pipeline import LabelOptions
from studio.pipeline.label import label_recording
from studio.sim import simulate
from studio.sim.base import SimRig


def test_a_camera_that_finds_nobody_is_noted(tmp_path: Path) -> None:
    sim = simulate("moving", out=tmp_path / "sim", seconds=6.0, seed=11, rig=SimRig(width=64, height=32))
    rig = load_rig(sim.out / "rig.yaml")
    run = label_recording(sim.out / "recording.mcap", rig)
    assert not any(p for f in run.labels for p in f.people)
    note = next(n for n in run.notes if n.startswith("the image detector found nobody in any of the "))
    assert "--sources laser labels from the lasers alone" in note
    laser = label_recording(sim.out / "recording.mcap", rig, options=LabelOptions(sources="laser"))
    assert any(p for f in laser.labels for p in f.people)
    assert not any(n.startswith("the image detector") for n in laser.notes)
