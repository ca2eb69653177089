"""sensor_msgs/MultiEchoLaserScan: each beam's first echo (the nearest return) is the scan.

Real scans: leg_tracker's ``positive_3.bag`` with every scan rewritten as a multi-echo scan whose beams
have the recorded range as first echo and a return 1.5 m behind it as second (a person in front of a
wall): labelled as the recorded bag is.
"""

from __future__ import annotations

from pathlib import Path
from types import SimpleNamespace

import numpy as np

from studio.cli import main
from studio.io import decode_scan
from tests.io.io_testdata import bag


def test_the_first_echo_of_each_beam_is_its_range() -> None:
    echo = lambda *e: SimpleNamespace(echoes=np.array(e, np.float32))  # noqa: E731
    header = SimpleNamespace(stamp=SimpleNamespace(sec=5, nanosec=0), frame_id="laser")
    msg = SimpleNamespace(
        header=header,
        angle_min=-1.0,
        angle_max=1.0,
        angle_increment=1.0,
        time_increment=0.0,
        scan_time=0.1,
        range_min=0.1,
        range_max=30.0,
        ranges=[echo(2.0, 4.5), echo(), echo(3.0)],
        intensities=[echo(100.0, 20.0), echo(), echo(50.0)],
    )
    s = decode_scan(msg)
    np.testing.assert_array_equal(s.ranges, np.array([2.0, np.nan, 3.0], np.float32))
    np.testing.assert_array_equal(s.intensities, np.array([100.0, np.nan, 50.0], np.float32))
    assert (s.stamp_ns, s.frame_id) == (5_000_000_000, "laser")


def to_multi_echo(src: Path, dst: Path) -> Path:
    """``src`` with its LaserScan messages as MultiEchoLaserScan ones (first echo: the recorded range)."""
    from rosbags.rosbag1 import Reader, Writer
    from rosbags.typesys import Stores, get_typestore

    store = get_typestore(Stores.ROS1_NOETIC)
    multi, echo = store.types["sensor_msgs/msg/MultiEchoLaserScan"], store.types["sensor_msgs/msg/LaserEcho"]
    writer = Writer(dst)
    with Reader(src) as reader:
        writer.open()
        conns = {
            c.id: writer.add_connection(c.topic, "sensor_msgs/msg/MultiEchoLaserScan", typestore=store)
            for c in reader.connections
        }
        for c, t, raw in reader.messages():
            m = store.deserialize_ros1(raw, c.msgtype)
            ranges = [
                echo(echoes=np.array([r, r + 1.5] if np.isfinite(r) else [r], np.float32)) for r in m.ranges
            ]
            intensities = [echo(echoes=np.array([i], np.float32)) for i in m.intensities]
            fields = {k: getattr(m, k) for k in ("header", "angle_min", "angle_max", "angle_increment")}
            fields |= {k: getattr(m, k) for k in ("time_increment", "scan_time", "range_min", "range_max")}
            out = multi(**fields, ranges=ranges, intensities=intensities)
            writer.write(conns[c.id], t, store.serialize_ros1(out, "sensor_msgs/msg/MultiEchoLaserScan"))
        writer.close()
    return dst


def test_a_multi_echo_bag_is_labelled_as_its_first_echoes_are(tmp_path: Path, capsys) -> None:
    src = bag("positive/positive_3.bag")
    multi = to_multi_echo(src, tmp_path / "multi_echo.bag")
    assert main(["inspect", str(multi)]) == 0
    out = capsys.readouterr().out
    assert "right_scan  sensor_msgs/msg/MultiEchoLaserScan" in out
    assert "multi-echo: each beam's first echo is used" in out
    assert "  - topic: right_scan" in out  # the draft rig takes it as a scanner
    rig = tmp_path / "rig.yaml"
    rig.write_text("base_frame: right_laser\nlasers:\n  - topic: right_scan\n")
    for name, path in (("recorded", src), ("multi", multi)):
        assert main(["label", str(path), "--rig", str(rig), "--out", str(tmp_path / name), "--no-rrd"]) == 0
    labels = [(tmp_path / name / "labels.yaml").read_text() for name in ("recorded", "multi")]
    assert labels[0] == labels[1]
    assert labels[0].count("id") > 100
