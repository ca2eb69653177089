"""Plain (non-ROS-profile) MCAP files, read with the ``mcap`` library.

What is decoded, per channel ``message_encoding``:

* ``json`` — the JSON document becomes nested attribute objects (:class:`types.SimpleNamespace`), so the
  decoders of :mod:`studio.io.decode` see ROS-shaped messages (``header.stamp.sec``, ``ranges`` …) or
  Foxglove-shaped ones (``foxglove.LaserScan``, ``foxglove.CompressedImage`` with base64 ``data``,
  ``foxglove.RawImage``, ``foxglove.FrameTransform(s)``, ``foxglove.PoseInFrame``) exactly as with a bag;
* ``cdr`` with a ``ros2msg`` / ``ros2idl`` schema and ``ros1`` with a ``ros1msg`` schema — deserialized with
  ``rosbags`` from the schema embedded in the file (e.g. an MCAP written by a ROS tool with another
  profile);
* anything else (protobuf, flatbuffer, schemaless CDR) is listed by ``inspect`` but cannot be decoded:
  :meth:`McapBackend.decode` raises and the caller reports it.

A file cut short (its recorder stopped before it wrote the summary and footer, or a broken copy) is read
record by record with ``mcap``'s stream reader, up to the cut, and the messages come in log-time order (put
back in it where the writer's order strays by up to ``_REORDER`` messages or 64 MB of them);
:attr:`McapBackend.notes` says so. ROS 2 MCAP files that rosbags cannot open for that reason are read this
way as well (``studio.io.reader``).
"""

from __future__ import annotations

import heapq
import json
from collections.abc import Iterator
from pathlib import Path
from types import SimpleNamespace
from typing import Any, BinaryIO

from studio.io.base import RawMessage, TopicInfo
from studio.io.errors import RecordingError

__all__ = ["McapBackend", "json_to_namespace"]

# messages of a cut file are put back in log-time order up to this many places, or this many bytes of them
_REORDER, _REORDER_BYTES = 4096, 64 << 20


def json_to_namespace(value: Any) -> Any:
    """Nested dicts → :class:`SimpleNamespace` (lists kept as lists), for attribute access."""
    if isinstance(value, dict):
        return SimpleNamespace(**{str(k): json_to_namespace(v) for k, v in value.items()})
    if isinstance(value, list):
        return [json_to_namespace(v) for v in value]
    return value


class McapBackend:
    """Reads a non-ROS MCAP file (see the module docstring for what decodes)."""

    def __init__(self, path: Path) -> None:
        from mcap.reader import make_reader

        self.path = path
        self._file: BinaryIO | None = path.open("rb")
        self.notes: list[str] = []
        self._cut = False  # the file ends before its summary and footer: read record by record
        # a cut file's chunks (and messages outside chunks): (file offset, first and last log time, ns)
        self._pieces: list[tuple[int, int, int]] | None = None
        self._schemas: dict[int, Any] = {}
        self._chans: dict[int, Any] = {}
        try:
            self.reader = make_reader(self._file)
            try:
                summary = self.reader.get_summary()
            except Exception as exc:
                self._cut, summary = True, None
                self._scan_cut(exc)
                return
            self._channels: dict[str, tuple[str, str, str, bytes]] = {}  # topic → (msg enc, name, enc, data)
            counts: dict[str, int] = {}
            start = end = 0
            if summary is not None and summary.statistics is not None:
                for ch in summary.channels.values():
                    self._add_channel(ch, summary.schemas.get(ch.schema_id))
                    counts[ch.topic] = counts.get(ch.topic, 0) + int(
                        summary.statistics.channel_message_counts.get(ch.id, 0)
                    )
                if summary.statistics.message_count:
                    start = int(summary.statistics.message_start_time)
                    end = int(summary.statistics.message_end_time)
            else:  # no summary: one scan over the file for the counts
                first = True
                for schema, ch, msg in self.reader.iter_messages(log_time_order=False):
                    if ch.topic not in self._channels:
                        self._add_channel(ch, schema)
                    counts[ch.topic] = counts.get(ch.topic, 0) + 1
                    t = int(msg.log_time)
                    start, end = (t, t) if first else (min(start, t), max(end, t))
                    first = False
            self.topics = {
                t: TopicInfo(t, self._channels[t][1], counts.get(t, 0)) for t in sorted(self._channels)
            }
            self.start_ns, self.end_ns = start, end
            self._typestore: Any = None
            self._registered: set[str] = set()
        except BaseException:
            self.close()
            raise

    def _scan_cut(self, error: Exception) -> None:
        """Channels, counts and span of a file cut short (its recorder stopped before it wrote the
        summary and footer, or a broken copy): one pass over its whole records."""
        counts: dict[str, int] = {}
        first, last = 2**63, -1
        for _schema, ch, msg in self._records(None):
            counts[ch.topic] = counts.get(ch.topic, 0) + 1
            first, last = min(first, int(msg.log_time)), max(last, int(msg.log_time))
        if last < 0:
            reason = " ".join(str(error).split()) or type(error).__name__
            raise RecordingError(f"{self.path}: no whole message in the file ({reason[:200]})")
        self._channels = {}
        for ch, schema in self._cut_channels.values():
            self._add_channel(ch, schema)
        self.topics = {
            t: TopicInfo(t, self._channels[t][1], counts.get(t, 0)) for t in sorted(self._channels)
        }
        self.start_ns, self.end_ns = first, last
        self._typestore = None
        self._registered = set()
        self.notes.append(
            f"{self.path}: an MCAP file without its summary (its recording was interrupted, or the file was "
            f"cut short): {sum(counts.values())} whole messages read"
        )

    def _records(
        self, topics: list[str] | None, start_ns: int | None = None, stop_ns: int | None = None
    ) -> Iterator[tuple[Any, Any, Any]]:
        """(schema, channel, message) of the whole records of a cut file, in file order, up to the cut.

        The first call reads the whole file and notes where each chunk (or message outside chunks) lies
        and the log times it spans; later calls read only the pieces that overlap ``[start_ns, stop_ns)``
        (the viewer asks for one frame's messages at a time)."""
        from mcap.records import Channel, Chunk, Message, Schema
        from mcap.stream_reader import StreamReader, breakup_chunk

        f = self._file
        assert f is not None
        first = self._pieces is None
        if first:
            self._pieces, self._schemas, self._chans = [], {}, {}
            self._cut_channels: dict[str, tuple[Any, Any]] = {}
            f.seek(0)
            records = StreamReader(f, emit_chunks=True).records
            where = [f.tell()]
        else:
            assert self._pieces is not None
            where = [
                at
                for at, t0, t1 in self._pieces
                if (start_ns is None or t1 >= start_ns) and (stop_ns is None or t0 < stop_ns)
            ]
        for at in where:
            if not first:
                f.seek(at)
                records = StreamReader(f, skip_magic=True, emit_chunks=True).records
            while True:
                here = f.tell()
                try:
                    record = next(records)
                    inner = list(breakup_chunk(record)) if isinstance(record, Chunk) else [record]
                except StopIteration:
                    break
                except Exception:  # the cut: a record, chunk or its compression ends there
                    return
                if first and isinstance(record, Chunk):
                    self._pieces.append((here, record.message_start_time, record.message_end_time))
                elif first and isinstance(record, Message):
                    self._pieces.append((here, record.log_time, record.log_time))
                for r in inner:
                    if isinstance(r, Schema):
                        self._schemas[r.id] = r
                    elif isinstance(r, Channel):
                        self._chans[r.id] = r
                        self._cut_channels.setdefault(r.topic, (r, self._schemas.get(r.schema_id)))
                    elif isinstance(r, Message) and r.channel_id in self._chans:
                        ch = self._chans[r.channel_id]
                        if topics is None or ch.topic in topics:
                            yield self._schemas.get(ch.schema_id), ch, r
                if not first:
                    break  # one piece

    def _add_channel(self, channel: Any, schema: Any) -> None:
        if schema is None:
            self._channels[channel.topic] = (channel.message_encoding, "", "", b"")
        else:
            self._channels[channel.topic] = (
                channel.message_encoding,
                str(schema.name),
                str(schema.encoding),
                bytes(schema.data),
            )

    def messages(
        self, topics: list[str] | None, start_ns: int | None, stop_ns: int | None
    ) -> Iterator[RawMessage]:
        if self._cut:
            yield from self._cut_messages(topics, start_ns, stop_ns)
            return
        for _schema, ch, msg in self.reader.iter_messages(
            topics=topics, starting_at=start_ns, ending_before=stop_ns
        ):
            name = self._channels.get(ch.topic, ("", "", "", b""))[1]
            yield RawMessage(ch.topic, name, int(msg.log_time), bytes(msg.data))

    def _cut_messages(
        self, topics: list[str] | None, start_ns: int | None, stop_ns: int | None
    ) -> Iterator[RawMessage]:
        """The messages of a cut file in log-time order: a recorder writes them in about that order, and
        those up to ``_REORDER`` places (or ``_REORDER_BYTES``) out of it are put back in it."""
        heap: list[tuple[int, int, RawMessage]] = []
        held = 0  # bytes of the messages in the heap
        for n, (_schema, ch, msg) in enumerate(self._records(topics, start_ns, stop_ns)):
            t = int(msg.log_time)
            if (start_ns is not None and t < start_ns) or (stop_ns is not None and t >= stop_ns):
                continue
            name = self._channels.get(ch.topic, ("", "", "", b""))[1]
            heapq.heappush(heap, (t, n, RawMessage(ch.topic, name, t, bytes(msg.data))))
            held += len(msg.data)
            while len(heap) > _REORDER or held > _REORDER_BYTES:
                out = heapq.heappop(heap)[2]
                held -= len(out.rawdata)
                yield out
        while heap:
            yield heapq.heappop(heap)[2]

    def _ros_type(self, name: str, schema_enc: str, schema_data: bytes) -> str:
        from rosbags.typesys import Stores, get_types_from_idl, get_types_from_msg, get_typestore

        if self._typestore is None:
            self._typestore = get_typestore(Stores.EMPTY)
        typename = name if "/msg/" in name else name.replace("/", "/msg/", 1)
        if typename not in self._registered:
            text = schema_data.decode("utf-8")
            if schema_enc == "ros2idl":
                types = get_types_from_idl(text)
            else:
                types = get_types_from_msg(text, typename)
            new = {k: v for k, v in types.items() if k not in self._typestore.fielddefs}
            if new:
                self._typestore.register(new)
            self._registered.add(typename)
        return typename

    def decode(self, raw: RawMessage) -> Any:
        msg_enc, name, schema_enc, schema_data = self._channels.get(raw.topic, ("", "", "", b""))
        if msg_enc == "json":
            return json_to_namespace(json.loads(raw.rawdata))
        if msg_enc == "cdr" and schema_enc in ("ros2msg", "ros2idl"):
            return self._typestore_of(name, schema_enc, schema_data).deserialize_cdr(
                raw.rawdata, self._ros_type(name, schema_enc, schema_data)
            )
        if msg_enc == "ros1" and schema_enc == "ros1msg":
            return self._typestore_of(name, schema_enc, schema_data).deserialize_ros1(
                raw.rawdata, self._ros_type(name, schema_enc, schema_data)
            )
        raise RecordingError(
            f"{self.path}: topic {raw.topic} uses message encoding '{msg_enc}' with schema encoding "
            f"'{schema_enc}', which studio cannot decode "
            "(supported: json, cdr + ros2msg/ros2idl, ros1 + ros1msg)"
        )

    def _typestore_of(self, name: str, schema_enc: str, schema_data: bytes) -> Any:
        self._ros_type(name, schema_enc, schema_data)
        return self._typestore

    def close(self) -> None:
        f, self._file = self._file, None
        if f is not None:
            f.close()
