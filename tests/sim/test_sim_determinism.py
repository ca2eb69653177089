"""Same seed → same messages and ground truth; another seed → another recording; errors are one line."""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np
import pytest
from rosbags.highlevel import AnyReader
from rosbags.typesys import Stores, get_typestore

from studio.cli import main
from studio.geometry import Pose3
from studio.sim import SimError, SimRig, simulate


def _messages(path: Path) -> list[tuple[str, int, bytes]]:
    with AnyReader([path], default_typestore=get_typestore(Stores.ROS2_HUMBLE)) as reader:
        return [(c.topic, t, bytes(raw)) for c, t, raw in reader.messages()]


def test_same_seed_gives_identical_messages_and_ground_truth(tmp_path: Path) -> None:
    a = simulate("moving", out=tmp_path / "a", seconds=0.4, seed=11)
    b = simulate("moving", out=tmp_path / "b", seconds=0.4, seed=11)
    c = simulate("moving", out=tmp_path / "c", seconds=0.4, seed=12)
    for name in ("ground_truth.yaml", "ground_truth.jsonl", "rig.yaml"):
        assert (a.out / name).read_bytes() == (b.out / name).read_bytes(), name
    ma, mb, mc = _messages(a.recording), _messages(b.recording), _messages(c.recording)
    assert len(ma) == len(mb) > 0
    assert ma == mb
    assert a.recording.read_bytes() == b.recording.read_bytes()
    assert (a.out / "ground_truth.jsonl").read_bytes() != (c.out / "ground_truth.jsonl").read_bytes()
    assert [m[2] for m in ma if m[0] == "/scan_front"] != [m[2] for m in mc if m[0] == "/scan_front"]


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"scenario": "nope"}, "unknown scenario 'nope'"),
        ({"scenario": "static", "seconds": 0.0}, "--seconds"),
        ({"scenario": "static", "seconds": -3.0}, "--seconds"),
        ({"scenario": "static", "seconds": float("nan")}, "--seconds"),
        ({"scenario": "static", "seconds": 1e6}, "--seconds"),
        ({"scenario": "static", "seed": -1}, "--seed"),
    ],
)
def test_bad_input_raises_one_line_sim_error(tmp_path: Path, kwargs: dict, match: str) -> None:  # type: ignore[type-arg]
    scenario = kwargs.pop("scenario")
    with pytest.raises(SimError, match=match) as info:
        simulate(scenario, out=tmp_path / "x", **kwargs)
    assert "\n" not in str(info.value)
    assert not (tmp_path / "x").exists()


def test_out_that_is_a_file_is_an_error(tmp_path: Path) -> None:
    f = tmp_path / "file"
    f.write_text("x")
    with pytest.raises(SimError, match="not a directory"):
        simulate("static", out=f, seconds=0.1)


def test_out_with_other_files_is_not_replaced(tmp_path: Path) -> None:
    (tmp_path / "mine.txt").write_text("keep me")
    with pytest.raises(SimError, match="holds other files"):
        simulate("static", out=tmp_path, seconds=0.1)
    assert (tmp_path / "mine.txt").read_text() == "keep me"


def test_a_failure_leaves_no_half_written_directory(tmp_path: Path) -> None:
    def boom(done: int, total: int) -> None:
        raise RuntimeError("stop")

    with pytest.raises(RuntimeError):
        simulate("static", out=tmp_path / "out", seconds=0.3, progress=boom)
    assert list(tmp_path.iterdir()) == []


def test_cli_simulate_writes_the_contract_files_and_reports_errors(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    assert (
        main(
            [
                "simulate",
                "--scenario",
                "rooms",
                "--seconds",
                "0.2",
                "--seed",
                "1",
                "--out",
                str(tmp_path / "r"),
            ]
        )
        == 0
    )
    assert sorted(p.name for p in (tmp_path / "r").iterdir()) == [
        ".studio-files", "ground_truth.jsonl", "ground_truth.yaml", "recording.mcap", "rig.yaml",
    ]  # fmt: skip
    assert "MB/min" in capsys.readouterr().out
    assert main(["simulate", "--scenario", "nope", "--out", str(tmp_path / "n")]) == 2
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0
    assert "unknown scenario" in err
    assert "calib-ball" in err  # the calibration scenarios are named too


def test_a_tilted_camera_is_refused(tmp_path: Path) -> None:
    rig = SimRig(camera_pose=Pose3.from_xyz_rpy(0.0, 0.0, 1.15, pitch=0.1))
    with pytest.raises(SimError, match="level"):
        simulate("static", out=tmp_path / "t", seconds=0.1, rig=rig)


def test_a_smaller_panorama_can_be_simulated(tmp_path: Path) -> None:
    res = simulate("static", out=tmp_path / "s", seconds=0.25, rig=SimRig(width=640, height=320))
    with AnyReader([res.recording], default_typestore=get_typestore(Stores.ROS2_HUMBLE)) as reader:
        conn = next(c for c in reader.connections if c.topic == "/theta_camera/image/compressed")
        raw = next(r for _, _, r in reader.messages(connections=[conn]))
        msg = reader.deserialize(raw, conn.msgtype)
    img = cv2.imdecode(np.frombuffer(bytes(msg.data), np.uint8), cv2.IMREAD_COLOR)
    assert img.shape == (320, 640, 3)


def test_default_recording_is_generated_once(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    import studio.sim.default as default

    monkeypatch.setattr(default, "DEFAULT_RECORDING", ("static", 0.3, 0))
    monkeypatch.setenv("STUDIO_RECORDINGS", str(tmp_path))
    first = default.default_recording()
    assert first == tmp_path / "default"
    assert (first / "recording.mcap").is_file()
    stamp = (first / "recording.mcap").stat().st_mtime_ns
    assert default.default_recording() == first
    assert (first / "recording.mcap").stat().st_mtime_ns == stamp
    monkeypatch.setattr(default, "DEFAULT_RECORDING", ("static", 0.5, 0))  # another length: regenerated
    assert default.default_recording() == first
    assert len((first / "ground_truth.jsonl").read_text().splitlines()) == 5
    stamp = (first / "recording.mcap").stat().st_mtime_ns
    (first / "sim_version").write_text("1\n")  # made by an older simulator: regenerated
    assert default.default_recording() == first
    assert (first / "recording.mcap").stat().st_mtime_ns != stamp
    assert (first / "sim_version").read_text().strip() == str(default.SIM_VERSION)
