"""The corrections log: an append-only JSON-lines file whose first line is a header.

Every line is appended with one ``write`` and made durable with ``fsync`` before the operation is
acknowledged. A process killed while writing can leave a torn last line (no newline, or not valid JSON):
it was never acknowledged, so :func:`read_log` drops it and cuts the file back to the last whole line.
"""

from __future__ import annotations

import contextlib
import errno
import fcntl
import hashlib
import json
import os
from pathlib import Path
from typing import Any

from studio.annotate.errors import AnnotationError
from studio.atomic import atomic_write_text

__all__ = [
    "FORMAT",
    "MAX_NAME",
    "VERSION",
    "RunLock",
    "append_line",
    "check_name",
    "file_sha256",
    "read_log",
    "write_header",
]

FORMAT = "studio-annotations"
VERSION = 1
MAX_NAME = 200  # characters of an author or client name


def check_name(value: Any, what: str) -> str | None:
    """An author or client name: None or a short string that is valid UTF-8 text (no lone surrogates).

    Raises:
        AnnotationError: anything else (it would be written into the log and shown on every page).
    """
    if value is None:
        return None
    if not isinstance(value, str):
        raise AnnotationError(f"{what} must be a string, got {type(value).__name__}")
    if len(value) > MAX_NAME:
        raise AnnotationError(f"{what} must be at most {MAX_NAME} characters, got {len(value)}")
    try:
        value.encode("utf-8")
    except UnicodeEncodeError:
        raise AnnotationError(f"{what} is not valid text (lone surrogate): {value!r}") from None
    if any(ord(c) < 32 for c in value):
        raise AnnotationError(f"{what} must not contain control characters: {value!r}")
    return value


def file_sha256(path: str | os.PathLike[str]) -> str:
    """Hex SHA-256 of a file's bytes."""
    h = hashlib.sha256()
    with open(path, "rb") as f:
        for chunk in iter(lambda: f.read(1 << 20), b""):
            h.update(chunk)
    return h.hexdigest()


def dumps_record(record: dict[str, Any]) -> str:
    """One log line (compact JSON, no NaN, with the newline)."""
    try:
        return json.dumps(record, separators=(",", ":"), allow_nan=False) + "\n"
    except (TypeError, ValueError) as exc:
        raise AnnotationError(f"operation is not JSON-serialisable: {exc}") from None


def write_header(path: Path, header: dict[str, Any]) -> None:
    """Create the log with its header line atomically (a reader never sees a log without a header)."""
    atomic_write_text(path, dumps_record(header))


def read_log(path: Path) -> tuple[dict[str, Any], list[dict[str, Any]]]:
    """Read the header and the records; drop (and cut off) a torn last line.

    Raises:
        AnnotationError: no valid header, or a broken line before the last one.
    """
    try:
        data = path.read_bytes()
    except OSError as exc:
        raise AnnotationError(f"{path}: cannot read the corrections log ({exc})") from None
    lines = data.split(b"\n")
    tail = lines.pop()  # b"" when the file ends with a newline, else a torn line
    good_len = len(data) - len(tail)
    parsed: list[dict[str, Any]] = []
    for n, raw in enumerate(lines, 1):
        try:
            obj = json.loads(raw)
            if not isinstance(obj, dict):
                raise ValueError("not a JSON object")
        except ValueError as exc:
            if n == len(lines) and n > 1:  # a garbled last line: never acknowledged
                good_len -= len(raw) + 1
                break
            raise AnnotationError(f"{path}:{n}: corrupt corrections log line ({exc})") from None
        parsed.append(obj)
    if not parsed:
        raise AnnotationError(f"{path}: empty corrections log (no header line)")
    header = parsed[0]
    if header.get("format") != FORMAT:
        raise AnnotationError(f"{path}: not a studio corrections log (first line has no format {FORMAT!r})")
    if header.get("version") != VERSION:
        raise AnnotationError(f"{path}: corrections log version {header.get('version')!r} is not supported")
    if good_len != len(data):
        with open(path, "r+b") as f:
            f.truncate(good_len)
            f.flush()
            os.fsync(f.fileno())
    return header, parsed[1:]


def append_line(fd: int, data: bytes) -> None:
    """Append one line (UTF-8 bytes) with a single write and fsync it (the durability point of an op)."""
    view = memoryview(data)
    while view:
        n = os.write(fd, view)
        view = view[n:]
    os.fsync(fd)


class RunLock:
    """An exclusive ``flock`` on ``annotations/.lock``: one store per run directory, across processes.

    Raises:
        AnnotationError: "run is already open by pid N" when another store holds the lock.
    """

    def __init__(self, path: Path) -> None:
        self.path = path
        self.fd: int | None = os.open(path, os.O_RDWR | os.O_CREAT, 0o666)
        try:
            fcntl.flock(self.fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError as exc:
            pid = os.pread(self.fd, 32, 0).decode("ascii", "replace").strip() or "?"
            os.close(self.fd)
            self.fd = None
            if exc.errno in (errno.EWOULDBLOCK, errno.EAGAIN, errno.EACCES):
                raise AnnotationError(f"run is already open by pid {pid} ({path.parent.parent})") from None
            raise
        os.ftruncate(self.fd, 0)
        os.pwrite(self.fd, f"{os.getpid()}\n".encode(), 0)

    def release(self) -> None:
        if self.fd is not None:
            with contextlib.suppress(OSError):
                os.ftruncate(self.fd, 0)
            os.close(self.fd)  # closing the descriptor releases the flock
            self.fd = None
