"""``studio evaluate``: table, JSON keys of DESIGN.md, one-line errors with exit status 2."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from evalfixtures import frame, random_sequence

from studio.cli import main
from studio.evaluate import JSON_KEYS
from studio.geometry.se import Pose2
from studio.labels import LabelFrame, LabelPerson, write_labels

DESIGN_KEYS = "precision recall f1 tp fp fn mota motp idf1 hota id_switches mt pt ml num_frames num_gt_tracks"


@pytest.fixture
def files(tmp_path: Path) -> tuple[Path, Path]:
    raw_gts, raw_preds = random_sequence(0)
    t0 = 1_700_000_000_000_000_000
    gts = [frame(g.frame, {p.id: p.xy for p in g.people}, stamp_ns=t0 + g.frame * 10**8) for g in raw_gts]
    preds = [
        frame(
            p.frame,
            {q.id: q.xy for q in p.people},
            stamp_ns=t0 + p.frame * 10**8,
            robot_pose=Pose2(0.1 * p.frame * (p.frame > 10), 0.0, 0.0),
        )
        for p in raw_preds
        if p is not None
    ]
    write_labels(tmp_path / "gt.jsonl", gts)
    write_labels(tmp_path / "pred.jsonl", preds)
    return tmp_path / "pred.jsonl", tmp_path / "gt.jsonl"


def test_table_and_json(files: tuple[Path, Path], tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    pred, gt = files
    out = tmp_path / "sub" / "metrics.json"
    assert main(["evaluate", str(pred), str(gt), "--radius", "0.3", "--json", str(out)]) == 0
    text = capsys.readouterr().out
    for word in ("precision", "MOTA", "MOTP", "IDF1", "HOTA", "MT", "static", "moving"):
        assert word in text
    data = json.loads(out.read_text())
    assert tuple(JSON_KEYS) == tuple(DESIGN_KEYS.split())
    assert tuple(data)[: len(JSON_KEYS)] == JSON_KEYS  # the contract keys come first, extras after
    assert {
        "idp",
        "idr",
        "deta",
        "assa",
        "loca",
        "frag",
        "num_pred_tracks",
        "radius",
        "frame_matching",
    } <= set(data)
    assert data["radius"] == 0.3
    assert data["frame_matching"] == "stamp"
    assert data["mt"] + data["pt"] + data["ml"] == 1.0
    assert isinstance(data["tp"], int)
    assert isinstance(data["num_frames"], int)
    assert set(data["splits"]) == {"static", "moving"}
    assert not list(out.parent.glob(".*.tmp"))  # written atomically, no leftovers


def test_yaml_against_jsonl(
    files: tuple[Path, Path], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    pred, gt = files
    from studio.labels import read_labels

    write_labels(tmp_path / "pred.yaml", read_labels(pred).frames)
    assert main(["evaluate", str(tmp_path / "pred.yaml"), str(gt), "--json", str(tmp_path / "m.json")]) == 0
    assert json.loads((tmp_path / "m.json").read_text())["frame_matching"] == "index"


BAD = {
    "missing file": ("nope.jsonl", "no such file"),
    "unknown format": ("pred.csv", "unknown label format"),
    "malformed json": ("bad.jsonl", "bad.jsonl:2"),
    "malformed yaml": ("bad.yaml", "not valid YAML"),
    "yaml not a mapping": ("list.yaml", "expected a mapping"),
    "no shared frame": ("far.jsonl", "share no frame"),
    "a directory without labels": ("adir", "is a directory"),
    "missing file, unknown suffix": ("nope.txt", "no such file"),
}


def _write_bad(tmp_path: Path) -> None:
    (tmp_path / "pred.csv").write_text("hello\n")
    (tmp_path / "bad.jsonl").write_text('{"frame": 0, "people": []}\n{"frame": 1, "people": [\n')
    (tmp_path / "bad.yaml").write_text("frame 0:\n  - id1: {x: 1, y: [\n")
    (tmp_path / "list.yaml").write_text("- 1\n- 2\n")
    write_labels(tmp_path / "far.jsonl", [frame(1000 + k, {1: (0.0, 0.0)}) for k in range(3)])
    (tmp_path / "adir").mkdir()


@pytest.mark.parametrize("case", BAD)
def test_bad_input_one_line_exit_2(
    case: str, files: tuple[Path, Path], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    _, _gt = files
    _write_bad(tmp_path)
    name, message = BAD[case]
    gt_plain = tmp_path / "gt_plain.jsonl"
    write_labels(gt_plain, [frame(k, {1: (0.0, 0.0)}) for k in range(3)])  # no stamps: index alignment
    assert main(["evaluate", str(tmp_path / name), str(gt_plain)]) == 2
    err = capsys.readouterr().err
    assert len(err.strip().splitlines()) == 1, err
    assert err.startswith("studio evaluate: error:")
    assert message in err
    # also as ground truth
    assert main(["evaluate", str(gt_plain), str(tmp_path / name)]) == 2
    assert len(capsys.readouterr().err.strip().splitlines()) == 1


def test_run_directory_stands_for_its_labels(
    files: tuple[Path, Path], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    pred, gt = files
    run = tmp_path / "run"
    run.mkdir()
    (run / "labels.jsonl").write_bytes(pred.read_bytes())
    assert main(["evaluate", str(run), str(gt)]) == 0
    assert "MOTA" in capsys.readouterr().out


def test_json_into_a_directory(
    files: tuple[Path, Path], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    pred, gt = files
    assert main(["evaluate", str(pred), str(gt), "--json", str(tmp_path)]) == 2
    assert "is a directory" in capsys.readouterr().err


def test_command_line_process(files: tuple[Path, Path], tmp_path: Path) -> None:
    pred, gt = files
    ok = subprocess.run(
        [
            sys.executable,
            "-m",
            "studio.cli",
            "evaluate",
            str(pred),
            str(gt),
            "--json",
            str(tmp_path / "m.json"),
        ],
        capture_output=True,
        text=True,
        check=False,
    )
    assert ok.returncode == 0, ok.stderr
    assert "IDF1" in ok.stdout
    bad = subprocess.run(
        [sys.executable, "-m", "studio.cli", "evaluate", str(tmp_path / "missing.jsonl"), str(gt)],
        capture_output=True,
        text=True,
        check=False,
    )
    assert bad.returncode == 2
    assert len(bad.stderr.strip().splitlines()) == 1
    assert "Traceback" not in bad.stderr


def test_positions_in_the_odom_frame(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    # ground truth annotated on a map of the recording: odom-frame positions; the robot drives along x, so
    # base-frame positions differ from odom ones and only --frame odom compares like with like
    t0 = 1_700_000_000_000_000_000
    gts, preds = [], []
    for k in range(10):
        pose = Pose2(0.5 * k, 0.0, 0.0)
        odom = (3.0, 1.0)
        base = tuple(float(v) for v in pose.inverse().apply(np.array(odom)))
        gts.append(LabelFrame(k, (LabelPerson(1, 0.0, 0.0, x_odom=odom[0], y_odom=odom[1]),), t0 + k * 10**8))
        preds.append(
            LabelFrame(
                k, (LabelPerson(7, *base, x_odom=odom[0] + 0.05, y_odom=odom[1]),), t0 + k * 10**8, pose
            )
        )
    write_labels(tmp_path / "gt.jsonl", gts)
    write_labels(tmp_path / "pred.jsonl", preds)
    out = tmp_path / "m.json"
    assert (
        main(["evaluate", str(tmp_path / "pred.jsonl"), str(tmp_path / "gt.jsonl"), "--json", str(out)]) == 0
    )
    assert json.loads(out.read_text())["tp"] < 10  # the ground truth's x, y are no base-frame positions
    args = ["evaluate", str(tmp_path / "pred.jsonl"), str(tmp_path / "gt.jsonl"), "--frame", "odom"]
    assert main([*args, "--json", str(out)]) == 0
    assert "odom frame" in capsys.readouterr().out
    data = json.loads(out.read_text())
    assert (data["tp"], data["fp"], data["fn"]) == (10, 0, 0)
    assert data["motp"] == pytest.approx(0.05)
    # a person without odom-frame coordinates: one line, exit 2
    write_labels(
        tmp_path / "bare.jsonl", [frame(k, {1: (3.0, 1.0)}, stamp_ns=t0 + k * 10**8) for k in range(10)]
    )
    capsys.readouterr()
    assert (
        main(["evaluate", str(tmp_path / "pred.jsonl"), str(tmp_path / "bare.jsonl"), "--frame", "odom"]) == 2
    )
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1
    assert "x_odom" in err[0]
