"""A simulated robot whose scanners are mounted upside down is labelled as well as the upright one.

The simulator casts a flipped scanner's beams the other way round, the recording carries its roll of π in
TF and rig.yaml, and the pipeline turns its scans upright: the people come out where they are.
"""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from studio.commands.label import run_label
from studio.evaluate import evaluate
from studio.geometry import Pose3
from studio.pipeline import LabelOptions
from studio.sim import simulate
from studio.sim.base import SimRig

pytestmark = pytest.mark.slow


def _flipped(rig: SimRig) -> SimRig:
    """Each scanner turned upside down about its x axis, its field of view mirrored to stay where it was."""
    lasers = []
    for s in rig.lasers:
        r, p, y = s.pose.rpy()
        last = s.angle_min + (s.n_beams - 1) * s.angle_increment
        lasers.append(
            replace(s, pose=Pose3.from_xyz_rpy(*s.pose.t, roll=r + np.pi, pitch=p, yaw=y), angle_min=-last)
        )
    return replace(rig, lasers=tuple(lasers))


def test_a_rig_with_its_scanners_upside_down_labels_as_the_upright_one(tmp_path: Path) -> None:
    base = SimRig(width=256, height=128)
    f1 = {}
    for name, rig in (("upright", base), ("flipped", _flipped(base))):
        sim = simulate("moving", out=tmp_path / name, seconds=12.0, seed=11, rig=rig)
        run = tmp_path / f"run-{name}"
        run_label(
            sim.out / "recording.mcap",
            sim.out / "rig.yaml",
            run,
            options=LabelOptions(sources="laser"),
            write_rrd=False,
            quiet=True,
        )
        f1[name] = evaluate(run / "labels.jsonl", sim.out / "ground_truth.jsonl").metrics()["f1"]
    assert f1["upright"] > 0.8
    assert f1["flipped"] == pytest.approx(f1["upright"], abs=0.03)
