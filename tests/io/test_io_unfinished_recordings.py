"""Recordings whose recorder stopped before it finished the file, or cut short by a full disk or a broken
copy: ROS1 bags without their index (``.bag.active``), MCAP files without their summary.

Real scans: leg_tracker's ``positive_3.bag`` (345 scans of 768 beams), rewritten by rosbags' writer into
small chunks (uncompressed, bz2 and lz4), then cut, or left unfinished as ``rosbag record`` leaves a bag;
the synthetic ROS 2 recording of ``io_testdata`` (lasers, camera, odometry, TF) for MCAP.
"""

from __future__ import annotations

import struct
from pathlib import Path

import pytest

from studio.io import RecordingError, open_recording
from studio.io.reader import _RosbagsBackend
from studio.io.ros1_unindexed import UnindexedRos1Backend, is_unindexed_ros1
from tests.io.io_testdata import T0, bag, make_scan, write_synthetic

_HEADER_AT = len(b"#ROSBAG V2.0\n")
Message = tuple[str, str, int, bytes]


def rewrite(
    src: Path,
    dst: Path,
    compression: str = "none",
    chunk_bytes: int = 32 * 1024,
    *,
    start_ns: int | None = None,
    stop_ns: int | None = None,
) -> Path:
    """``src``'s messages (those logged in ``[start_ns, stop_ns)``) in a bag of ``chunk_bytes`` chunks,
    compressed as told (raw bytes unchanged)."""
    from rosbags.rosbag1 import Reader, Writer

    writer = Writer(dst)
    if compression != "none":
        writer.set_compression(Writer.CompressionFormat[compression.upper()])
    writer.chunk_threshold = chunk_bytes
    with Reader(src) as reader:
        writer.open()
        conns = {
            c.id: writer.add_connection(c.topic, c.msgtype, msgdef=c.msgdef.data, md5sum=c.digest)
            for c in reader.connections
        }
        for c, t, raw in reader.messages(start=start_ns, stop=stop_ns):
            writer.write(conns[c.id], t, raw)
        writer.close()
    return dst


def stream(backend: _RosbagsBackend | UnindexedRos1Backend) -> list[Message]:
    out = [(m.topic, m.msgtype, m.log_ns, m.rawdata) for m in backend.messages(None, None, None)]
    backend.close()
    return out


def header_field(data: bytes | bytearray, name: str) -> int:
    """Where the value of the bag header's field ``name`` starts."""
    return bytes(data).index(name.encode() + b"=", _HEADER_AT) + len(name) + 1


def index_pos(path: Path) -> int:
    data = path.read_bytes()
    return int(struct.unpack_from("<Q", data, header_field(data, "index_pos"))[0])


def fields(values: dict[str, bytes]) -> bytes:
    return b"".join(struct.pack("<I", len(k) + 1 + len(v)) + k.encode() + b"=" + v for k, v in values.items())


def record(header: dict[str, bytes], data: bytes) -> bytes:
    h = fields(header)
    return struct.pack("<I", len(h)) + h + struct.pack("<I", len(data)) + data


def unfinished(whole: Path, dst: Path, open_chunk: list[Message] | None = None) -> Path:
    """``whole`` as a stopped ``rosbag record`` leaves it: ``index_pos`` 0 and nothing after the last chunk,
    then (with ``open_chunk``) an unterminated uncompressed chunk (its lengths 0) holding those messages."""
    data = bytearray(whole.read_bytes()[: index_pos(whole)])
    at = header_field(data, "index_pos")
    data[at : at + 8] = bytes(8)
    if open_chunk:
        from rosbags.rosbag1 import Reader

        with Reader(whole) as reader:
            c = reader.connections[0]
            conn = struct.pack("<I", c.id)
            info = {"topic": c.topic.encode(), "type": b"sensor_msgs/LaserScan", "md5sum": c.digest.encode()}
            body = record({"op": b"\x07", "conn": conn, "topic": c.topic.encode()}, fields(info))
        for _, _, t, raw in open_chunk:
            stamp = struct.pack("<II", t // 1_000_000_000, t % 1_000_000_000)
            body += record({"op": b"\x02", "conn": conn, "time": stamp}, raw)
        head = fields({"op": b"\x05", "compression": b"none", "size": struct.pack("<I", 0)})
        data += struct.pack("<I", len(head)) + head + struct.pack("<I", 0) + body
    dst.write_bytes(bytes(data))
    return dst


@pytest.fixture(scope="module")
def chunked(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    root = tmp_path_factory.mktemp("chunked")
    src = bag("positive/positive_3.bag")
    return {c: rewrite(src, root / f"{c}.bag", c) for c in ("none", "bz2", "lz4")}


@pytest.mark.parametrize("compression", ["none", "bz2", "lz4"])
def test_the_chunks_of_a_whole_bag_give_every_message_as_rosbags_does(chunked, compression):
    path = chunked[compression]
    expected = stream(_RosbagsBackend([path], "ros1"))
    assert len(expected) == 345
    backend = UnindexedRos1Backend([path])
    assert backend.notes == []  # it has its index
    assert {t: (i.msgtype, i.count) for t, i in backend.topics.items()} == {
        "right_scan": ("sensor_msgs/msg/LaserScan", 345)
    }
    assert (backend.start_ns, backend.end_ns) == (expected[0][2], expected[-1][2])
    assert stream(backend) == expected
    # and on real bags as recorded (one chunk each): every leg_tracker bag
    for name in (
        "negative_2.bag",
        "demo_stationary_simple_environment.bag",
        "legs_labelled/positive_1_extracted.bag",
    ):
        assert stream(UnindexedRos1Backend([bag(name)])) == stream(_RosbagsBackend([bag(name)], "ros1"))


@pytest.mark.parametrize("compression", ["none", "bz2", "lz4"])
def test_a_bag_cut_short_gives_every_whole_message_before_the_cut(chunked, compression, tmp_path):
    whole = chunked[compression]
    expected = stream(_RosbagsBackend([whole], "ros1"))
    data = whole.read_bytes()
    got = []
    for frac in (0.1, 0.5, 0.9):
        cut = tmp_path / f"cut_{frac}.bag"
        cut.write_bytes(data[: int(len(data) * frac)])
        assert is_unindexed_ros1(cut)
        with open_recording(cut) as rec:
            msgs = [(m.topic, m.msgtype, m.log_ns, m.rawdata) for m in rec.messages()]
            assert len(rec.notes) == 1
            assert "without its index" in rec.notes[0]
            assert str(cut) in rec.notes[0]
            assert rec.decode(next(rec.messages())).ranges.shape == (768,)
        assert 0 < len(msgs) < len(expected)
        assert msgs == expected[: len(msgs)]  # the first ones, in order: nothing made up, nothing skipped
        got.append(len(msgs))
    assert got == sorted(got)
    # cut inside the index: rosbags cannot read the index, the chunks give every message
    cut = tmp_path / "cut_index.bag"
    cut.write_bytes(data[: index_pos(whole) + 40])
    with open_recording(cut) as rec:
        assert [(m.topic, m.msgtype, m.log_ns, m.rawdata) for m in rec.messages()] == expected


def test_an_unfinished_recording_reads_as_far_as_it_got(chunked, tmp_path):
    whole = chunked["none"]
    expected = stream(_RosbagsBackend([whole], "ros1"))
    # the index never written; the last chunk still open (as rosbag record leaves it) with 5 more scans
    more = [
        (topic, msgtype, expected[-1][2] + k * 100_000_000, raw)
        for k, (topic, msgtype, _, raw) in enumerate(expected[:5], 1)
    ]
    active = unfinished(whole, tmp_path / "run.bag.active", open_chunk=more)
    with open_recording(active) as rec:
        assert [(m.topic, m.msgtype, m.log_ns, m.rawdata) for m in rec.messages()] == expected + more
        assert rec.topics["right_scan"].count == 350
    # a folder of split bags whose last one is unfinished is one recording
    folder = tmp_path / "split"
    folder.mkdir()
    early = [m for m in expected if m[2] < expected[200][2]]
    src, split_at = bag("positive/positive_3.bag"), expected[200][2]
    rewrite(src, folder / "rec_0.bag", stop_ns=split_at)
    unfinished(rewrite(src, tmp_path / "late.bag", start_ns=split_at), folder / "rec_1.bag.active")
    with open_recording(folder) as rec:
        assert rec.files == (folder / "rec_0.bag", folder / "rec_1.bag.active")
        msgs = [(m.topic, m.msgtype, m.log_ns, m.rawdata) for m in rec.messages()]
        assert msgs[: len(early)] == early
        assert len(msgs) == len(expected)
        assert len(rec.notes) == 1
        assert "rec_1.bag.active" in rec.notes[0]


def test_a_bag_with_no_whole_message_is_one_clear_error(chunked, tmp_path):
    data = chunked["none"].read_bytes()
    for name, content in (
        ("header_only.bag", data[:5000]),  # the bag header's 4 KB and a few bytes of the first chunk
        ("junk.bag.active", data[:4200] + b"\x13\x37" * 500),
    ):
        path = tmp_path / name
        path.write_bytes(content)
        with pytest.raises(RecordingError) as info:
            open_recording(path)
        assert "\n" not in str(info.value)
        assert str(path) in str(info.value)


def test_studio_label_labels_a_cut_real_bag_and_says_so(tmp_path, capsys):
    from studio.cli import main

    data = bag("positive/positive_3.bag").read_bytes()
    cut = tmp_path / "positive_3_cut.bag"
    cut.write_bytes(data[: len(data) // 2])
    rig = tmp_path / "rig.yaml"
    rig.write_text("base_frame: right_laser\nlasers:\n  - topic: right_scan\n")
    assert main(["label", str(cut), "--rig", str(rig), "--out", str(tmp_path / "run"), "--no-rrd"]) == 0
    out = capsys.readouterr().out
    assert "note: " in out
    assert "without its index" in out
    frames = int(out.split("labeled ")[1].split(" frames")[0])
    assert 150 < frames < 345
    assert (tmp_path / "run" / "labels.yaml").is_file()


def rechunk(src: Path, dst: Path, chunk_bytes: int = 16 * 1024) -> Path:
    """``src`` (an MCAP file) written again by the ``mcap`` library in zstd chunks of ``chunk_bytes``, as a
    ROS 2 recorder writes (records unchanged)."""
    from mcap.reader import make_reader
    from mcap.writer import Writer

    with src.open("rb") as f, dst.open("wb") as out:
        reader = make_reader(f)
        header = reader.get_header()
        summary = reader.get_summary()
        assert summary is not None
        writer = Writer(out, chunk_size=chunk_bytes)
        writer.start(profile=header.profile, library=header.library)
        schemas = {i: writer.register_schema(s.name, s.encoding, s.data) for i, s in summary.schemas.items()}
        channels = {
            i: writer.register_channel(c.topic, c.message_encoding, schemas.get(c.schema_id, 0), c.metadata)
            for i, c in summary.channels.items()
        }
        for _schema, ch, msg in reader.iter_messages(log_time_order=False):
            writer.add_message(channels[ch.id], msg.log_time, msg.data, msg.publish_time, msg.sequence)
        writer.finish()
    return dst


def test_an_mcap_file_cut_short_gives_its_whole_messages_in_order(tmp_path):
    from studio.io import iter_frames, load_rig

    whole = rechunk(write_synthetic(tmp_path / "one_chunk.mcap"), tmp_path / "rec.mcap")
    with open_recording(whole) as rec:
        assert rec.notes == []
        expected = sorted((m.log_ns, m.topic, m.rawdata) for m in rec.messages())
    data = whole.read_bytes()
    got_counts = []
    for frac in (0.3, 0.7, 1.0):
        cut = tmp_path / f"cut_{frac}.mcap"
        cut.write_bytes(data[: int(len(data) * frac) - 30])  # at 1.0 only the footer is lost
        with open_recording(cut) as rec:
            assert len(rec.notes) == 1
            assert rec.notes[0].startswith(f"{cut}: an MCAP file without its summary")
            got = [(m.log_ns, m.topic, m.rawdata) for m in rec.messages()]
            assert [g[0] for g in got] == sorted(g[0] for g in got)  # in log-time order
            assert sorted(got) == expected[: len(got)]  # the first ones: nothing made up, nothing skipped
            assert sum(t.count for t in rec.topics.values()) == len(got)
            scan = rec.decode(next(rec.messages(["/scan_front"])))
            assert scan.ranges.shape == (45,)
            # a window (the viewer reads one frame's messages at a time) reads only its chunks
            a, b = got[len(got) // 3][0], got[len(got) // 2][0]
            window = [(m.log_ns, m.topic, m.rawdata) for m in rec.messages(start_ns=a, stop_ns=b)]
            assert window == [g for g in got if a <= g[0] < b]
        got_counts.append(len(got))
    assert 0 < got_counts[0] < got_counts[1] < got_counts[2] == len(expected)
    # and it labels: frames of the lasers and the camera as far as the file goes
    rig = tmp_path / "rig.yaml"
    rig.write_text(
        "base_frame: base_link\nodometry: {topic: /odom}\n"
        "camera: {topic: /camera/image/compressed}\nlasers: [{topic: /scan_front}, {topic: /scan_back}]\n"
    )
    with open_recording(tmp_path / "cut_0.7.mcap") as rec:
        frames = list(iter_frames(rec, load_rig(rig)))
    assert 0 < len(frames) < 40
    assert all(len(f.scans) == 2 for f in frames)


def test_an_mcap_file_with_no_whole_message_is_one_clear_error(tmp_path):
    data = write_synthetic(tmp_path / "rec.mcap").read_bytes()
    cut = tmp_path / "cut.mcap"
    cut.write_bytes(data[:60])
    with pytest.raises(RecordingError) as info:
        open_recording(cut)
    assert str(cut) in str(info.value)
    assert "\n" not in str(info.value)


def test_a_ros2_bag_folder_without_metadata_reads_its_mcap_file(tmp_path):
    """``ros2 bag record`` writes metadata.yaml when it stops; a crash leaves the folder without it."""
    whole = rechunk(write_synthetic(tmp_path / "one_chunk.mcap"), tmp_path / "rec.mcap")
    with open_recording(whole) as rec:
        expected = [(m.log_ns, m.topic) for m in rec.messages()]
    folder = tmp_path / "rosbag2_2026_12_05"
    folder.mkdir()
    data = whole.read_bytes()
    (folder / "rosbag2_2026_12_05_0.mcap").write_bytes(data[: len(data) // 2])
    with open_recording(folder) as rec:
        assert rec.notes[0] == (
            f"{folder}: a ROS 2 bag without metadata.yaml (its recording was interrupted): read its "
            "rosbag2_2026_12_05_0.mcap"
        )
        assert "without its summary" in rec.notes[1]
        got = [(m.log_ns, m.topic) for m in rec.messages()]
    assert 0 < len(got) < len(expected)
    # a split one (several files): what to do, in one line
    (folder / "rosbag2_2026_12_05_1.mcap").write_bytes(data)
    with pytest.raises(RecordingError, match=r"without metadata\.yaml .* in 2 files: run `ros2 bag reindex`"):
        open_recording(folder)


def test_a_ros2_sqlite3_bag_folder_without_metadata_reads_its_db3_file(tmp_path):
    """Humble's default storage: ``ros2 bag record`` stopped by a crash leaves its .db3 file alone."""
    from rosbags.highlevel import AnyReader
    from rosbags.rosbag2 import StoragePlugin, Writer
    from rosbags.typesys import Stores, get_typestore

    src = write_synthetic(tmp_path / "rec.mcap")
    folder = tmp_path / "rosbag2_db3"
    writer = Writer(folder, version=8, storage_plugin=StoragePlugin.SQLITE3)
    with AnyReader([src], default_typestore=get_typestore(Stores.ROS2_HUMBLE)) as reader:
        writer.open()
        conns = {
            c.id: writer.add_connection(c.topic, c.msgtype, typestore=reader.typestore)
            for c in reader.connections
        }
        expected = []
        for c, t, raw in reader.messages():
            writer.write(conns[c.id], t, raw)
            expected.append((t, c.topic))
        writer.close()
    (folder / "metadata.yaml").unlink()
    with open_recording(folder) as rec:
        note = f"{folder}: a ROS 2 bag without metadata.yaml (its recording was interrupted): read its "
        assert rec.notes == [note + "rosbag2_db3.db3"]
        assert sorted((m.log_ns, m.topic) for m in rec.messages()) == sorted(expected)
        assert rec.decode(next(rec.messages(["/scan_front"]))).ranges.shape == (45,)
    # the "resilient" preset writes through a write-ahead log: what is still in it is read from a merged copy
    import shutil
    import sqlite3

    db = folder / "rosbag2_db3.db3"
    con = sqlite3.connect(db)
    con.execute("PRAGMA journal_mode=WAL")
    con.execute("PRAGMA wal_autocheckpoint=0")
    con.execute(
        "insert into messages(topic_id, timestamp, data) select topic_id, timestamp + 10, data from messages"
    )
    con.commit()
    crashed = tmp_path / "crashed"
    crashed.mkdir()
    for f in folder.iterdir():
        shutil.copy(f, crashed / f.name)  # while the writer has it open, as a crash leaves it
    con.close()
    with open_recording(crashed) as rec:
        assert len(rec.notes) == 2
        assert rec.notes[1].startswith(
            f"{crashed / 'rosbag2_db3.db3-wal'}: its write-ahead log held messages"
        )
        assert sum(1 for _ in rec.messages()) == 2 * len(expected)  # those in the log too
        assert rec.decode(next(rec.messages(["/scan_front"]))).ranges.shape == (45,)
    # the recording itself is left as it was
    assert sorted(f.name for f in crashed.iterdir()) == [
        "rosbag2_db3.db3",
        "rosbag2_db3.db3-shm",
        "rosbag2_db3.db3-wal",
    ]


def test_a_cut_mcap_written_slightly_out_of_order_is_read_in_log_time_order(tmp_path):
    """A writer's order may stray from log time (several threads writing): the cut file is read sorted."""
    import json

    from mcap.writer import Writer

    stamps = [1_000_000_000 + 10_000_000 * (k + (3 if k % 4 == 0 else 0)) for k in range(400)]
    whole = tmp_path / "plain.mcap"
    with whole.open("wb") as f:
        w = Writer(f, chunk_size=2048)
        w.start(profile="", library="test")
        schema = w.register_schema("Thing", "jsonschema", b"{}")
        ch = w.register_channel("/thing", "json", schema)
        for k, t in enumerate(stamps):
            w.add_message(ch, t, json.dumps({"k": k}).encode(), t)
        w.finish()
    data = whole.read_bytes()
    cut = tmp_path / "cut.mcap"
    cut.write_bytes(data[: len(data) // 2])
    with open_recording(cut) as rec:
        got = [(m.log_ns, rec.decode(m).k) for m in rec.messages()]
    assert 100 < len(got) < 400
    assert [t for t, _ in got] == sorted(t for t, _ in got)
    assert sorted(k for _, k in got) == list(range(len(got)))  # the first ones written, each once


def test_ties_and_filters_come_out_as_rosbags_gives_them(tmp_path):
    """Several connections (two on one topic, one added half-way), equal and out-of-order stamps."""
    import random

    from rosbags.rosbag1 import Writer
    from rosbags.typesys import Stores, get_typestore

    store = get_typestore(Stores.ROS1_NOETIC)
    string = store.types["std_msgs/msg/String"]
    rng = random.Random(1)
    t0 = 1_000_000_000_000
    for compression in ("none", "bz2"):
        path = tmp_path / f"ties_{compression}.bag"
        w = Writer(path)
        if compression != "none":
            w.set_compression(Writer.CompressionFormat.BZ2)
        w.chunk_threshold = 300
        w.open()
        conns = {
            k: w.add_connection(t, "std_msgs/msg/String", typestore=store, callerid=k)
            for k, t in (("a", "/a"), ("b", "/b"), ("a2", "/a"))
        }
        for i in range(300):
            key = rng.choice(["a", "b", "a2"])
            t = t0 + rng.choice([i, i, i - 3, i + 5]) * 1000
            w.write(conns[key], t, store.serialize_ros1(string(data=f"{key}{i}"), "std_msgs/msg/String"))
            if i == 150:
                conns["c"] = w.add_connection("/c", "std_msgs/msg/String", typestore=store, callerid="c")
            if i > 150 and i % 7 == 0:
                w.write(
                    conns["c"],
                    t0 + i * 1000,
                    store.serialize_ros1(string(data=f"c{i}"), "std_msgs/msg/String"),
                )
        w.close()
        for args in ((None, None, None), (["/a"], None, None), (["/b", "/c"], t0 + 50_000, t0 + 200_000)):
            want = [(m.topic, m.log_ns, m.rawdata) for m in _RosbagsBackend([path], "ros1").messages(*args)]
            got = [(m.topic, m.log_ns, m.rawdata) for m in UnindexedRos1Backend([path]).messages(*args)]
            assert got == want


def test_a_split_recording_whose_last_bag_holds_nothing_yet_reads_the_others(tmp_path):
    """``rosbag record --split`` killed right after it opened the next bag: its header only."""
    folder = tmp_path / "split"
    folder.mkdir()
    whole = rewrite(bag("positive/positive_3.bag"), folder / "rec_0.bag")
    (folder / "rec_1.bag.active").write_bytes(whole.read_bytes()[:4200])
    with open_recording(folder) as rec:
        assert sum(1 for _ in rec.messages()) == 345
        assert rec.notes == [
            f"{folder / 'rec_1.bag.active'}: a ROS1 bag without its index (its recording was interrupted, "
            "or the file was cut short): 0 whole messages read from its chunks"
        ]


def test_a_ros2_bag_folder_whose_mcap_file_was_cut_short_is_read_as_far_as_it_goes(tmp_path):
    """metadata.yaml written (a recorder that writes it as it goes), its one .mcap cut short."""
    from studio.io import RecordingWriter

    folder = tmp_path / "ros2_bag"
    whole = rechunk(write_synthetic(tmp_path / "one_chunk.mcap"), tmp_path / "rec.mcap")
    with RecordingWriter(folder) as w:  # a ROS 2 bag folder of the same recording, for its metadata.yaml
        w.write_scan("/scan_front", make_scan(T0, "front_laser"))
    (mcap,) = folder.glob("*.mcap")
    data = whole.read_bytes()
    mcap.write_bytes(data[: len(data) // 2])
    with open_recording(folder) as rec:
        assert any("without its summary" in n for n in rec.notes)
        assert sum(1 for _ in rec.messages()) > 100
