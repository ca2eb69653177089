"""Write files so that a reader never sees a half-written one (write to a temporary file, then rename)."""

from __future__ import annotations

import contextlib
import os
import shutil
import tempfile
from collections.abc import Collection, Iterator
from pathlib import Path
from typing import overload

from studio.errors import StudioError

__all__ = [
    "atomic_dir",
    "atomic_write_bytes",
    "atomic_write_text",
    "check_replaceable",
    "out_file",
    "write_out",
]


@overload
def out_file(text: str | os.PathLike[str], option: str) -> Path: ...
@overload
def out_file(text: None, option: str) -> None: ...
def out_file(text: str | os.PathLike[str] | None, option: str) -> Path | None:
    """The file an output option names (None passes through), checked before any work is done: not a
    folder, and inside a folder that exists or can be made, and can be written to.

    Raises:
        StudioError: one line naming ``option`` and what is wrong.
    """
    if text is None:
        return None
    p = Path(text)
    if p.is_dir():
        raise StudioError(f"{option} {p}: is a directory, expected a file name")
    folder = p.absolute().parent
    while not folder.exists() and folder != folder.parent:
        folder = folder.parent
    if not folder.is_dir():
        raise StudioError(f"{option} {p}: {folder} is not a folder")
    if not os.access(folder, os.W_OK | os.X_OK):
        raise StudioError(f"{option} {p}: cannot write in {folder}")
    return p


def write_out(path: Path, text: str, option: str) -> None:
    """:func:`atomic_write_text` for the file an output option named (:func:`out_file`): a failure (a full
    disk, a folder that refuses the file) is one line naming ``option``."""
    try:
        atomic_write_text(path, text)
    except OSError as exc:
        raise StudioError(f"{option} {path}: cannot write ({exc.strerror or exc})") from None


def atomic_write_bytes(path: str | os.PathLike[str], data: bytes, *, fsync: bool = True) -> None:
    """Replace ``path`` with ``data`` atomically (same-directory temporary file + ``os.replace``)."""
    target = Path(path)
    target.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{target.name}.", suffix=".tmp", dir=target.parent)
    try:
        os.fchmod(fd, 0o666 & ~_umask())  # mkstemp makes 0600; give the file the mode open() would
        with os.fdopen(fd, "wb") as f:
            f.write(data)
            if fsync:
                f.flush()
                os.fsync(f.fileno())
        os.replace(tmp, target)
    except BaseException:
        with contextlib.suppress(FileNotFoundError):
            os.unlink(tmp)
        raise
    if fsync:
        _fsync_dir(target.parent)


def atomic_write_text(path: str | os.PathLike[str], text: str, *, fsync: bool = True) -> None:
    """Text (UTF-8) version of :func:`atomic_write_bytes`."""
    atomic_write_bytes(path, text.encode("utf-8"), fsync=fsync)


@contextlib.contextmanager
def atomic_dir(
    path: str | os.PathLike[str], *, outputs: Collection[str] = (), what: str = ""
) -> Iterator[Path]:
    """Build a directory's files in a sibling temporary directory; on success it replaces ``path``.

    On any error the temporary directory is removed and ``path`` is left as it was. An existing ``path`` is
    replaced only when it is an empty directory or an earlier output of the same command: a directory
    holding ``outputs[0]`` and nothing but names in ``outputs`` (the files and folders the command writes).
    Anything else — a file, a folder of the user's data, an earlier run someone added annotations to —
    raises :class:`~studio.errors.StudioError` before the work starts, and again before the replacement
    if it changed meanwhile, so a mistyped ``--out`` never deletes anything. ``what`` names the output in
    that message (e.g. ``"a studio label run"``).
    """
    target = Path(path)
    check_replaceable(target, outputs, what)
    target.parent.mkdir(parents=True, exist_ok=True)
    tmp = Path(tempfile.mkdtemp(prefix=f".{target.name}.", suffix=".tmp", dir=target.parent))
    os.chmod(tmp, 0o777 & ~_umask())
    try:
        yield tmp
        check_replaceable(target, outputs, what)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    if target.exists():
        old = target.with_name(f".{target.name}.old")
        shutil.rmtree(old, ignore_errors=True)
        os.replace(target, old)
        os.replace(tmp, target)
        shutil.rmtree(old, ignore_errors=True)
    else:
        os.replace(tmp, target)


def check_replaceable(target: str | os.PathLike[str], outputs: Collection[str], what: str = "") -> None:
    """Raise :class:`~studio.errors.StudioError` unless :func:`atomic_dir` may replace ``target`` (see there);
    a command calls it first, to refuse before reading its inputs."""
    target = Path(target)
    if not target.exists() and not target.is_symlink():
        return
    if not target.is_dir() or target.is_symlink():
        raise StudioError(f"{target} exists and is not a directory: give the output a new or empty directory")
    names = sorted(p.name for p in target.iterdir())
    if not names:
        return
    known = list(outputs)
    foreign = [n for n in names if n not in known]
    if known and known[0] in names and not foreign:
        return
    hint = (
        "give the output a new or empty directory (an earlier output is replaced only when nothing was added)"
    )
    if "annotations" in foreign:
        raise StudioError(f"{target} holds annotations (annotations/), which are never overwritten: {hint}")
    shown = ", ".join(foreign[:3]) + (", ..." if len(foreign) > 3 else "")
    earlier = f"an earlier {what}" if what else "an earlier output of this command"
    raise StudioError(f"{target} is not {earlier} (it holds {shown}): {hint}")


def _umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask


def _fsync_dir(path: Path) -> None:
    with contextlib.suppress(OSError):
        fd = os.open(path, os.O_RDONLY)
        try:
            os.fsync(fd)
        finally:
            os.close(fd)
