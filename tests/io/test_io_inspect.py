"""``studio inspect`` on real and synthetic recordings, and on bad input (exit 2, one line)."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from io_testdata import DATA, bag

from studio.cli import main


def test_inspect_every_real_bag(capsys: pytest.CaptureFixture[str]) -> None:
    if not DATA.exists():
        pytest.skip("real data not available")
    for p in sorted(DATA.rglob("*.bag")):
        assert main(["inspect", str(p)]) == 0, p
        out = capsys.readouterr().out
        assert "topics (" in out
        assert "sensor_msgs/msg/LaserScan" in out
        assert "TF: none" in out


def test_inspect_real_bag_with_rig(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    rig = tmp_path / "rig.yaml"
    rig.write_text(
        "base_frame: left_laser\nlasers:\n  - topic: /left_scan\n  - topic: /rear_scan\n"
        "    pose: {x: -0.5, yaw: 3.14}\nsync: {max_dt_s: 0.05}\n"
    )
    assert main(["inspect", str(bag("negative_2.bag")), "--rig", str(rig)]) == 0
    out = capsys.readouterr().out
    assert "/left_scan" in out
    assert "768 beams" in out
    assert "swept in 49.9 ms (time_increment)" in out  # 768 beams 65 µs apart
    assert "7.51 Hz" in out
    assert "header stamps: first − log time +0.241 s" in out
    assert "frames: 435 yielded of 435 (scans of /left_scan)" in out
    assert "laser /rear_scan: scan in" in out
    assert "warning: the rig has no odometry" in out
    assert "laser /left_scan: 0.000 0.000 0.000, 0.0 0.0 0.0 (TF)" in out  # the base frame is its own
    assert "laser /rear_scan: -0.500 0.000 0.000, 0.0 0.0 179.9 (rig)" in out
    assert "upside down" not in out


def test_inspect_names_a_scanner_mounted_upside_down(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    rig = tmp_path / "rig.yaml"
    rig.write_text("base_frame: base\nlasers:\n  - topic: /left_scan\n    pose: {z: 0.3, roll: 3.14159}\n")
    assert main(["inspect", str(bag("negative_2.bag")), "--rig", str(rig)]) == 0
    out = capsys.readouterr().out
    assert "laser /left_scan: 0.000 0.000 0.300, 180.0 0.0 0.0 (rig); mounted upside down" in out


def test_inspect_synthetic_shows_tf_tree(
    synthetic: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    rig = tmp_path / "rig.yaml"
    rig.write_text(
        "base_frame: base_link\nodometry: {topic: /odom}\ncamera: {topic: /camera/image/compressed}\n"
        "lasers:\n  - topic: /scan_front\n  - topic: /scan_back\n"
    )
    assert main(["inspect", str(synthetic), "--rig", str(rig)]) == 0
    out = capsys.readouterr().out
    assert "ROS2 bag" in out
    assert "frame 'camera', 64×32, jpeg" in out
    assert "odom → base_link (dynamic, 201 samples, 50.0 Hz)" in out
    assert "base_link → front_laser (static)" in out
    assert "no time_increment (beams taken as measured at the header stamp)" in out
    assert "frames: 40 yielded of 40 (camera images on /camera/image/compressed)" in out


def _one_error_line(args: list[str]) -> str:
    proc = subprocess.run(
        [sys.executable, "-m", "studio.cli", *args], capture_output=True, text=True, timeout=120, check=False
    )
    assert proc.returncode == 2, proc.stderr
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1, proc.stderr
    assert "Traceback" not in proc.stderr
    return lines[0]


def test_inspect_truncated_bag_reads_its_whole_messages_and_says_so(tmp_path: Path, capsys) -> None:
    data = bag("demo_stationary_simple_environment.bag").read_bytes()
    cut = tmp_path / "cut.bag"
    cut.write_bytes(data[: len(data) // 3])
    assert main(["inspect", str(cut)]) == 0
    out = capsys.readouterr().out
    assert f"note: {cut}: a ROS1 bag without its index" in out
    assert "/scan  sensor_msgs/msg/LaserScan" in out


def test_inspect_corrupt_bag_exits_2_with_one_line(tmp_path: Path) -> None:
    data = bag("demo_stationary_simple_environment.bag").read_bytes()
    bad = tmp_path / "bad.bag"
    bad.write_bytes(data[:4200] + bytes(range(256)) * 40)  # the bag header, then no record
    line = _one_error_line(["inspect", str(bad)])
    assert line.startswith("studio inspect: error:")
    assert "bad.bag" in line


@pytest.mark.parametrize(
    ("rig_text", "match"),
    [
        ("base_frame: laser\nlasers: [{topic: /scan_front}]\n", "'/scan_front' is not in the recording"),
        ("base_frame: base_link\nlasers: [{topic: /scan}]\n", "not in the TF tree"),
        ("base_frame: laser\nlasers: [{topic: /scan}]\nbogus: 1\n", "key 'bogus' is not a known key"),
    ],
)
def test_inspect_bad_rig_exits_2(
    tmp_path: Path, rig_text: str, match: str, capsys: pytest.CaptureFixture[str]
) -> None:
    rig = tmp_path / "rig.yaml"
    rig.write_text(rig_text)
    assert main(["inspect", str(bag("demo_stationary_simple_environment.bag")), "--rig", str(rig)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1
    assert match in err[0]


def test_inspect_missing_file(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["inspect", str(tmp_path / "none.bag")]) == 2
    assert "recording not found" in capsys.readouterr().err


def test_inspect_says_when_header_stamps_are_unset(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    from io_testdata import T0, make_scan

    from studio.io import RecordingWriter

    p = tmp_path / "zero.mcap"
    with RecordingWriter(p) as w:
        for k in range(3):
            w.write_scan("/scan", make_scan(0, "laser"), log_ns=T0 + k * 100_000_000)
    assert main(["inspect", str(p)]) == 0
    assert "header stamps: unset (0): the log time stands in for them" in capsys.readouterr().out


def _draft(recording: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> Path:
    """``studio inspect`` without a rig ends with a rig to start from: written out as it prints it."""
    assert main(["inspect", str(recording)]) == 0
    out = capsys.readouterr().out
    draft = out[out.index("# a rig.yaml to start from") :]
    path = tmp_path / "draft.yaml"
    path.write_text(draft)
    return path


def test_the_rig_to_start_from_places_every_sensor_of_a_recording_with_tf(
    synthetic: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    from studio.io import count_frames, load_rig, open_recording, resolve_sensor_poses

    rig = load_rig(_draft(synthetic, tmp_path, capsys))
    assert rig.base_frame == "base_link"
    assert rig.odometry is not None
    assert rig.odometry.topic == "/odom"
    assert rig.camera is not None
    assert rig.camera.topic == "/camera/image/compressed"
    assert sorted(la.topic for la in rig.lasers) == ["/scan_back", "/scan_front"]
    with open_recording(synthetic) as rec:
        placed = resolve_sensor_poses(rec, rig)  # every pose from the TF tree
        assert placed.camera is not None
        assert placed.camera.pose is not None
        assert all(la.pose is not None for la in placed.lasers)
        assert count_frames(rec, rig) == 40


def test_the_rig_to_start_from_leaves_out_scanners_it_cannot_place(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    from studio.io import load_rig

    path = _draft(bag("negative_2.bag"), tmp_path, capsys)  # three scanners, no TF, no odometry
    rig = load_rig(path)
    assert rig.base_frame == "left_laser"
    assert rig.odometry is None
    assert rig.camera is None
    assert [la.topic for la in rig.lasers] == ["/left_scan"]
    text = path.read_text()
    assert "# - topic: /rear_scan" in text
    assert "# - topic: /right_scan" in text
    assert "frame 'rear_laser' is not in the TF tree of 'left_laser'" in text


def test_the_rig_to_start_from_loads_when_the_tf_tree_places_no_sensor(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    from io_testdata import write_synthetic

    from studio.io import load_rig

    rec = write_synthetic(tmp_path / "recording.mcap", tf_lasers=False)  # odometry, but no sensor in TF
    path = _draft(rec, tmp_path, capsys)
    rig = load_rig(path)
    assert rig.base_frame == "base_link"
    (kept,) = [la.topic for la in rig.lasers]  # the first scanner, its pose to measure
    other = ({"/scan_front", "/scan_back"} - {kept}).pop()
    text = path.read_text()
    assert "# MEASURE the pose of its frame" in text
    assert f"# - topic: {other}" in text  # the others left out
    assert "# camera:" in text


@pytest.mark.parametrize(
    "name", ["/scan_front", "laser #1", "laser: front", "*laser", "null", "123", "[a]", "x'y"]
)
def test_names_in_the_rig_to_start_from_read_back_as_written(name: str) -> None:
    import yaml

    from studio.commands.inspect import _scalar

    assert yaml.safe_load(f"k: {_scalar(name)}") == {"k": name}


def test_the_rig_to_start_from_skips_a_first_message_that_does_not_decode(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    from io_testdata import T0, make_scan

    from studio.io import RecordingWriter, load_rig

    rec = tmp_path / "recording.mcap"
    with RecordingWriter(rec) as w:
        t = w.types
        stamp = t["builtin_interfaces/msg/Time"](sec=T0 // 10**9, nanosec=0)
        bad = t["sensor_msgs/msg/LaserScan"](
            header=t["std_msgs/msg/Header"](stamp=stamp, frame_id="laser"),
            angle_min=0.0, angle_max=0.0, angle_increment=0.0, time_increment=0.0, scan_time=0.0,
            range_min=0.1, range_max=10.0, ranges=np.ones(5, np.float32), intensities=np.zeros(0, np.float32),
        )  # fmt: skip
        w.write_message("/scan", "sensor_msgs/msg/LaserScan", bad, log_ns=T0 - 1)  # a driver starting up
        for k in range(3):
            w.write_scan("/scan", make_scan(T0 + k * 100_000_000, "laser"))
    rig = load_rig(_draft(rec, tmp_path, capsys))
    assert rig.base_frame == "laser"
    assert [la.topic for la in rig.lasers] == ["/scan"]
