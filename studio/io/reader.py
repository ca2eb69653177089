"""Open a recording and read its raw records: ROS1 ``.bag`` (one, or a folder of them), ROS2 (folder,
``.db3``, ``.mcap``), plain MCAP.

ROS bags are read with ``rosbags``' AnyReader. ROS1 bags carry their own message definitions (custom types
included); ROS2 bags that carry none are decoded with the ROS2 Humble type store (types missing from a
bag's own definitions are taken from it too). A folder of ROS1 bags (``rosbag record --split``, or one bag
per sensor recorded side by side) is one recording: its bags' messages are merged in log-time order and a
topic in several bags is one topic. An ``.mcap`` file whose profile is not ``ros2`` is read
with the ``mcap`` library (see :mod:`studio.io.mcap_backend`).

Reading yields :class:`~studio.io.base.RawMessage` records in log-time order; decoding is a separate
step (:meth:`Recording.decode`, then :mod:`studio.io.decode`).
"""

from __future__ import annotations

import os
import re
from collections.abc import Iterable, Iterator
from pathlib import Path
from types import TracebackType
from typing import Any, Literal, Protocol

from studio.io.base import RawMessage, TopicInfo
from studio.io.errors import RecordingError

__all__ = ["Recording", "open_recording"]

Kind = Literal["ros1", "ros2", "mcap"]


class _Backend(Protocol):
    topics: dict[str, TopicInfo]
    start_ns: int
    end_ns: int

    def messages(
        self, topics: list[str] | None, start_ns: int | None, stop_ns: int | None
    ) -> Iterator[RawMessage]: ...

    def decode(self, raw: RawMessage) -> Any: ...

    def close(self) -> None: ...


def _reason(exc: BaseException) -> str:
    text = " ".join(str(a) for a in exc.args) if exc.args else ""
    text = " ".join((text or type(exc).__name__).split())
    return text[:300]


class _RosbagsBackend:
    """ROS1 / ROS2 bags through rosbags' AnyReader."""

    def __init__(self, paths: list[Path], kind: Kind) -> None:
        from rosbags.highlevel import AnyReader
        from rosbags.typesys import Stores, get_typestore

        store = get_typestore(Stores.ROS1_NOETIC if kind == "ros1" else Stores.ROS2_HUMBLE)
        self.reader = AnyReader(paths, default_typestore=store)
        try:
            self.reader.open()
        except Exception:
            if len(paths) > 1:
                _name_the_bad_bag(paths, store)
            raise
        try:
            self._complete_types(store)
            self.topics: dict[str, TopicInfo] = {}
            self._conns: dict[str, list[Any]] = {}
            for conn in self.reader.connections:
                self._conns.setdefault(conn.topic, []).append(conn)
            for name, conns in sorted(self._conns.items()):
                self.topics[name] = TopicInfo(name, conns[0].msgtype, sum(int(c.msgcount) for c in conns))
            count = sum(t.count for t in self.topics.values())
            self.start_ns = int(self.reader.start_time) if count else 0
            # rosbags' end_time is one past the last message
            self.end_ns = int(self.reader.end_time) - 1 if count else 0
            self.notes = _far_apart(self.reader.readers)
        except BaseException:
            self.close()
            raise

    def _complete_types(self, store: Any) -> None:
        """Register default types for connections whose type the bag did not define."""
        ts = self.reader.typestore
        missing = [c.msgtype for c in self.reader.connections if c.msgtype not in ts.fielddefs]
        if not missing:
            return
        extra = {k: v for k, v in store.fielddefs.items() if k not in ts.fielddefs}
        if extra:
            ts.register(extra)

    def messages(
        self, topics: list[str] | None, start_ns: int | None, stop_ns: int | None
    ) -> Iterator[RawMessage]:
        if topics is None:
            conns: list[Any] = []
        else:
            conns = [c for t in topics for c in self._conns.get(t, [])]
            if not conns:
                return
        for conn, log_ns, raw in self.reader.messages(connections=conns, start=start_ns, stop=stop_ns):
            yield RawMessage(conn.topic, conn.msgtype, int(log_ns), bytes(raw))

    def decode(self, raw: RawMessage) -> Any:
        return self.reader.deserialize(raw.rawdata, raw.msgtype)

    def close(self) -> None:
        if self.reader.stack is not None:
            self.reader.close()


FAR_APART_S = 600.0
"""Bags of one folder whose messages lie more than this apart (seconds) are probably not one recording."""


def _far_apart(readers: Iterable[Any]) -> list[str]:
    """A note where the bags read as one recording (a folder of them) follow each other after a long
    pause: a split recording's pieces, or bags of sensors recorded side by side, do not; unrelated bags put
    in one folder do, and their merged timeline is mostly empty."""
    spans = sorted(
        (int(r.start_time), int(r.end_time), Path(r.path).name) for r in readers if int(r.message_count) > 0
    )
    notes, end, last = [], None, ""
    for start, stop, name in spans:
        if end is not None and (start - end) / 1e9 > FAR_APART_S:
            notes.append(
                f"{name} begins {_duration((start - end) / 1e9)} after {last} ends: the folder's bags are "
                "read as one recording; are they one?"
            )
        if end is None or stop > end:
            end, last = stop, name
    return notes


def _duration(seconds: float) -> str:
    for unit, size in (("days", 86400.0), ("h", 3600.0), ("min", 60.0)):
        if seconds >= size:
            return f"{seconds / size:.1f} {unit}"
    return f"{seconds:.0f} s"


def _ros1_backend(files: list[Path]) -> _Backend:
    """rosbags' reader for indexed bags; where a bag has no index (an unfinished or cut-short recording) or
    rosbags cannot read its index, every whole message of the bags' chunks
    (:mod:`studio.io.ros1_unindexed`), when there is one."""
    from studio.io.ros1_unindexed import UnindexedRos1Backend, is_unindexed_ros1

    if not any(is_unindexed_ros1(f) for f in files):
        try:
            return _RosbagsBackend(files, "ros1")
        except Exception as exc:
            error = exc
    else:
        error = None
    try:
        backend = UnindexedRos1Backend(files)
    except Exception:
        if error is not None:
            raise error from None
        raise
    if not backend.topics:
        backend.close()
        if error is not None:
            raise error
        raise RecordingError(f"{files[0]}: no whole message in the bag")
    if error is not None and not backend.notes:
        backend.notes.append(
            f"{', '.join(map(str, files))}: read from its chunks: rosbags could not read its index (its "
            f"recording was interrupted, or the file was cut short?): {_reason(error)}"
        )
    return backend


def _ros2_mcap_backend(path: Path) -> _Backend:
    """rosbags' reader for a ROS 2 MCAP file; one cut short (no summary and footer: the recorder stopped
    before it wrote them, or a broken copy) is read record by record with the ``mcap`` library instead
    (:class:`studio.io.mcap_backend.McapBackend`, which decodes its CDR messages with rosbags)."""
    from studio.io.mcap_backend import McapBackend

    try:
        return _RosbagsBackend([path], "ros2")
    except Exception as exc:
        error = exc
    try:
        backend = McapBackend(path)
    except Exception:
        raise error from None
    if not backend.notes:  # the mcap library reads what rosbags could not, summary and all
        backend.notes.append(
            f"{path}: read with the mcap library: rosbags could not read it (its recording was "
            f"interrupted, or the file was cut short?): {_reason(error)}"
        )
    return backend


def _wal_of(db3: Path) -> Path | None:
    """The non-empty write-ahead log beside a ``.db3`` file (rosbag2's "resilient" storage preset writes
    through one; a recording stopped by a crash leaves messages in it), or None."""
    wal = db3.with_name(db3.name + "-wal")
    return wal if wal.is_file() and wal.stat().st_size > 0 else None


class _Db3WithWal:
    """A ``.db3`` file whose write-ahead log still holds messages: read from a temporary copy into which
    sqlite merged the log (the recording itself is not written to; rosbags opens databases read-only and
    would not see the log), deleted on close."""

    def __init__(self, db3: Path) -> None:
        import shutil
        import sqlite3
        import tempfile

        wal = _wal_of(db3)
        self._tmp = Path(tempfile.mkdtemp(prefix="studio-db3-"))
        try:
            copy = self._tmp / db3.name
            for suffix in ("", "-wal", "-shm"):
                src = db3.with_name(db3.name + suffix)
                if src.is_file():
                    shutil.copyfile(src, self._tmp / src.name)
            con = sqlite3.connect(copy)
            try:
                con.execute("PRAGMA wal_checkpoint(TRUNCATE)")
            finally:
                con.close()
            self._inner = _RosbagsBackend([copy], "ros2")
        except BaseException:
            shutil.rmtree(self._tmp, ignore_errors=True)
            raise
        self.topics, self.start_ns, self.end_ns = self._inner.topics, self._inner.start_ns, self._inner.end_ns
        self.notes = [
            f"{wal}: its write-ahead log held messages not yet in {db3.name} (its recording was "
            "interrupted): read from a temporary copy with the log merged in"
        ]

    def messages(
        self, topics: list[str] | None, start_ns: int | None, stop_ns: int | None
    ) -> Iterator[RawMessage]:
        return self._inner.messages(topics, start_ns, stop_ns)

    def decode(self, raw: RawMessage) -> Any:
        return self._inner.decode(raw)

    def close(self) -> None:
        import shutil

        self._inner.close()
        shutil.rmtree(self._tmp, ignore_errors=True)


def _ros2_folder_backend(folder: Path) -> _Backend:
    """rosbags' reader for a ROS 2 bag folder; when it cannot open one whose only storage file is an MCAP
    file (cut short: the recorder stopped before it finished it), that file as :func:`_ros2_mcap_backend`
    reads it."""
    try:
        return _RosbagsBackend([folder], "ros2")
    except Exception:
        mcaps = sorted(folder.glob("*.mcap"))
        if len(mcaps) != 1 or any(folder.glob("*.db3")):
            raise
    return _ros2_mcap_backend(mcaps[0])


def _name_the_bad_bag(paths: list[Path], store: Any) -> None:
    """Raises :class:`RecordingError` naming the first of ``paths`` (ROS1 bags) that cannot be opened alone;
    returns when each can (the error is then in how they go together)."""
    from rosbags.highlevel import AnyReader

    for path in paths:
        try:
            with AnyReader([path], default_typestore=store):
                pass
        except Exception as exc:
            raise RecordingError(
                f"{path}: cannot open this bag of the recording (truncated or corrupt?): {_reason(exc)}"
            ) from exc


def _unfinished_ros2(folder: Path) -> Path | None:
    """The one storage file (``.mcap`` or ``.db3``) of a ROS 2 bag folder that has no ``metadata.yaml``
    (``ros2 bag record`` writes it when it stops: one stopped by a crash or a power cut leaves none), or None
    when the folder holds ROS1 bags or no ROS 2 storage file.

    Raises:
        RecordingError: several storage files (a split recording: their order is in the metadata).
    """
    if any(f.name.endswith((".bag", ".bag.active")) for f in folder.iterdir()):
        return None
    files = sorted(f for f in folder.iterdir() if f.suffix in (".mcap", ".db3") and f.is_file())
    if len(files) > 1:
        raise RecordingError(
            f"{folder}: a ROS 2 bag without metadata.yaml (its recording was interrupted) in "
            f"{len(files)} files: run `ros2 bag reindex` on it, or pass one of its files"
        )
    return files[0] if files else None


def _ros1_bags(folder: Path) -> list[Path]:
    """The ROS1 bags of a folder recording, in name order (``run_2.bag`` before ``run_10.bag``), a bag
    ``rosbag record`` did not finish (``.bag.active``) included.

    Raises:
        RecordingError: no bags.
    """
    bags = [f for f in folder.iterdir() if f.is_file() and f.name.endswith((".bag", ".bag.active"))]
    if not bags:
        raise RecordingError(
            f"{folder}: a folder recording must be a ROS2 bag (with metadata.yaml) or hold ROS1 .bag files"
        )
    return sorted(bags, key=lambda f: [int(t) if t.isdigit() else t for t in re.split(r"(\d+)", f.name)])


class Recording:
    """An open recording. Use as a context manager (or call :meth:`close`).

    Attributes:
        path: the file or directory.
        files: the ROS1 bags of a folder of them, else ``(path,)``.
        kind: ``"ros1"``, ``"ros2"`` or ``"mcap"`` (plain, non-ROS MCAP).
        topics: topic name → :class:`TopicInfo` (type and message count).
        start_ns: log time of the first message, ns (0 when empty).
        end_ns: log time of the last message, ns (0 when empty).
        notes: what a user should know about how it was read (an unfinished or cut-short file read as far
            as it goes).
    """

    def __init__(self, path: Path, kind: Kind, backend: _Backend, files: tuple[Path, ...] = ()) -> None:
        self.path = path
        self.files: tuple[Path, ...] = files or (path,)
        self.kind: Kind = kind
        self._backend: _Backend | None = backend
        self.topics: dict[str, TopicInfo] = dict(backend.topics)
        self.start_ns: int = backend.start_ns
        self.end_ns: int = backend.end_ns
        self.notes: list[str] = list(getattr(backend, "notes", []))

    def __repr__(self) -> str:
        return f"Recording({str(self.path)!r}, kind={self.kind!r}, topics={len(self.topics)})"

    def __enter__(self) -> Recording:
        return self

    def __exit__(
        self, exc_type: type[BaseException] | None, exc: BaseException | None, tb: TracebackType | None
    ) -> None:
        self.close()

    def close(self) -> None:
        """Release the file (idempotent)."""
        backend, self._backend = self._backend, None
        if backend is not None:
            backend.close()

    @property
    def duration_ns(self) -> int:
        return max(0, self.end_ns - self.start_ns)

    def _open_backend(self) -> _Backend:
        if self._backend is None:
            raise RecordingError(f"{self.path}: recording is closed")
        return self._backend

    def resolve_topic(self, name: str) -> str:
        """The recording's spelling of topic ``name`` (a leading ``/`` may differ, as in old ROS1 bags).

        Raises:
            RecordingError: no such topic; the message lists the topics the recording has.
        """
        if name in self.topics:
            return name
        alt = name.lstrip("/")
        for cand in (alt, "/" + alt):
            if cand in self.topics:
                return cand
        have = ", ".join(f"{t} ({i.msgtype})" for t, i in self.topics.items()) or "none"
        raise RecordingError(f"{self.path}: no topic '{name}' in the recording (it has: {have})")

    def has_topic(self, name: str) -> bool:
        try:
            self.resolve_topic(name)
        except RecordingError:
            return False
        return True

    def messages(
        self,
        topics: Iterable[str] | None = None,
        *,
        start_ns: int | None = None,
        stop_ns: int | None = None,
    ) -> Iterator[RawMessage]:
        """Raw records in log-time order.

        Args:
            topics: topics to read (spelling as in :meth:`resolve_topic`); None reads every topic.
            start_ns: only records logged at or after this time, ns.
            stop_ns: only records logged before this time, ns.

        Raises:
            RecordingError: an unknown topic, or the file turns out unreadable while reading.
        """
        backend = self._open_backend()
        names = None if topics is None else sorted({self.resolve_topic(t) for t in topics})
        it = backend.messages(names, start_ns, stop_ns)
        while True:
            try:
                raw = next(it)
            except StopIteration:
                return
            except RecordingError:
                raise
            except Exception as exc:
                raise RecordingError(
                    f"{self.path}: cannot read the recording (truncated or corrupt?): {_reason(exc)}"
                ) from exc
            yield raw

    def decode(self, raw: RawMessage) -> Any:
        """Deserialize a raw record into a message object (ROS field names; plain MCAP JSON as attributes).

        Raises:
            RecordingError: the record cannot be deserialized.
        """
        backend = self._open_backend()
        try:
            return backend.decode(raw)
        except RecordingError:
            raise
        except Exception as exc:
            raise RecordingError(
                f"{self.path}: cannot decode a {raw.msgtype} message on {raw.topic} "
                f"at {raw.log_ns} ns: {_reason(exc)}"
            ) from exc


def _mcap_profile(path: Path) -> str:
    from mcap.reader import make_reader

    with path.open("rb") as f:
        return str(make_reader(f).get_header().profile)


def open_recording(path: str | os.PathLike[str]) -> Recording:
    """Open a recording for reading.

    Args:
        path: a ROS1 ``.bag``, or a folder of them (read as one recording); a ROS2 bag directory (with
            ``metadata.yaml``), ``.db3`` or ``.mcap`` file; or a plain MCAP file (any other profile).

    Raises:
        RecordingError: missing path, unknown format, or a corrupt/truncated/unreadable file (one line).
    """
    p = Path(path)
    if not p.exists():
        raise RecordingError(f"recording not found: {p}")
    kind: Kind
    files = [p]
    meta = p.parent / "metadata.yaml"
    if p.is_file() and meta.is_file() and "compression_format: zstd" in meta.read_text(errors="replace"):
        raise RecordingError(
            f"{p} is one file of the compressed ROS 2 bag {p.parent} (its metadata.yaml says how to read "
            f"it): pass the folder {p.parent}"
        )
    try:
        notes: list[str] = []
        unfinished_ros2 = p.is_dir() and not (p / "metadata.yaml").exists() and _unfinished_ros2(p)
        if unfinished_ros2:
            notes = [
                f"{p}: a ROS 2 bag without metadata.yaml (its recording was interrupted): read its "
                f"{unfinished_ros2.name}"
            ]
            p = unfinished_ros2
            files = [p]
            kind = "ros2" if p.suffix == ".db3" or _mcap_profile(p) == "ros2" else "mcap"
        elif p.is_dir():
            if (p / "metadata.yaml").exists():
                kind = "ros2"
            else:
                files = _ros1_bags(p)
                kind = "ros1"
        elif p.suffix == ".bag" or p.name.endswith(".bag.active"):
            kind = "ros1"
        elif p.suffix == ".db3":
            kind = "ros2"
        elif p.suffix == ".mcap":
            kind = "ros2" if _mcap_profile(p) == "ros2" else "mcap"
        else:
            raise RecordingError(
                f"{p}: unknown recording format '{p.suffix}' "
                "(expected .bag, .db3, .mcap or a ROS2 bag folder)"
            )
        backend: _Backend
        if kind == "mcap":
            from studio.io.mcap_backend import McapBackend

            backend = McapBackend(p)
        elif kind == "ros2" and p.suffix == ".mcap":
            backend = _ros2_mcap_backend(p)
        elif kind == "ros1":
            backend = _ros1_backend(files)
        elif p.suffix == ".db3" and _wal_of(p) is not None:
            backend = _Db3WithWal(p)
        elif p.is_dir():
            backend = _ros2_folder_backend(p)
        else:
            backend = _RosbagsBackend(files, kind)
    except RecordingError:
        raise
    except Exception as exc:
        raise RecordingError(
            f"{p}: cannot open the recording (truncated or corrupt?): {_reason(exc)}"
        ) from exc
    rec = Recording(p, kind, backend, tuple(files))
    rec.notes[:0] = notes
    return rec
