"""The base of the ground truth: the run's auto-labels, no people, or an existing ground-truth file.

Frames of the run's ``labels.jsonl`` are parsed lazily (:class:`studio.annotate.ops.BaseFrame`): opening a
long run reads the JSON once, and only frames that are edited or shown become :class:`LabelFrame` objects.
"""

from __future__ import annotations

import functools
import itertools
import json
import math
import os
from dataclasses import replace
from pathlib import Path
from typing import Any

from studio.annotate.errors import AnnotationError
from studio.annotate.ops import BaseFrame
from studio.labels import LabelError, LabelFrame, LabelPerson, frame_from_json, read_labels

__all__ = ["BASE_KINDS", "base_path", "load_base", "parse_frame", "read_run_lines", "rel_path"]

BASE_KINDS = ("auto", "empty", "file")


def _is_int(v: Any) -> bool:
    return isinstance(v, int) and not isinstance(v, bool)


def read_run_lines(path: Path) -> list[tuple[int, int, dict[str, Any]]]:
    """``(frame number, line number, JSON object)`` of every frame of a ``labels.jsonl``, by frame number.

    Raises:
        LabelError: unreadable file, a line that is not a JSON object with an integer ``frame``,
            duplicate frame numbers.
    """
    try:
        text = path.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as exc:
        raise LabelError(f"{path}: cannot read ({exc})") from None
    out = []
    for n, line in enumerate(text.splitlines(), 1):
        if not line.strip():
            continue
        try:
            obj = json.loads(line)
        except ValueError as exc:
            raise LabelError(f"{path}:{n}: {exc}") from None
        if not isinstance(obj, dict) or not _is_int(obj.get("frame")):
            raise LabelError(f"{path}:{n}: missing integer 'frame'")
        out.append((obj["frame"], n, obj))
    out.sort(key=lambda t: t[0])
    for a, b in itertools.pairwise(out):
        if a[0] == b[0]:
            raise LabelError(f"{path}:{b[1]}: duplicate frame {b[0]}")
    return out


_STD_KEYS = frozenset({"id", "x", "y", "x_odom", "y_odom", "cov", "source", "box", "score"})


def _num(v: Any) -> float:
    t = type(v)
    if t is float:
        if math.isfinite(v):
            return float(v)
    elif t is int:
        f = float(v)
        if math.isfinite(f):
            return f
    raise _IrregularError


def _opt(v: Any) -> float | None:
    return None if v is None else _num(v)


class _IrregularError(Exception):
    """Not the plain shape the fast parser handles: let ``frame_from_json`` decide (and explain)."""


def _fast_person(p: Any) -> LabelPerson:
    """A person from a JSON object of the common shape, checked in plain Python (same values and checks as
    ``frame_from_json``, whose numpy covariance check per person dominated opening long runs)."""
    if type(p) is not dict or type(p.get("id")) is not int:
        raise _IrregularError
    cov = p.get("cov")
    if cov is not None:
        if type(cov) is not list or len(cov) != 2 or any(type(r) is not list or len(r) != 2 for r in cov):
            raise _IrregularError
        cov = ((_num(cov[0][0]), _num(cov[0][1])), (_num(cov[1][0]), _num(cov[1][1])))
    box = p.get("box")
    if box is not None:
        if type(box) is not list or len(box) != 4:
            raise _IrregularError
        box = (_num(box[0]), _num(box[1]), _num(box[2]), _num(box[3]))
    q = object.__new__(LabelPerson)
    q.__dict__.update(
        id=p["id"],
        x=_num(p["x"]) if "x" in p else _num(None),
        y=_num(p["y"]) if "y" in p else _num(None),
        x_odom=_opt(p.get("x_odom")),
        y_odom=_opt(p.get("y_odom")),
        cov=cov,
        source=p.get("source"),
        box=box,
        score=_opt(p.get("score")),
        extra={} if p.keys() <= _STD_KEYS else {k: v for k, v in p.items() if k not in _STD_KEYS},
    )
    return q


def parse_frame(obj: dict[str, Any]) -> LabelFrame:
    """``frame_from_json(obj)``, faster for the usual shape (the same frame; ValueError when invalid)."""
    people_raw = obj.get("people", [])
    try:
        if type(people_raw) is not list:
            raise _IrregularError
        people = [_fast_person(p) for p in people_raw]
    except _IrregularError:
        return frame_from_json(obj)
    return replace(frame_from_json({**obj, "people": []}), people=tuple(people))


def _parse(path: Path, line: int, obj: dict[str, Any]) -> LabelFrame:
    try:
        return parse_frame(obj)
    except (ValueError, TypeError) as exc:
        raise LabelError(f"{path}:{line}: {exc}") from None


def _ids(obj: dict[str, Any]) -> tuple[int, ...]:
    people = obj.get("people")
    if not isinstance(people, list):
        return ()
    return tuple(p["id"] for p in people if isinstance(p, dict) and _is_int(p.get("id")))


def _lazy(path: Path, line: int, obj: dict[str, Any], *, people: bool) -> BaseFrame:
    src = obj if people else {k: v for k, v in obj.items() if k != "people"}
    return BaseFrame(
        number=obj["frame"],
        ids=_ids(src),
        reviewed=src.get("reviewed") is True,
        load=functools.partial(_parse, path, line, src),
    )


def _merged(meta: LabelFrame, g: LabelFrame | None) -> LabelFrame:
    """People (and extra keys) of the ground-truth frame, stamp and pose of the run's frame where missing."""
    if g is None:
        return LabelFrame(frame=meta.frame, stamp_ns=meta.stamp_ns, robot_pose=meta.robot_pose)
    return LabelFrame(
        frame=g.frame,
        people=g.people,
        stamp_ns=meta.stamp_ns if g.stamp_ns is None else g.stamp_ns,
        robot_pose=meta.robot_pose if g.robot_pose is None else g.robot_pose,
        extra=g.extra,
    )


def _load_merged(path: Path, line: int, meta_src: dict[str, Any], g: LabelFrame | None) -> LabelFrame:
    return _merged(_parse(path, line, meta_src), g)


def load_base(run_dir: Path, info: dict[str, Any]) -> list[BaseFrame]:
    """The base frames described by a log header's ``base`` entry, sorted by frame number.

    ``auto``: the run's ``labels.jsonl``; ``empty``: its frames without people; ``file``: the people of a
    ground-truth file, stamps and robot poses from ``labels.jsonl`` where the file has none; frames of the
    run the file lacks are empty, frames only the file has are kept.
    """
    labels = run_dir / "labels.jsonl"
    lines = read_run_lines(labels)
    kind = info.get("kind")
    if kind in ("auto", "empty"):
        return [_lazy(labels, n, obj, people=kind == "auto") for _, n, obj in lines]
    if kind != "file":
        raise AnnotationError(f"corrections log: unknown base kind {kind!r} (expected one of {BASE_KINDS})")
    gt = read_labels(base_path(run_dir, info)).by_frame()
    out = []
    for number, n, obj in lines:
        meta_src = {k: v for k, v in obj.items() if k not in ("people", "reviewed")}
        g = gt.pop(number, None)
        out.append(
            BaseFrame(
                number=number,
                ids=() if g is None else tuple(q.id for q in g.people),
                reviewed=g is not None and g.extra.get("reviewed") is True,
                load=functools.partial(_load_merged, labels, n, meta_src, g),
            )
        )
    out.extend(BaseFrame.of(g) for g in gt.values())
    out.sort(key=lambda b: b.number)
    return out


def base_path(run_dir: Path, info: dict[str, Any]) -> Path:
    """The file of a ``file`` base (paths in the header are relative to the run directory)."""
    p = Path(str(info.get("path")))
    return p if p.is_absolute() else run_dir / p


def rel_path(path: str | os.PathLike[str], run_dir: Path) -> str:
    """``path`` relative to the run directory when inside it, else absolute."""
    try:
        return str(Path(path).resolve().relative_to(run_dir.resolve()))
    except ValueError:
        return str(Path(path).resolve())
