"""The ground-truth store: base labels + an append-only log of corrections → ground truth.

Ground truth = a base (the run's auto-labels, an empty set, or an existing ground-truth file) with the
operations of ``RUN/annotations/corrections.jsonl`` applied in order. The log is the only source of truth:
each operation is validated, appended and fsync'ed before it is acknowledged, and the materialised
``RUN/ground_truth.yaml`` (thesis format) and ``RUN/ground_truth.jsonl`` are rewritten atomically after it.
Reopening replays the log, so a process killed at any moment loses at most the operation in flight.
The base files are never written. File formats: ``docs/annotation.md``.
"""

from __future__ import annotations

import contextlib
import functools
import os
import shutil
import threading
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from pathlib import Path
from types import TracebackType
from typing import Any, Concatenate, ParamSpec, TypeVar

from studio.annotate import gtfiles
from studio.annotate import log as _log
from studio.annotate.bases import base_path, load_base, rel_path
from studio.annotate.errors import AnnotationError, ConflictError
from studio.annotate.gtfiles import jsonl_bytes, yaml_bytes
from studio.annotate.ops import FrameState, Timeline, normalize_op
from studio.labels import LabelFrame, read_labels

__all__ = ["AnnotationError", "AnnotationStore", "ConflictError", "OpResult"]

LOG_NAME = "annotations/corrections.jsonl"
LOCK_NAME = "annotations/.lock"


@dataclass(frozen=True)
class OpResult:
    """The outcome of an acknowledged operation (already durable in the log).

    Attributes:
        rev: the store's revision after the operation (= its log sequence number).
        frames: frame numbers whose ground truth changed, ascending.
        op: the operation as recorded (normalised: defaults filled in, picked ids explicit).
    """

    rev: int
    frames: list[int]
    op: dict[str, Any]


@dataclass
class _Entry:
    record: dict[str, Any]
    frames: list[int]
    before: dict[int, FrameState] = field(default_factory=dict)
    after: dict[int, FrameState] = field(default_factory=dict)


_P = ParamSpec("_P")
_R = TypeVar("_R")


def _locked(
    fn: Callable[Concatenate[AnnotationStore, _P], _R],
) -> Callable[Concatenate[AnnotationStore, _P], _R]:
    """Serialise a public method on the store's lock (web servers call from several threads)."""

    @functools.wraps(fn)
    def wrapper(self: AnnotationStore, *args: _P.args, **kwargs: _P.kwargs) -> _R:
        with self._mutex:
            return fn(self, *args, **kwargs)

    return wrapper


class AnnotationStore:
    """Ground truth of one run directory, corrected by an append-only log. Use :meth:`open`.

    Frames are the frame numbers of the run's ``labels.jsonl``; positions are metres in the base frame.
    One store per run at a time (an exclusive lock file); thread-safe (calls are serialised).
    """

    def __init__(self) -> None:  # use AnnotationStore.open
        self.run_dir = Path()
        self.author = "user"
        self.header: dict[str, Any] = {}
        self._tl = Timeline([])
        self._lock: _log.RunLock | None = None
        self._fd: int | None = None
        self._mutex = threading.RLock()
        self._rev = 0
        self._log_bytes = 0
        self._frame_rev: list[int] = []
        self._entries: list[_Entry] = []
        self._undo: list[int] = []
        self._redo: list[int] = []
        self._undone: set[int] = set()
        self._frames: list[LabelFrame | None] = []
        self._jsonl: list[bytes] = []
        self._yaml: list[bytes] = []

    # ---- opening ----------------------------------------------------------------------------------------

    @classmethod
    def open(
        cls,
        run_dir: str | os.PathLike[str],
        *,
        base: str | os.PathLike[str] | None = None,
        author: str = "user",
    ) -> AnnotationStore:
        """Open (or start) the ground truth of a labeled run directory.

        Args:
            run_dir: a run directory holding ``labels.jsonl``.
            base: where a new log starts from: None or ``"auto"`` → the run's auto-labels, ``"empty"`` → no
                people, a path → an existing ground-truth file (``.yaml``/``.jsonl``). An existing log keeps
                the base of its header; giving a different one is an error.
            author: default author of the operations.

        Raises:
            AnnotationError: not a run directory, run already open, base mismatch or changed, corrupt log.
            LabelError: a label file does not parse.
        """
        run = Path(run_dir)
        labels_path = run / "labels.jsonl"
        if not labels_path.is_file():
            raise AnnotationError(f"{run}: not a labeled run directory (no labels.jsonl)")
        _log.check_name(author, "author")
        if not os.access(run, os.W_OK) or (
            (run / "annotations").is_dir() and not os.access(run / "annotations", os.W_OK)
        ):
            raise AnnotationError(
                f"{run}: the run directory is read-only; corrections need to write annotations/ and "
                "ground_truth.* there (copy the run to a writable place)"
            )
        store = cls()
        store.run_dir, store.author = run, author
        try:
            (run / "annotations").mkdir(exist_ok=True)
            store._lock = _log.RunLock(run / LOCK_NAME)
            store._load(base)
        except OSError as exc:
            store.close()
            raise AnnotationError(f"{run}: cannot open the annotations ({exc})") from None
        except BaseException:
            store.close()
            raise
        return store

    def _load(self, base: str | os.PathLike[str] | None) -> None:
        run = self.run_dir
        log_path = run / LOG_NAME
        labels_sha = _log.file_sha256(run / "labels.jsonl")
        new = not log_path.exists()
        records: list[dict[str, Any]]
        if new:
            header, records = self._new_header(base, labels_sha), []
        else:
            header, records = _log.read_log(log_path)
            self._check_header(header, base, labels_sha)
        self.header = header
        self._tl = Timeline(load_base(run, header["base"]))
        n = len(self._tl)
        self._frame_rev = [0] * n
        self._frames = [None] * n
        for seq, rec in enumerate(records, 1):
            if rec.get("seq") != seq:
                raise AnnotationError(
                    f"{log_path}: record {seq} has seq {rec.get('seq')!r} (log out of order)"
                )
            try:
                self._apply_record(rec)
            except AnnotationError as exc:
                raise AnnotationError(f"{log_path}: record {seq} does not replay: {exc}") from None
        log_bytes = 0 if new else log_path.stat().st_size
        reused = None if new else gtfiles.reuse(run, self._tl.numbers, rev=self._rev, log_bytes=log_bytes)
        if reused is None:
            # parses every frame: a bad base frame fails here, before a new log is written
            self._jsonl = [jsonl_bytes(self._frame_at(i)) for i in range(n)]
            self._yaml = [yaml_bytes(self._frame_at(i)) for i in range(n)]
            if new:
                _log.write_header(log_path, header)
            self._fd = os.open(log_path, os.O_WRONLY | os.O_APPEND)
            self._log_bytes = log_path.stat().st_size
            gtfiles.write(
                run, self._jsonl, self._yaml, rev=self._rev, log_bytes=self._log_bytes, only_if_stale=True
            )
        else:
            self._jsonl, self._yaml = reused
            self._log_bytes = log_bytes
            self._fd = os.open(log_path, os.O_WRONLY | os.O_APPEND)

    def _new_header(self, base: str | os.PathLike[str] | None, labels_sha: str) -> dict[str, Any]:
        run = self.run_dir
        info: dict[str, Any]
        if base is None or base == "auto":
            info = {"kind": "auto", "path": "labels.jsonl", "sha256": labels_sha}
        elif base == "empty":
            info = {"kind": "empty", "path": None, "sha256": None}
        else:
            src = Path(base)
            if not src.is_file():
                raise AnnotationError(f"base ground truth {src}: no such file")
            read_labels(src)  # fail now, before anything is written, if it does not parse
            path = src
            if src.resolve() in {(run / gtfiles.GT_YAML).resolve(), (run / gtfiles.GT_JSONL).resolve()}:
                # the store rewrites these files: keep a private copy of the base
                path = run / "annotations" / f"base{src.suffix.lower()}"
                shutil.copyfile(src, path)
            info = {
                "kind": "file",
                "path": rel_path(path, run),
                "source": rel_path(src, run),
                "sha256": _log.file_sha256(path),
            }
        return {
            "format": _log.FORMAT,
            "version": _log.VERSION,
            "base": info,
            "labels_sha256": labels_sha,
            "created_ns": time.time_ns(),
            "author": self.author,
        }

    def _check_header(
        self, header: dict[str, Any], base: str | os.PathLike[str] | None, labels_sha: str
    ) -> None:
        info = header.get("base") or {}
        kind = info.get("kind")
        if base is not None:
            if base in ("auto", "empty"):
                ok = kind == base
            else:
                given = rel_path(Path(base), self.run_dir)
                ok = kind == "file" and given in (info.get("path"), info.get("source"))
            if not ok:
                what = info.get("source") or info.get("path") if kind == "file" else kind
                raise AnnotationError(
                    f"{self.run_dir}: the corrections log starts from base {what!r}, not {str(base)!r} "
                    "(open without a base, or move annotations/ away to start over)"
                )
        if header.get("labels_sha256") != labels_sha:
            raise AnnotationError(
                f"{self.run_dir}/labels.jsonl changed since the corrections log was started; "
                "the logged corrections may no longer fit its frames"
            )
        if kind == "file":
            path = base_path(self.run_dir, info)
            if not path.is_file():
                raise AnnotationError(f"base ground truth {path} of the corrections log is missing")
            if _log.file_sha256(path) != info.get("sha256"):
                raise AnnotationError(
                    f"base ground truth {path} changed since the corrections log was started"
                )

    # ---- reading ----------------------------------------------------------------------------------------

    @property
    def rev(self) -> int:
        """Number of effective operations so far (undo and redo count too)."""
        return self._rev

    @property
    def num_frames(self) -> int:
        return len(self._tl)

    @property
    def frame_numbers(self) -> list[int]:
        """The frame numbers, ascending (usually ``0..num_frames-1``)."""
        return list(self._tl.numbers)

    @property
    def can_undo(self) -> bool:
        return bool(self._undo)

    @property
    def can_redo(self) -> bool:
        return bool(self._redo)

    def _frame_at(self, i: int) -> LabelFrame:
        f = self._frames[i]
        if f is None:
            f = self._frames[i] = self._tl.label_frame(i)
        return f

    @_locked
    def frame(self, n: int) -> LabelFrame:
        """Ground truth of frame ``n`` (people sorted by id, base-frame metres)."""
        return self._frame_at(self._tl.index(n))

    @_locked
    def frame_rev(self, n: int) -> int:
        """Revision of the last operation that changed frame ``n`` (0: never changed)."""
        return self._frame_rev[self._tl.index(n)]

    @_locked
    def frames(self) -> list[LabelFrame]:
        return [self._frame_at(i) for i in range(len(self._tl))]

    @_locked
    def reviewed(self) -> set[int]:
        """Frame numbers marked reviewed."""
        tl = self._tl
        return {tl.numbers[i] for i in range(len(tl)) if tl.is_reviewed(i)}

    def _public(self, e: _Entry) -> dict[str, Any]:
        r = e.record
        return {
            "seq": r["seq"],
            "rev": r["seq"],
            "time": r["time"],
            "author": r.get("author"),
            "client": r.get("client"),
            "op": dict(r["op"]),
            "frames": list(e.frames),
            "undone": r["seq"] in self._undone,
        }

    @_locked
    def history(self, *, frame: int | None = None, limit: int = 50) -> list[dict[str, Any]]:
        """Log records, newest first: ``seq, rev, time`` (ns since epoch), ``author, client, op, frames,
        undone``; with ``frame``, only those that changed that frame."""
        if frame is not None:
            self._tl.index(frame)
        out: list[dict[str, Any]] = []
        for e in reversed(self._entries):
            if len(out) >= limit:
                break
            if frame is None or frame in e.frames:
                out.append(self._public(e))
        return out

    @_locked
    def changed_by(self, n: int) -> dict[int, dict[str, Any]]:
        """Person id → the last record that touched it in frame ``n`` (with ``how``: edit, propagate,
        identity, flag, delete). Ids deleted from the frame are included; untouched base people are not."""
        s = self._tl.state(self._tl.index(n))
        out = {}
        for k, t in s.who.items():
            rec = self._public(self._entries[t.seq - 1])
            rec["how"] = t.how
            out[k] = rec
        return out

    def __iter__(self) -> Iterator[LabelFrame]:
        return iter(self.frames())

    # ---- writing ----------------------------------------------------------------------------------------

    def _record(
        self, op: dict[str, Any], frames: list[int], author: str | None, client: str | None
    ) -> dict[str, Any]:
        return {
            "seq": self._rev + 1,
            "time": time.time_ns(),
            "author": self.author if author is None else author,
            "client": client,
            "op": op,
            "frames": frames,
        }

    def _check_conflict(self, positions: set[int], base_rev: int | None) -> None:
        if base_rev is None:
            return
        if isinstance(base_rev, bool) or not isinstance(base_rev, int) or not 0 <= base_rev <= self._rev:
            raise AnnotationError(f"base_rev must be an integer in 0..{self._rev}, got {base_rev!r}")
        for i in sorted(positions):
            if self._frame_rev[i] > base_rev:
                e = self._entries[self._frame_rev[i] - 1].record
                raise ConflictError(
                    f"frame {self._tl.numbers[i]} was changed at rev {self._frame_rev[i]} "
                    f"by {e.get('author')} after rev {base_rev} you saw; reload and retry",
                    frame=self._tl.numbers[i],
                    frame_rev=self._frame_rev[i],
                )

    def _commit(self, record: dict[str, Any], changes: dict[int, FrameState]) -> _Entry:
        """Apply planned changes in memory (after the record is durable, or while replaying)."""
        seq = record["seq"]
        before = {i: self._tl.state(i) for i in changes}
        for i, s in changes.items():
            self._tl.set_state(i, s)
            self._frame_rev[i] = seq
            self._frames[i] = None
            if self._jsonl:
                f = self._frame_at(i)
                self._jsonl[i], self._yaml[i] = jsonl_bytes(f), yaml_bytes(f)
        frames = [self._tl.numbers[i] for i in sorted(changes)]
        entry = _Entry(record=record, frames=frames, before=before, after=dict(changes))
        self._entries.append(entry)
        self._rev = seq
        return entry

    def _plan_record(
        self, rec: dict[str, Any], *, replay: bool = False
    ) -> tuple[dict[str, Any], dict[int, FrameState], set[int]]:
        """(normalised op, changes, positions the op touches) of an op, undo or redo record."""
        op = rec["op"]
        name = op.get("op") if isinstance(op, dict) else None
        if name in ("undo", "redo"):
            stack = self._undo if name == "undo" else self._redo
            if not stack:
                raise AnnotationError(f"nothing to {name}")
            target = stack[-1]
            e = self._entries[target - 1]
            changes = dict(e.before if name == "undo" else e.after)
            return {"op": name, "target": target}, changes, set(changes)
        norm = normalize_op(op, limits=not replay)
        norm, changes = self._tl.plan(norm, seq=self._rev + 1)
        touched = set(changes)
        if "frame" in norm:
            touched.add(self._tl.index(norm["frame"]))
        return norm, changes, touched

    def _after_commit(self, name: str, seq: int, target: int | None) -> None:
        if name == "undo":
            assert target is not None
            self._undo.pop()
            self._redo.append(target)
            self._undone.add(target)
        elif name == "redo":
            assert target is not None
            self._redo.pop()
            self._undo.append(target)
            self._undone.discard(target)
        else:
            self._undo.append(seq)
            self._redo.clear()

    def _apply_record(self, rec: dict[str, Any]) -> None:
        """Replay one log record."""
        norm, changes, _ = self._plan_record(rec, replay=True)
        logged = rec.get("op")
        if (
            norm["op"] in ("undo", "redo")
            and isinstance(logged, dict)
            and logged.get("target") != norm["target"]
        ):
            raise AnnotationError(
                f"{norm['op']} of record {logged.get('target')!r}, expected {norm['target']}"
            )
        record = {**rec, "op": norm}
        self._commit(record, changes)
        self._after_commit(norm["op"], record["seq"], norm.get("target"))

    @_locked
    def _do(self, op: Any, base_rev: int | None, author: str | None, client: str | None) -> OpResult:
        if self._fd is None:
            raise AnnotationError("the annotation store is closed")
        _log.check_name(author, "author")
        _log.check_name(client, "client")
        norm, changes, touched = self._plan_record({"op": op})
        self._check_conflict(touched, base_rev)
        frames = [self._tl.numbers[i] for i in sorted(changes)]
        record = self._record(norm, frames, author, client)
        data = _log.dumps_record(record).encode("utf-8")
        try:
            _log.append_line(self._fd, data)  # durable from here on
        except OSError as exc:
            # cut a partly written line off, so that the next append does not glue onto it
            with contextlib.suppress(OSError):
                os.ftruncate(self._fd, self._log_bytes)
            raise AnnotationError(f"cannot write the corrections log ({exc}); op not applied") from None
        self._log_bytes += len(data)
        self._commit(record, changes)
        self._after_commit(norm["op"], record["seq"], norm.get("target"))
        try:
            gtfiles.write(self.run_dir, self._jsonl, self._yaml, rev=self._rev, log_bytes=self._log_bytes)
        except OSError as exc:
            raise AnnotationError(
                f"op {self._rev} is saved in the corrections log, but the ground-truth files could not be "
                f"rewritten ({exc}); they are rebuilt on the next op or open"
            ) from None
        return OpResult(rev=self._rev, frames=frames, op=dict(norm))

    def apply(
        self,
        op: dict[str, Any],
        *,
        base_rev: int | None = None,
        author: str | None = None,
        client: str | None = None,
    ) -> OpResult:
        """Validate, apply and log one operation (see ``docs/annotation.md`` for the ops).

        Args:
            op: the operation, e.g. ``{"op": "move", "frame": 3, "id": 1, "x": 1.0, "y": 2.0}``.
            base_rev: the revision the client last saw; if a frame the op touches changed after it,
                ConflictError and nothing is written. None: no check.
            author, client: who (default: the store's author) and from where (e.g. a browser tab id).

        Raises:
            AnnotationError: invalid op (the state is untouched). ConflictError: stale ``base_rev``.
        """
        if isinstance(op, dict) and op.get("op") in ("undo", "redo"):
            raise AnnotationError("use undo() / redo() for 'undo' and 'redo'")
        return self._do(op, base_rev, author, client)

    def undo(
        self, *, base_rev: int | None = None, author: str | None = None, client: str | None = None
    ) -> OpResult:
        """Undo the last operation not undone yet (an ``undo`` record; the log is never rewritten)."""
        return self._do({"op": "undo"}, base_rev, author, client)

    def redo(
        self, *, base_rev: int | None = None, author: str | None = None, client: str | None = None
    ) -> OpResult:
        """Redo the last undone operation (a new operation clears the redo list)."""
        return self._do({"op": "redo"}, base_rev, author, client)

    @_locked
    def close(self) -> None:
        """Release the log and the run lock (idempotent)."""
        if self._fd is not None:
            os.close(self._fd)
            self._fd = None
        if self._lock is not None:
            self._lock.release()
            self._lock = None

    def __enter__(self) -> AnnotationStore:
        return self

    def __exit__(
        self, et: type[BaseException] | None, ev: BaseException | None, tb: TracebackType | None
    ) -> None:
        self.close()
