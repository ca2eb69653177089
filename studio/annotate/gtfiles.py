"""The materialised ground-truth files: fast per-frame text, atomic rewrite, reuse on open.

:func:`jsonl_line` gives exactly the line :func:`studio.labels.dumps_jsonl` writes for one frame (a test
checks byte equality on varied frames), several times faster: the store re-serialises every changed frame
after each operation and every frame on open, and the generic recursive cleaning of
:func:`studio.labels.frame_to_json` dominated both. :func:`yaml_text` is the thesis YAML of one frame.
"""

from __future__ import annotations

import contextlib
import json
import math
import re
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from studio.atomic import atomic_write_bytes, atomic_write_text
from studio.labels import LabelFrame, dumps_yaml
from studio.labels.formats import json_value

__all__ = [
    "GT_JSONL",
    "GT_YAML",
    "STAMP_NAME",
    "jsonl_bytes",
    "jsonl_line",
    "reuse",
    "write",
    "yaml_bytes",
    "yaml_text",
]

GT_YAML = "ground_truth.yaml"
GT_JSONL = "ground_truth.jsonl"
STAMP_NAME = "annotations/materialized.json"
_YAML_FRAME = re.compile(rb"^(?=frame )", re.MULTILINE)

_dumps = json.JSONEncoder(separators=(",", ":")).encode


def _num(v: Any) -> Any:
    if type(v) is float:  # the common case, without the generic dispatch
        return round(v, 6) if math.isfinite(v) else None
    return json_value(v)


def jsonl_line(f: LabelFrame) -> str:
    """The ``labels.jsonl`` line of one frame (with its newline), identical to ``dumps_jsonl([f])``."""
    people = []
    for p in f.people:
        d: dict[str, Any] = {"id": p.id, "x": _num(p.x), "y": _num(p.y)}
        if p.x_odom is not None and p.y_odom is not None:
            d["x_odom"], d["y_odom"] = _num(p.x_odom), _num(p.y_odom)
        if p.cov is not None:
            (a, b), (c, e) = p.cov
            d["cov"] = [[_num(a), _num(b)], [_num(c), _num(e)]]
        if p.source is not None:
            d["source"] = p.source
        if p.box is not None:
            d["box"] = [_num(u) for u in p.box]
        if p.score is not None:
            d["score"] = _num(p.score)
        if p.extra:
            d.update(json_value(p.extra))
        people.append(d)
    obj: dict[str, Any] = {"frame": f.frame}
    if f.stamp_ns is not None:
        obj["stamp_ns"] = f.stamp_ns
    if f.robot_pose is not None:
        obj["robot_pose"] = json_value(f.robot_pose.as_dict())
    obj["people"] = people
    if f.extra:
        obj.update(json_value(f.extra))
    return _dumps(obj) + "\n"


def yaml_text(f: LabelFrame) -> str:
    """The thesis YAML lines of one frame (``frame N:`` and its people)."""
    return dumps_yaml([f])


def jsonl_bytes(f: LabelFrame) -> bytes:
    """:func:`jsonl_line` as UTF-8 bytes (the store caches bytes: no re-encoding of whole files per op)."""
    return jsonl_line(f).encode("utf-8")


def yaml_bytes(f: LabelFrame) -> bytes:
    """:func:`yaml_text` as UTF-8 bytes."""
    return yaml_text(f).encode("utf-8")


def write(
    run_dir: Path,
    jsonl: Sequence[bytes],
    yaml: Sequence[bytes],
    *,
    rev: int,
    log_bytes: int,
    only_if_stale: bool = False,
) -> None:
    """Rewrite ``ground_truth.jsonl`` / ``.yaml`` (temporary file + rename) from per-frame bytes, then the
    stamp that lets the next open reuse them (rev, log size, the files' size and mtime).

    The files are not fsync'ed: they are derived from the fsync'ed log and rebuilt on open when the stamp
    does not match (e.g. after a crash between the log append and this rewrite).
    """
    stamp: dict[str, Any] = {"rev": rev, "log_bytes": log_bytes}
    for name, parts in ((GT_JSONL, jsonl), (GT_YAML, yaml)):
        data = b"".join(parts)
        path = run_dir / name
        same = False
        if only_if_stale:
            with contextlib.suppress(OSError):
                same = path.read_bytes() == data
        if not same:
            atomic_write_bytes(path, data, fsync=False)
        st = path.stat()
        stamp[name] = [st.st_size, st.st_mtime_ns]
    atomic_write_text(run_dir / STAMP_NAME, json.dumps(stamp) + "\n", fsync=False)


def reuse(
    run_dir: Path, numbers: Sequence[int], *, rev: int, log_bytes: int
) -> tuple[list[bytes], list[bytes]] | None:
    """The per-frame bytes of the ground-truth files when the stamp says they show state ``rev`` of a log
    of ``log_bytes`` bytes and they hold exactly the frames ``numbers``; else None (rebuild them)."""
    try:
        stamp = json.loads((run_dir / STAMP_NAME).read_text(encoding="utf-8"))
        if stamp.get("rev") != rev or stamp.get("log_bytes") != log_bytes:
            return None
        data = {}
        for name in (GT_JSONL, GT_YAML):
            path = run_dir / name
            st = path.stat()
            if stamp.get(name) != [st.st_size, st.st_mtime_ns]:
                return None
            data[name] = path.read_bytes()
    except (OSError, ValueError, AttributeError):
        return None
    jsonl = data[GT_JSONL].splitlines(keepends=True)
    yaml = _YAML_FRAME.split(data[GT_YAML])[1:]
    if len(jsonl) != len(numbers) or len(yaml) != len(numbers):
        return None
    for n, j, y in zip(numbers, jsonl, yaml, strict=True):
        if not (j.startswith(b'{"frame":%d,' % n) and j.endswith(b"\n") and y.startswith(b"frame %d:" % n)):
            return None
    return jsonl, yaml
