"""A 3-D lidar's point clouds label as the planar scans they contain.

The simulated recording is written again with its front scanner's scans as sensor_msgs/PointCloud2 (ROS2
MCAP), as a 3-D lidar publishes them: each return becomes a point inside the rig's height band, and the
points a 3-D lidar adds (the floor, walls above the legs, returns nearer than the body, NaN points of an
organised cloud) lie outside it. Sliced with ``cloud: {min_z, max_z}``, the labels must be those of the
original scans (the virtual beams' bearings are rounded to the 0.25° grid: positions agree to centimetres).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import pytest

from studio.io import load_rig
from studio.pipeline import LabelOptions
from studio.pipeline.label import label_recording

pytestmark = pytest.mark.slow

SCANS = """base_frame: base_link
odometry: {topic: /odom}
lasers:
  - topic: /scan_front
  - topic: /scan_rear
"""
CLOUD = """base_frame: base_link
odometry: {topic: /odom}
lasers:
  - topic: /scan_front
    cloud: {min_z: -0.15, max_z: 0.15}
  - topic: /scan_rear
"""
POINT = np.dtype(  # an Ouster-like layout: `t` is each point's time after the stamp, ns
    {
        "names": ["x", "y", "z", "intensity", "t", "ring"],
        "formats": ["<f4", "<f4", "<f4", "<f4", "<u4", "<u2"],
        "offsets": [0, 4, 8, 16, 20, 24],
        "itemsize": 32,
    }
)


def cloud_of(scan: Any, store: Any, rng: np.random.Generator, *, organised: bool = True) -> Any:
    """A PointCloud2 holding ``scan``'s returns in the band and a 3-D lidar's other points outside it.

    Organised: four rings of one column per beam step all around (the scanner's beams, then NaN where it
    does not look): the band, nearer points above and below it, points on the robot, rays without a
    return. Unorganised: one row of the points that are there, in that order.
    """
    cols = round(2 * np.pi / abs(scan.angle_increment))
    r = np.full(cols, np.nan)
    r[: len(scan.ranges)] = scan.ranges
    r[~((r >= scan.range_min) & (r <= scan.range_max))] = np.nan
    a = scan.angle_min + scan.angle_increment * np.arange(cols)
    t = np.round(np.arange(cols) * scan.time_increment * 1e9)
    pts = np.zeros((4, cols), POINT)  # one array: concatenating padded records may drop the padding
    band, other, body, blank = pts
    band["x"], band["y"], band["z"] = r * np.cos(a), r * np.sin(a), rng.uniform(-0.12, 0.12, cols)
    other["x"], other["y"] = 0.5 * r * np.cos(a), 0.5 * r * np.sin(a)
    other["z"] = np.where(np.arange(cols) % 2 == 0, -0.4, 0.9)
    body["x"], body["y"] = 0.05 * np.cos(a), 0.05 * np.sin(a)  # on the robot itself, inside range_min
    for c in "xyz":
        blank[c] = np.nan
    for row in pts:
        row["t"] = t
    if not organised:
        pts = pts[:, np.isfinite(r)][:3].reshape(1, -1)
    field = store.types["sensor_msgs/msg/PointField"]
    fields = [
        field(name=name, offset=off, datatype=dt, count=1)
        for name, off, dt in (
            ("x", 0, 7),
            ("y", 4, 7),
            ("z", 8, 7),
            ("intensity", 16, 7),
            ("t", 20, 6),
            ("ring", 24, 4),
        )
    ]
    return store.types["sensor_msgs/msg/PointCloud2"](
        header=scan.header,
        height=pts.shape[0],
        width=pts.shape[1],
        fields=fields,
        is_bigendian=False,
        point_step=POINT.itemsize,
        row_step=pts.shape[1] * POINT.itemsize,
        data=np.frombuffer(pts.tobytes(), np.uint8),
        is_dense=False,
    )


def as_point_clouds(src: Path, dst: Path, topic: str, *, organised: bool = True) -> None:
    """``src`` (ROS2 MCAP) written again with ``topic``'s scans as point clouds (:func:`cloud_of`)."""
    from rosbags.highlevel import AnyReader
    from rosbags.rosbag2 import StoragePlugin, Writer
    from rosbags.typesys import Stores, get_typestore

    store = get_typestore(Stores.ROS2_HUMBLE)
    rng = np.random.default_rng(0)
    with AnyReader([src]) as reader, Writer(dst, version=9, storage_plugin=StoragePlugin.MCAP) as writer:
        conns = {}
        for c in reader.connections:
            msgtype = "sensor_msgs/msg/PointCloud2" if c.topic == topic else c.msgtype
            qos = c.ext.offered_qos_profiles if hasattr(c.ext, "offered_qos_profiles") else ""
            conns[c.id] = writer.add_connection(
                c.topic, msgtype, typestore=store, serialization_format="cdr", offered_qos_profiles=qos
            )
        for c, t, raw in reader.messages():
            if c.topic == topic:
                msg = cloud_of(reader.deserialize(raw, c.msgtype), store, rng, organised=organised)
                raw = store.serialize_cdr(msg, "sensor_msgs/msg/PointCloud2")
            writer.write(conns[c.id], t, raw)


def _run(recording: Path, rig_text: str, tmp: Path) -> Any:
    rig = tmp / "rig.yaml"
    rig.write_text(rig_text)
    return label_recording(recording, load_rig(rig), options=LabelOptions(sources="laser"))


def _labels(recording: Path, rig_text: str, tmp: Path) -> dict[int, np.ndarray]:
    run = _run(recording, rig_text, tmp)
    return {f.stamp_ns: np.array([(p.x, p.y) for p in f.people]).reshape(-1, 2) for f in run.labels}


@pytest.fixture(scope="module")
def simulated(tmp_path_factory: pytest.TempPathFactory) -> Path:
    from studio.sim import simulate

    out = tmp_path_factory.mktemp("sim") / "moving"
    simulate("moving", out=out, seconds=8.0, seed=2)
    return out


@pytest.fixture(scope="module")
def sweeping(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The same recording with scanners that sweep their beams over 75 ms at 10 Hz, as a spinning lidar."""
    from dataclasses import replace

    from studio.sim import simulate
    from studio.sim.base import SimRig

    base = SimRig()
    rig = replace(base, lasers=tuple(replace(x, rate_hz=10.0, sweep_s=0.075) for x in base.lasers))
    out = tmp_path_factory.mktemp("sim") / "sweeping"
    simulate("moving", out=out, seconds=8.0, seed=2, rig=rig)
    return out


def _agree(scans: dict[int, np.ndarray], clouds: dict[int, np.ndarray]) -> None:
    """The same frames (a timed cloud's frame is stamped at its first return: within a sweep of the scan's
    stamp) and the same people in them, to 5 cm."""
    assert len(scans) == len(clouds)
    pairs = list(zip(sorted(scans), sorted(clouds), strict=True))
    assert all(0 <= c - s < 75_000_000 for s, c in pairs)
    total = sum(len(v) for v in scans.values())
    assert total > 40
    matched = 0
    for stamp, other in pairs:
        a, b = scans[stamp], clouds[other]
        if len(a) and len(b):
            d = np.hypot(*(a[:, None, :] - b[None, :, :]).transpose(2, 0, 1))
            matched += int(np.sum(d.min(axis=1) < 0.05))
    assert matched >= 0.95 * total
    assert abs(sum(len(v) for v in clouds.values()) - total) <= 0.03 * total


def test_a_spinning_lidar_s_timed_clouds_label_as_its_sweeping_scans(sweeping: Path, tmp_path: Path) -> None:
    """Each point's time (`t`) places the virtual beams in the sweep as the scans' time_increment does."""
    bag = tmp_path / "clouds"
    as_point_clouds(sweeping / "recording.mcap", bag, "/scan_front")
    _agree(_labels(sweeping / "recording.mcap", SCANS, tmp_path), _labels(bag, CLOUD, tmp_path))


@pytest.mark.parametrize("organised", [True, False])
def test_point_clouds_label_as_the_scans_they_contain(
    simulated: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str], organised: bool
) -> None:
    """Organised (rings of columns all around: the beams are the columns) or not (sliced at 0.25°)."""
    from studio.cli import main
    from studio.pipeline.export import dataset_card

    bag = tmp_path / "clouds"
    as_point_clouds(simulated / "recording.mcap", bag, "/scan_front", organised=organised)
    scans = _labels(simulated / "recording.mcap", SCANS, tmp_path)
    run = _run(bag, CLOUD, tmp_path)
    clouds = {f.stamp_ns: np.array([(p.x, p.y) for p in f.people]).reshape(-1, 2) for f in run.labels}
    card = dataset_card(
        run,
        options=LabelOptions(sources="laser"),
        recording=bag,
        rig=load_rig(tmp_path / "rig.yaml"),
        n_images=0,
    )
    assert "- laser `/scan_front`" in card
    assert "a 3-D lidar's point clouds sliced into a planar scan (points -0.15 to 0.15 m" in card
    assert main(["inspect", str(bag)]) == 0
    out = capsys.readouterr().out
    assert "/scan_front" in out
    assert "a 3-D lidar; label it with a height band" in out
    assert sum(len(v) for v in scans.values()) > 100
    _agree(scans, clouds)


def test_a_point_cloud_without_a_height_band_is_refused(simulated: Path, tmp_path: Path) -> None:
    from studio.io.errors import RecordingError

    bag = tmp_path / "clouds"
    as_point_clouds(simulated / "recording.mcap", bag, "/scan_front")
    with pytest.raises(RecordingError, match=r"carries PointCloud2.*cloud: \{min_z"):
        _labels(bag, SCANS, tmp_path)
    with pytest.raises(RecordingError, match="not PointCloud2: drop its 'cloud' entry"):
        _labels(simulated / "recording.mcap", CLOUD, tmp_path)
