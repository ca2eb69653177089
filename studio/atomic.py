"""Write files so that a reader never sees a half-written one (write to a temporary file, then rename)."""

from __future__ import annotations

import contextlib
import json
import os
import shutil
import tempfile
from collections.abc import Collection, Iterator
from pathlib import Path
from typing import overload

from studio.errors import StudioError

__all__ = [
    "MANIFEST",
    "atomic_dir",
    "atomic_write_bytes",
    "atomic_write_text",
    "check_replaceable",
    "out_file",
    "write_out",
]


_Inputs = Collection[str | os.PathLike[str] | None]


@overload
def out_file(text: str | os.PathLike[str], option: str, *, inputs: _Inputs = ()) -> Path: ...
@overload
def out_file(text: None, option: str, *, inputs: _Inputs = ()) -> None: ...
def out_file(
    text: str | os.PathLike[str] | None,
    option: str,
    *,
    inputs: _Inputs = (),
) -> Path | None:
    """The file an output option names (None passes through), checked before any work is done: not a
    folder, not one of the command's ``inputs`` (a typo must not overwrite what the command reads: ground
    truth, a recording), and inside a folder that exists or can be made, and can be written to.

    Raises:
        StudioError: one line naming ``option`` and what is wrong.
    """
    if text is None:
        return None
    p = Path(text)
    if p.is_dir():
        raise StudioError(f"{option} {p}: is a directory, expected a file name")
    for given in inputs:
        if given is not None and Path(given).exists() and p.exists() and p.resolve() == Path(given).resolve():
            raise StudioError(f"{option} {p}: is an input of this command, which would be overwritten")
    _writable_folder(p, option)
    return p


def _writable_folder(p: Path, option: str) -> None:
    """Raise unless ``p``'s folder exists (or can be made: its first existing ancestor is a folder) and
    can be written to."""
    prefix = f"{option} {p}" if option else str(p)
    folder = p.absolute().parent
    while not folder.exists() and folder != folder.parent:
        folder = folder.parent
    if not folder.is_dir():
        raise StudioError(f"{prefix}: {folder} is not a folder")
    if not os.access(folder, os.W_OK | os.X_OK):
        raise StudioError(f"{prefix}: cannot write in {folder}")


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


MANIFEST = ".studio-files"
"""The file an output directory lists its files in (relative path → size in bytes), written last: a later
run replaces the directory only when nothing was added to it, in sub-folders either, and no listed file
changed size (someone edited it)."""


@contextlib.contextmanager
def atomic_dir(
    path: str | os.PathLike[str], *, outputs: Collection[str] = (), what: str = ""
) -> Iterator[Path]:
    """Build a directory's files in a sibling temporary directory; on success it replaces ``path``.

    On any error the temporary directory is removed and ``path`` is left as it was. An existing ``path`` is
    replaced only when it is an empty directory or an earlier output of the same command: a directory
    holding ``outputs[0]`` and nothing but names in ``outputs`` (the files and folders the command writes),
    nothing added inside those folders and no file edited (:data:`MANIFEST`). Anything else — a file, a
    folder of the user's data, an earlier run someone added annotations to or edited — raises
    :class:`~studio.errors.StudioError` before the work starts, and again before the replacement if it
    changed meanwhile, so a mistyped ``--out`` never deletes anything. ``what`` names the output in that
    message (e.g. ``"a studio label run"``).
    """
    target = Path(path)
    check_replaceable(target, outputs, what)
    try:
        target.parent.mkdir(parents=True, exist_ok=True)
        tmp = Path(tempfile.mkdtemp(prefix=f".{target.name}.", suffix=".tmp", dir=target.parent))
        os.chmod(tmp, 0o777 & ~_umask())
    except OSError as exc:
        raise StudioError(f"{target}: cannot write the output there ({exc.strerror or exc})") from None
    try:
        yield tmp
        check_replaceable(target, outputs, what)
        _write_manifest(tmp)
        _swap_in(tmp, target)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise


def _swap_in(tmp: Path, target: Path) -> None:
    """Put the finished directory ``tmp`` in ``target``'s place (an earlier output there is removed); a
    failure leaves ``target`` as it was and is one :class:`~studio.errors.StudioError`."""
    try:
        if not target.exists():
            os.replace(tmp, target)
            return
        # an empty directory of a name of our own, which the rename replaces (a user's `.run.old` stays)
        old = Path(tempfile.mkdtemp(prefix=f".{target.name}.", suffix=".old", dir=target.parent))
        try:
            os.replace(target, old)
        except OSError:
            old.rmdir()
            raise
        try:
            os.replace(tmp, target)
        except OSError:
            os.replace(old, target)  # put the earlier output back
            raise
        shutil.rmtree(old, ignore_errors=True)
    except OSError as exc:
        raise StudioError(f"{target}: cannot replace the earlier output ({exc.strerror or exc})") from None


def _write_manifest(folder: Path) -> None:
    files = {
        p.relative_to(folder).as_posix(): p.stat().st_size
        for p in sorted(folder.rglob("*"))
        if p.is_file() and p.name != MANIFEST
    }
    atomic_write_text(folder / MANIFEST, json.dumps(files, indent=0) + "\n", fsync=False)


def check_replaceable(target: str | os.PathLike[str], outputs: Collection[str], what: str = "") -> None:
    """Raise :class:`~studio.errors.StudioError` unless :func:`atomic_dir` may replace ``target`` (see there)
    or make it (its folder can be written to); a command calls it first, to refuse before reading its
    inputs."""
    target = Path(target)
    if not target.exists() and not target.is_symlink():
        _writable_folder(target, "")
        return
    if not target.is_dir() or target.is_symlink():
        raise StudioError(f"{target} exists and is not a directory: give the output a new or empty directory")
    _writable_folder(target, "")
    names = sorted(p.name for p in target.iterdir())
    if not names:
        return
    known = [*outputs, MANIFEST]
    foreign = [n for n in names if n not in known]
    if outputs and next(iter(outputs)) in names and not foreign:
        foreign = _changed_since_written(target)
        if not foreign:
            return
    hint = (
        "give the output a new or empty directory (an earlier output is replaced only when nothing was "
        "added or edited)"
    )
    if "annotations" in foreign:
        raise StudioError(f"{target} holds annotations (annotations/), which are never overwritten: {hint}")
    shown = ", ".join(foreign[:3]) + (", ..." if len(foreign) > 3 else "")
    earlier = f"an earlier {what}" if what else "an earlier output of this command"
    raise StudioError(f"{target} is not {earlier} (it holds {shown}): {hint}")


def _changed_since_written(target: Path) -> list[str]:
    """The files of an earlier output that its :data:`MANIFEST` does not list (added inside its folders) or
    lists with another size (edited); top-level files named in ``outputs`` that it does not list were
    written by a later step (``studio demo``'s metrics.json) and count as its own. Without a manifest (an
    output of an earlier version) only the top-level names were checked."""
    try:
        listed = json.loads((target / MANIFEST).read_text())
    except FileNotFoundError:
        return []
    except (OSError, ValueError):
        return [MANIFEST]
    if not isinstance(listed, dict):
        return [MANIFEST]
    out = []
    for p in sorted(target.rglob("*")):
        rel = p.relative_to(target).as_posix()
        if not p.is_file() or rel == MANIFEST:
            continue
        if rel not in listed:
            if "/" in rel:
                out.append(f"{rel} (added)")
        elif p.stat().st_size != listed[rel]:
            out.append(f"{rel} (edited)")
    return out


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
