"""Read and write label files: the thesis YAML format and JSON lines (DESIGN.md §2).

``labels.yaml``::

    frame 0:
    - id3: {x: 2.605, y: 0.748}
    frame 1: []

``labels.jsonl``: one object per frame, ``{"frame", "stamp_ns", "robot_pose", "people": [...]}``.

Writers are atomic (temporary file + rename): a reader never sees half a file.
"""

from __future__ import annotations

import json
import math
import os
import re
from collections.abc import Iterable, Mapping
from pathlib import Path
from typing import Any

import yaml

from studio.atomic import atomic_write_text
from studio.geometry.se import Pose2
from studio.labels.base import LabelFrame, LabelPerson, LabelSet
from studio.labels.errors import LabelError
from studio.yamlload import load_yaml, yaml_problem

__all__ = [
    "dumps_jsonl",
    "dumps_yaml",
    "frame_from_json",
    "frame_to_json",
    "json_value",
    "read_labels",
    "read_labels_jsonl",
    "read_labels_yaml",
    "write_labels",
    "write_labels_jsonl",
    "write_labels_yaml",
]

_FRAME_KEY = re.compile(r"^frame\s+(-?\d+)$")
_ID_KEY = re.compile(r"^id(-?\d+)$")
_PERSON_KEYS = {"id", "x", "y", "x_odom", "y_odom", "cov", "source", "box", "score"}


def _num(v: float, nd: int = 3) -> str:
    r = round(float(v), nd)
    if r == 0:
        r = 0.0  # no "-0.0"
    return repr(r)


def dumps_yaml(frames: Iterable[LabelFrame], *, decimals: int = 3) -> str:
    """The thesis YAML text of ``frames`` (positions in the base frame)."""
    out: list[str] = []
    for f in frames:
        if not f.people:
            out.append(f"frame {f.frame}: []")
            continue
        out.append(f"frame {f.frame}:")
        out.extend(f"- id{p.id}: {{x: {_num(p.x, decimals)}, y: {_num(p.y, decimals)}}}" for p in f.people)
    return "\n".join(out) + ("\n" if out else "")


def write_labels_yaml(
    path: str | os.PathLike[str], frames: Iterable[LabelFrame], *, decimals: int = 3
) -> None:
    """Write the thesis YAML format atomically."""
    atomic_write_text(path, dumps_yaml(frames, decimals=decimals))


def json_value(v: Any) -> Any:
    """``v`` made JSON-ready as the label writers write it: floats rounded to 6 decimals, NaN/inf → None,
    numpy scalars → Python, mapping keys → str, tuples → lists."""
    if isinstance(v, float):
        if not math.isfinite(v):
            return None
        return round(v, 6)
    if isinstance(v, Mapping):
        return {str(k): json_value(x) for k, x in v.items()}
    if isinstance(v, list | tuple):
        return [json_value(x) for x in v]
    if hasattr(v, "item"):  # numpy scalar
        return json_value(v.item())
    return v


def frame_to_json(f: LabelFrame) -> dict[str, Any]:
    """The JSONL object of one frame."""
    people = []
    for p in f.people:
        d: dict[str, Any] = {"id": p.id, "x": p.x, "y": p.y}
        if p.x_odom is not None and p.y_odom is not None:
            d["x_odom"], d["y_odom"] = p.x_odom, p.y_odom
        if p.cov is not None:
            d["cov"] = [list(r) for r in p.cov]
        if p.source is not None:
            d["source"] = p.source
        if p.box is not None:
            d["box"] = list(p.box)
        if p.score is not None:
            d["score"] = p.score
        d.update(p.extra)
        people.append(d)
    obj: dict[str, Any] = {"frame": f.frame}
    if f.stamp_ns is not None:
        obj["stamp_ns"] = f.stamp_ns
    if f.robot_pose is not None:
        obj["robot_pose"] = f.robot_pose.as_dict()
    obj["people"] = people
    obj.update(f.extra)
    cleaned: dict[str, Any] = json_value(obj)
    return cleaned


def dumps_jsonl(frames: Iterable[LabelFrame]) -> str:
    return "".join(json.dumps(frame_to_json(f), separators=(",", ":")) + "\n" for f in frames)


def write_labels_jsonl(path: str | os.PathLike[str], frames: Iterable[LabelFrame]) -> None:
    """Write JSON lines atomically."""
    atomic_write_text(path, dumps_jsonl(frames))


def write_labels(path: str | os.PathLike[str], frames: Iterable[LabelFrame]) -> None:
    """Write by extension: ``.yaml``/``.yml`` thesis format, ``.jsonl`` JSON lines."""
    suffix = Path(path).suffix.lower()
    if suffix in (".yaml", ".yml"):
        write_labels_yaml(path, frames)
    elif suffix == ".jsonl":
        write_labels_jsonl(path, frames)
    else:
        raise LabelError(f"{path}: unknown label format '{suffix}' (use .yaml or .jsonl)")


def _float(v: Any, what: str) -> float:
    if isinstance(v, bool) or not isinstance(v, int | float):
        raise ValueError(f"{what} must be a number, got {v!r}")
    f = float(v)
    if not math.isfinite(f):
        raise ValueError(f"{what} must be finite, got {v!r}")
    return f


def frame_from_json(obj: Any) -> LabelFrame:
    """Parse one JSONL object (raises ValueError with a readable reason)."""
    if not isinstance(obj, dict):
        raise ValueError("each line must be a JSON object")
    if "frame" not in obj or isinstance(obj["frame"], bool) or not isinstance(obj["frame"], int):
        raise ValueError("missing integer 'frame'")
    people_raw = obj.get("people", [])
    if not isinstance(people_raw, list):
        raise ValueError("'people' must be a list")
    people = []
    for i, p in enumerate(people_raw):
        if not isinstance(p, dict):
            raise ValueError(f"people[{i}] must be an object")
        for k in ("id", "x", "y"):
            if k not in p:
                raise ValueError(f"people[{i}] has no '{k}'")
        if isinstance(p["id"], bool) or not isinstance(p["id"], int):
            raise ValueError(f"people[{i}].id must be an integer, got {p['id']!r}")
        xo, yo = p.get("x_odom"), p.get("y_odom")
        people.append(
            LabelPerson(
                id=p["id"],
                x=_float(p["x"], f"people[{i}].x"),
                y=_float(p["y"], f"people[{i}].y"),
                x_odom=None if xo is None else _float(xo, f"people[{i}].x_odom"),
                y_odom=None if yo is None else _float(yo, f"people[{i}].y_odom"),
                cov=p.get("cov"),
                source=p.get("source"),
                box=p.get("box"),
                score=None if p.get("score") is None else _float(p["score"], f"people[{i}].score"),
                extra={k: v for k, v in p.items() if k not in _PERSON_KEYS},
            )
        )
    stamp = obj.get("stamp_ns")
    if stamp is not None and (isinstance(stamp, bool) or not isinstance(stamp, int)):
        raise ValueError(f"'stamp_ns' must be an integer (nanoseconds), got {stamp!r}")
    rp = obj.get("robot_pose")
    pose = None
    if rp is not None:
        if not isinstance(rp, dict):
            raise ValueError("'robot_pose' must be an object {x, y, yaw}")
        pose = Pose2(
            _float(rp.get("x", 0.0), "robot_pose.x"),
            _float(rp.get("y", 0.0), "robot_pose.y"),
            _float(rp.get("yaw", 0.0), "robot_pose.yaw"),
        )
    extra = {k: v for k, v in obj.items() if k not in ("frame", "stamp_ns", "robot_pose", "people")}
    return LabelFrame(frame=obj["frame"], people=tuple(people), stamp_ns=stamp, robot_pose=pose, extra=extra)


def _open_text(path: str | os.PathLike[str]) -> str:
    p = Path(path)
    if not p.exists():
        raise LabelError(f"{p}: no such file")
    if p.is_dir():
        raise LabelError(f"{p}: is a directory, expected a .yaml or .jsonl label file")
    try:
        return p.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as exc:
        raise LabelError(f"{p}: cannot read ({exc})") from None


def read_labels_jsonl(path: str | os.PathLike[str]) -> LabelSet:
    """Read a JSONL label file."""
    text = _open_text(path)
    frames = []
    for n, line in enumerate(text.splitlines(), 1):
        if not line.strip():
            continue
        try:
            frames.append(frame_from_json(json.loads(line)))
        except (ValueError, TypeError) as exc:  # json.JSONDecodeError is a ValueError
            raise LabelError(f"{path}:{n}: {exc}") from None
    try:
        return LabelSet(tuple(frames), {"path": str(path), "format": "jsonl"})
    except ValueError as exc:
        raise LabelError(f"{path}: {exc}") from None


def read_labels_yaml(path: str | os.PathLike[str]) -> LabelSet:
    """Read the thesis YAML format (``frame N:`` → list of ``idK: {x, y}``)."""
    text = _open_text(path)
    try:
        data = load_yaml(text)
    except yaml.YAMLError as exc:
        raise LabelError(f"{path}: not valid YAML ({yaml_problem(exc)})") from None
    if data is None:
        data = {}
    if not isinstance(data, dict):
        raise LabelError(f"{path}: expected a mapping 'frame N: [...]' at the top level")
    frames = []
    for key, people_raw in data.items():
        m = _FRAME_KEY.match(str(key).strip())
        if not m:
            raise LabelError(f"{path}: unexpected key '{key}' (expected 'frame N')")
        idx = int(m.group(1))
        people = []
        for item in people_raw or []:
            try:
                if not isinstance(item, dict) or len(item) != 1:
                    raise ValueError(f"expected '- idK: {{x: .., y: ..}}', got {item!r}")
                ((pid_key, pos),) = item.items()
                mid = _ID_KEY.match(str(pid_key).strip())
                if not mid:
                    raise ValueError(f"expected a key 'idK', got '{pid_key}'")
                if not isinstance(pos, dict) or "x" not in pos or "y" not in pos:
                    raise ValueError(f"'{pid_key}' needs x and y")
                people.append(
                    LabelPerson(id=int(mid.group(1)), x=_float(pos["x"], "x"), y=_float(pos["y"], "y"))
                )
            except ValueError as exc:
                raise LabelError(f"{path}: frame {idx}: {exc}") from None
        try:
            frames.append(LabelFrame(frame=idx, people=tuple(people)))
        except ValueError as exc:
            raise LabelError(f"{path}: {exc}") from None
    try:
        return LabelSet(tuple(frames), {"path": str(path), "format": "yaml"})
    except ValueError as exc:
        raise LabelError(f"{path}: {exc}") from None


def read_labels(path: str | os.PathLike[str]) -> LabelSet:
    """Read a label file by extension (``.yaml``/``.yml`` or ``.jsonl``)."""
    if not Path(path).exists():
        raise LabelError(f"{path}: no such file")
    suffix = Path(path).suffix.lower()
    if suffix in (".yaml", ".yml"):
        return read_labels_yaml(path)
    if suffix in (".jsonl", ".json"):
        return read_labels_jsonl(path)
    raise LabelError(f"{path}: unknown label format '{suffix}' (expected .yaml, .yml or .jsonl)")
