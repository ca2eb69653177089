"""A ROS1 bag with TF and odometry, as another robot records it, labels as its ROS2 MCAP original does.

The simulated recording is written again as a ROS1 bag: once as a recent ROS1 robot records it
(``tf2_msgs/TFMessage`` on ``/tf`` and ``/tf_static``), once as an old one does (``tf/tfMessage``, frame ids
with a leading ``/``, the static transforms repeated on ``/tf`` from 0.3 s on instead of ``/tf_static``, the
odometry read from the TF tree). The labels must be the same as those of the MCAP.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path
from typing import Any

import pytest

from studio.io import load_rig
from studio.pipeline import LabelOptions
from studio.pipeline.label import label_recording

pytestmark = pytest.mark.slow

RIG = """base_frame: base_link
odometry: {odometry}
lasers:
  - topic: /scan_front
  - topic: /scan_rear
"""


def _as_ros1(src: Path, dst: Path, *, old: bool) -> None:
    """``src`` (ROS2 MCAP) written as a ROS1 bag (see the module docstring for ``old``)."""
    from rosbags.highlevel import AnyReader
    from rosbags.rosbag1 import Writer
    from rosbags.typesys import Stores, get_types_from_msg, get_typestore

    store = get_typestore(Stores.ROS1_NOETIC)
    tf_type = "tf/msg/tfMessage" if old else "tf2_msgs/msg/TFMessage"
    store.register(get_types_from_msg("geometry_msgs/TransformStamped[] transforms", tf_type))

    def ros1_type(msgtype: str) -> str:
        return tf_type if msgtype.endswith("TFMessage") else msgtype

    def convert(obj: Any) -> Any:
        if dataclasses.is_dataclass(obj) and not isinstance(obj, type):
            cls = store.types[ros1_type(obj.__msgtype__)]  # type: ignore[attr-defined]
            fields = {}
            for f in dataclasses.fields(cls):
                v = convert(getattr(obj, f.name)) if hasattr(obj, f.name) else 0  # ROS1 headers: seq
                if old and f.name in ("frame_id", "child_frame_id") and v:
                    v = "/" + v
                fields[f.name] = v
            return cls(**fields)
        if isinstance(obj, list):
            return [convert(x) for x in obj]
        return obj

    with AnyReader([src]) as reader, Writer(dst) as writer:
        conns = {
            c.id: writer.add_connection(c.topic, ros1_type(c.msgtype), typestore=store)
            for c in reader.connections
        }
        static, t0 = None, None
        for c, t, raw in reader.messages():
            msg = convert(reader.deserialize(raw, c.msgtype))
            t0 = t if t0 is None else t0
            if old and c.topic == "/tf_static":
                static = msg
                continue
            if old and c.topic == "/tf" and static is not None and t - t0 > 300_000_000:
                stamp = msg.transforms[0].header.stamp
                again = [
                    dataclasses.replace(tr, header=dataclasses.replace(tr.header, stamp=stamp))
                    for tr in static.transforms
                ]
                msg.transforms = [*msg.transforms, *again]
            writer.write(conns[c.id], t, store.serialize_ros1(msg, ros1_type(c.msgtype)))


@pytest.fixture(scope="module")
def simulated(tmp_path_factory: pytest.TempPathFactory) -> Path:
    from studio.sim import simulate

    out = tmp_path_factory.mktemp("sim") / "moving"
    simulate("moving", out=out, seconds=6.0, seed=2)
    return out


def _labels(recording: Path, rig_text: str, tmp: Path) -> dict[int, list[tuple[int, float, float]]]:
    rig = tmp / "rig.yaml"
    rig.write_text(rig_text)
    run = label_recording(recording, load_rig(rig), options=LabelOptions(sources="laser"))
    return {f.stamp_ns: sorted((p.id, round(p.x, 4), round(p.y, 4)) for p in f.people) for f in run.labels}


@pytest.mark.parametrize("old", [False, True])
def test_a_ros1_bag_with_tf_and_odometry_labels_as_its_mcap(
    simulated: Path, tmp_path: Path, old: bool
) -> None:
    bag = tmp_path / "recording.bag"
    _as_ros1(simulated / "recording.mcap", bag, old=old)
    mcap = _labels(simulated / "recording.mcap", RIG.format(odometry="{topic: /odom}"), tmp_path)
    ros1 = _labels(bag, RIG.format(odometry="{tf: odom}" if old else "{topic: /odom}"), tmp_path)
    assert sum(len(v) for v in mcap.values()) > 100
    assert ros1 == mcap  # the old robot's mounts, seen from 0.3 s on, place its first scans too
