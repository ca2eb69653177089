"""Read ROS1 bags that have no index: a ``rosbag record`` that did not finish (``.bag.active``: the robot's
battery ran out, the recorder was killed) or a bag cut short (copied while it was being recorded, a full
disk, a broken download).

A ROS1 bag (format 2.0) is a sequence of records, each a header (``name=value`` fields, among them the
``op`` code) and data. The messages lie in *chunk* records (possibly bz2 or lz4 compressed), each holding
connection records (topic, type, message definition) and message data records (connection id, receive
time, serialized message). The index that tells a reader where everything is (connection records and
chunk infos after the last chunk, and the bag header's ``index_pos``) is written last, when the recorder
closes the bag. Without it rosbags refuses the bag, and ``rosbag reindex`` needs a ROS1 installation,
which few machines still have.

:class:`UnindexedRos1Backend` does what ``rosbag reindex`` does, in memory: it scans the chunks one after
the other and keeps every message record that is whole (of a chunk the file ends in, the records before
the cut; of a compressed one, what its stream gives up to there). The messages are then read in
receive-time order across all chunks and bags. Types come from the bags' own message definitions, as
with rosbags' AnyReader, completed by the ROS1 Noetic type store.
"""

from __future__ import annotations

import bz2
import struct
from array import array
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np

from studio.io.base import RawMessage, TopicInfo
from studio.io.errors import RecordingError

__all__ = ["UnindexedRos1Backend", "is_unindexed_ros1"]

_MAGIC = b"#ROSBAG V2.0\n"
_OP_MSG_DATA, _OP_BAG_HEADER, _OP_CHUNK, _OP_CHUNK_INFO, _OP_CONNECTION = 0x02, 0x03, 0x05, 0x06, 0x07


def is_unindexed_ros1(path: Path) -> bool:
    """Whether ``path`` is a ROS1 bag (format 2.0) whose index is missing: its bag header has no index
    position, or the index position lies past the end of the file (the bag was cut short)."""
    try:
        with path.open("rb") as f:
            if f.read(len(_MAGIC)) != _MAGIC:
                return False
            header = _read_record(f)
            size = path.stat().st_size
    except OSError:
        return False
    if header is None or header[0].get("op") != bytes([_OP_BAG_HEADER]):
        return False
    index_pos = _uint(header[0].get("index_pos", b""))
    return index_pos is None or index_pos == 0 or index_pos >= size


def _uint(v: bytes) -> int | None:
    return int.from_bytes(v, "little") if len(v) in (4, 8) else None


def _fields(buf: bytes) -> dict[str, bytes] | None:
    """The ``name=value`` fields of a record header, or None when it is malformed."""
    out: dict[str, bytes] = {}
    pos = 0
    while pos < len(buf):
        if pos + 4 > len(buf):
            return None
        (n,) = struct.unpack_from("<I", buf, pos)
        pos += 4
        field = buf[pos : pos + n]
        if len(field) != n or b"=" not in field:
            return None
        name, value = field.split(b"=", 1)
        out[name.decode("latin-1")] = value
        pos += n
    return out


def _read_record(f: Any) -> tuple[dict[str, bytes], int, int] | None:
    """The next record of file ``f``: (header fields, data position, data length as written), with ``f``
    after the data; None at the end of the file or where the header is cut or malformed."""
    raw = f.read(4)
    if len(raw) < 4:
        return None
    (n,) = struct.unpack("<I", raw)
    buf = f.read(n)
    if len(buf) < n:
        return None
    fields = _fields(buf)
    raw = f.read(4)
    if fields is None or len(raw) < 4:
        return None
    (data_len,) = struct.unpack("<I", raw)
    pos = f.tell()
    f.seek(pos + data_len)
    return fields, pos, data_len


def _records(buf: bytes) -> Iterator[tuple[dict[str, bytes], int, int]]:
    """The whole records of a chunk's (uncompressed) data: (header fields, data offset, data length)."""
    pos = 0
    while pos + 4 <= len(buf):
        (n,) = struct.unpack_from("<I", buf, pos)
        if pos + 8 + n > len(buf):
            return
        fields = _fields(buf[pos + 4 : pos + 4 + n])
        (data_len,) = struct.unpack_from("<I", buf, pos + 4 + n)
        start = pos + 8 + n
        if fields is None or start + data_len > len(buf):
            return
        yield fields, start, data_len
        pos = start + data_len


def _inflate(compression: str, data: bytes) -> bytes:
    """A chunk's data, decompressed as far as it goes (a chunk the file ends in gives what precedes the
    cut)."""
    if compression == "none":
        return data
    if compression == "bz2":
        d = bz2.BZ2Decompressor()
    elif compression == "lz4":
        import lz4.frame

        d = lz4.frame.LZ4FrameDecompressor()
    else:
        raise RecordingError(f"unknown chunk compression '{compression}'")
    out = []
    step = 1 << 16
    try:
        for i in range(0, len(data), step):
            out.append(d.decompress(data[i : i + step]))
            if getattr(d, "eof", False):
                break
    except (OSError, EOFError, RuntimeError, ValueError):  # the cut, or garbage after it
        pass
    return b"".join(out)


class _Scan:
    """What the chunks of the bags hold: connections, message definitions, and where each message lies."""

    def __init__(self) -> None:
        from rosbags.typesys.msg import normalize_msgtype

        self._normalize = normalize_msgtype
        self.chunks: list[tuple[int, int, int, str]] = []  # (bag, data position, data length, compression)
        self.conns: dict[tuple[int, int], tuple[str, str]] = {}  # (bag, conn id) -> (topic, msgtype)
        self.defs: dict[str, str] = {}  # msgtype -> message definition
        self.cols = {k: array("q") for k in ("stamp", "chunk", "offset", "length", "bag", "conn")}
        self.per_bag: list[int] = []
        self.indexed: list[bool] = []  # per bag: its index (chunk info records) was there

    def bag(self, b: int, f: Any, size: int) -> None:
        """Scan bag ``b`` (file ``f`` after its magic line, ``size`` bytes long)."""
        count, indexed = 0, False
        while (rec := _read_record(f)) is not None:
            fields, pos, data_len = rec
            op = fields.get("op", b"\xff")[:1]
            indexed |= op == bytes([_OP_CHUNK_INFO])
            if op == bytes([_OP_CONNECTION]):
                self._connection(b, fields, _read_at(f, pos, data_len))
            if op != bytes([_OP_CHUNK]):
                continue
            # an unterminated chunk (its length never written) runs to the end of the file
            n = data_len if data_len > 0 else size - pos
            compression = fields.get("compression", b"none").decode("latin-1")
            data = _inflate(compression, _read_at(f, pos, n))
            self.chunks.append((b, pos, n, compression))
            for rf, start, dlen in _records(data):
                rop = rf.get("op", b"\xff")[:1]
                if rop == bytes([_OP_CONNECTION]):
                    self._connection(b, rf, data[start : start + dlen])
                elif rop == bytes([_OP_MSG_DATA]) and len(rf.get("time", b"")) == 8 and "conn" in rf:
                    sec, nsec = struct.unpack("<II", rf["time"])
                    row = (
                        sec * 1_000_000_000 + nsec,
                        len(self.chunks) - 1,
                        start,
                        dlen,
                        b,
                        _uint(rf["conn"]),
                    )
                    for col, v in zip(self.cols.values(), row, strict=True):
                        col.append(-1 if v is None else v)
                    count += 1
            if data_len == 0 or pos + data_len > size:
                break  # the file ends in this chunk
        self.per_bag.append(count)
        self.indexed.append(indexed)

    def _connection(self, b: int, fields: dict[str, bytes], data: bytes) -> None:
        conn = _uint(fields.get("conn", b""))
        info = _fields(data)
        if conn is None or info is None or "type" not in info:
            return
        topic = (info.get("topic") or fields.get("topic", b"")).decode("utf-8", "replace")
        msgtype = self._normalize(info["type"].decode("utf-8", "replace"))
        self.conns.setdefault((b, conn), (topic, msgtype))
        text = info.get("message_definition", b"").decode("utf-8", "replace")
        if text.strip():
            self.defs.setdefault(msgtype, text)


class UnindexedRos1Backend:
    """The messages of ROS1 bags without an index (see the module docstring), merged in receive-time order.

    Attributes:
        topics: topic name → :class:`TopicInfo`.
        start_ns, end_ns: receive times of the first and last message, ns (0 when there is none).
        recovered: per bag, how many messages were read.
        notes: one line for each bag that had no index.
    """

    def __init__(self, paths: list[Path]) -> None:
        from rosbags.typesys import Stores, get_typestore
        from rosbags.typesys.msg import get_types_from_msg

        self._files = [p.open("rb") for p in paths]
        try:
            scan = _Scan()
            for b, f in enumerate(self._files):
                if f.read(len(_MAGIC)) != _MAGIC:
                    raise RecordingError(f"{paths[b]}: not a ROS1 bag of format 2.0")
                scan.bag(b, f, paths[b].stat().st_size)
            self._chunks = scan.chunks
            names = sorted(set(scan.conns.values()))
            index = {tm: i for i, tm in enumerate(names)}
            cols = {k: np.frombuffer(v, dtype=np.int64) for k, v in scan.cols.items()}
            # each message's connection as an index into names (-1: its connection record was lost)
            key = cols["bag"] * (1 << 32) + cols["conn"]
            uniq, inverse = np.unique(key, return_inverse=True)
            lut = np.array(
                [index.get(scan.conns.get((int(k) >> 32, int(k) & 0xFFFFFFFF), ("", "")), -1) for k in uniq],
                dtype=np.int64,
            )
            conn = lut[inverse.reshape(-1)] if len(key) else np.zeros(0, dtype=np.int64)
            keep = np.flatnonzero(conn >= 0)  # messages on a connection whose record was lost are left out
            # by receive time, ties as rosbags breaks them: bag by bag, connection by connection
            order = keep[np.lexsort((cols["conn"][keep], cols["bag"][keep], cols["stamp"][keep]))]
            per_bag = np.bincount(cols["bag"][keep], minlength=len(paths))
            self.recovered = [int(n) for n in per_bag]
            if not len(keep):
                raise RecordingError(f"{paths[0]}: a ROS1 bag without its index, and no whole message in it")
            self.notes = [
                f"{path}: a ROS1 bag without its index (its recording was interrupted, or the file was cut "
                f"short): {n} whole messages read from its chunks"
                for path, n, indexed in zip(paths, self.recovered, scan.indexed, strict=True)
                if not indexed
            ]
            self._conn_names = names
            self._stamp, self._chunk = cols["stamp"][order], cols["chunk"][order]
            self._offset, self._length, self._conn = cols["offset"][order], cols["length"][order], conn[order]
            counts = np.bincount(self._conn, minlength=len(names))
            self.topics: dict[str, TopicInfo] = {}
            for i, (topic, msgtype) in enumerate(self._conn_names):
                prev = self.topics.get(topic)
                self.topics[topic] = TopicInfo(topic, msgtype, int(counts[i]) + (prev.count if prev else 0))
            self.start_ns = int(self._stamp[0]) if len(self._stamp) else 0
            self.end_ns = int(self._stamp[-1]) if len(self._stamp) else 0
            store = get_typestore(Stores.EMPTY)
            types: dict[str, Any] = {}
            for msgtype, text in scan.defs.items():
                try:
                    types.update(get_types_from_msg(text, msgtype))
                except Exception:  # a definition rosbags cannot parse: the default store may know the type
                    continue
            store.register(types)
            default = get_typestore(Stores.ROS1_NOETIC)
            store.register({k: v for k, v in default.fielddefs.items() if k not in store.fielddefs})
            self._store = store
        except BaseException:
            self.close()
            raise

    def messages(
        self, topics: list[str] | None, start_ns: int | None, stop_ns: int | None
    ) -> Iterator[RawMessage]:
        wanted = np.ones(len(self._conn_names), dtype=bool)
        if topics is not None:
            wanted = np.array([t in topics for t, _ in self._conn_names], dtype=bool)
        sel = wanted[self._conn] if len(self._conn) else np.zeros(0, dtype=bool)
        if start_ns is not None:
            sel &= self._stamp >= start_ns
        if stop_ns is not None:
            sel &= self._stamp < stop_ns
        rows = np.flatnonzero(sel)
        if not len(rows):
            return
        # each chunk is decompressed once and let go after its last message in this order
        last = {int(c): k for k, c in enumerate(self._chunk[rows])}
        cache: dict[int, bytes] = {}
        for k, r in enumerate(rows):
            c = int(self._chunk[r])
            if c not in cache:
                b, pos, n, compression = self._chunks[c]
                cache[c] = _inflate(compression, _read_at(self._files[b], pos, n))
            data = cache[c]
            topic, msgtype = self._conn_names[int(self._conn[r])]
            o = int(self._offset[r])
            yield RawMessage(topic, msgtype, int(self._stamp[r]), data[o : o + int(self._length[r])])
            if last[c] == k:
                del cache[c]

    def decode(self, raw: RawMessage) -> Any:
        return self._store.deserialize_ros1(raw.rawdata, raw.msgtype)

    def close(self) -> None:
        for f in self._files:
            f.close()
        self._files = []


def _read_at(f: Any, pos: int, n: int) -> bytes:
    here = f.tell()
    f.seek(pos)
    data: bytes = f.read(n)
    f.seek(here)
    return data
