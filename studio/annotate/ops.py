"""Annotation operations: validation, normalisation and their effect on the ground-truth timeline.

An operation is a JSON-able dict (``{"op": "move", "frame": 12, "id": 3, "x": 1.2, "y": -0.4}``, see
``docs/annotation.md``). :func:`normalize_op` checks its keys and types and fills defaults;
:meth:`Timeline.plan` computes the new state of every frame it changes *without* changing anything, so
that the store can write the log first and commit after. Frame states are immutable: a change replaces a
:class:`FrameState`, which makes undo a matter of putting the old objects back.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass, field, fields
from typing import Any

from studio.annotate.errors import AnnotationError
from studio.geometry.se import Pose2
from studio.labels import LabelFrame, LabelPerson

__all__ = ["OPS", "BaseFrame", "FrameState", "Timeline", "Touch", "normalize_op", "person_with"]

# op name → (required keys, optional keys with their defaults)
OPS: dict[str, tuple[tuple[str, ...], dict[str, Any]]] = {
    "add": (("frame", "id", "x", "y"), {}),
    "move": (("frame", "id", "x", "y"), {"propagate": False}),
    "delete": (("frame", "id"), {}),
    "set_id": (("id", "start", "end"), {"new_id": None}),
    "merge": (("ids", "start", "end"), {"into": None}),
    "swap": (("ids", "start", "end"), {}),
    "split": (("id", "frame"), {"new_id": None, "end": None}),
    "flag": (("frame", "id"), {"occluded": None, "uncertain": None}),
    "review": (("start", "end"), {"reviewed": True}),
}
FLAGS = ("occluded", "uncertain")
MAX_ID = 2**31 - 1  # ids and frame numbers: int32 (evaluators, MOT files and JavaScript handle them exactly)
MAX_COORD = 1000.0  # m: |x|, |y| of a person in the base frame (no sensor sees farther)
_PERSON_FIELDS = frozenset(f.name for f in fields(LabelPerson))


def _to_odom(pose: Pose2, x: float, y: float) -> tuple[float, float]:
    """A base-frame point in the odom frame (``pose.apply`` for one point, without numpy), metres, µm."""
    c, s = math.cos(pose.yaw), math.sin(pose.yaw)
    return round(c * x - s * y + pose.x, 6), round(s * x + c * y + pose.y, 6)


def person_with(p: LabelPerson, **changes: Any) -> LabelPerson:
    """A copy of a valid person with some fields changed, without validating it all again.

    ``dataclasses.replace`` re-runs ``LabelPerson.__post_init__``, whose numpy covariance check dominated
    replays of long logs. Only values the ops computed and checked are passed here (finite float x/y,
    non-negative int ids, a str source, a dict extra, cov None).
    """
    unknown = set(changes) - _PERSON_FIELDS
    if unknown:
        raise TypeError(f"LabelPerson has no field(s) {sorted(unknown)}")
    q = object.__new__(LabelPerson)
    q.__dict__.update(p.__dict__)
    q.__dict__.update(changes)
    return q


@dataclass(frozen=True)
class Touch:
    """Which log record last changed a person in a frame, and how.

    Attributes:
        seq: sequence number of the log record.
        how: ``edit`` (added/moved by hand in this frame), ``propagate`` (moved by a propagated move),
            ``identity`` (set_id/merge/split/swap), ``flag`` or ``delete``.
    """

    seq: int
    how: str


@dataclass(frozen=True)
class FrameState:
    """The ground truth of one frame. Never mutated: a change makes a new object.

    Attributes:
        people: person id → person (positions in the base frame, metres).
        reviewed: the frame was marked reviewed.
        who: person id → the last record that touched that id in this frame (deleted ids included).
    """

    people: Mapping[int, LabelPerson]
    reviewed: bool = False
    who: Mapping[int, Touch] = field(default_factory=dict)


def _is_int(v: Any) -> bool:
    return isinstance(v, int) and not isinstance(v, bool)


def _check_id(v: Any, what: str, limits: bool = True) -> int:
    if not _is_int(v) or v < 0:
        raise AnnotationError(f"{what} must be a non-negative integer, got {v!r}")
    if limits and v > MAX_ID:
        raise AnnotationError(f"{what} must be at most {MAX_ID}, got {v}")
    return int(v)


def _check_coord(v: Any, what: str, limits: bool = True) -> float:
    if isinstance(v, bool) or not isinstance(v, int | float):
        raise AnnotationError(f"{what} must be a number (metres), got {v!r}")
    f = float(v)
    if not math.isfinite(f):
        raise AnnotationError(f"{what} must be finite, got {v!r}")
    if limits and abs(f) > MAX_COORD:
        raise AnnotationError(f"{what} must be within ±{MAX_COORD:g} m of the robot, got {f:g}")
    return f


def _check_opt_bool(v: Any, what: str) -> bool | None:
    if v is not None and not isinstance(v, bool):
        raise AnnotationError(f"{what} must be true, false or null, got {v!r}")
    return v


def normalize_op(op: Any, *, limits: bool = True) -> dict[str, Any]:
    """Check an operation's keys and value types; return a copy with defaults filled in.

    Frame existence and the people in frames are checked by :meth:`Timeline.plan`. ``limits``: also
    refuse ids above :data:`MAX_ID` and coordinates beyond :data:`MAX_COORD` (off when replaying a log
    written before these limits existed).

    Raises:
        AnnotationError: not an object, unknown op, unknown or missing keys, bad value types.
    """
    if not isinstance(op, Mapping):
        raise AnnotationError(f"an operation must be a JSON object, got {type(op).__name__}")
    name = op.get("op")
    if name not in OPS:
        raise AnnotationError(f"unknown op {name!r} (expected one of {', '.join(OPS)})")
    required, optional = OPS[name]
    keys = set(op) - {"op"}
    missing = [k for k in required if k not in keys]
    if missing:
        raise AnnotationError(f"op {name!r}: missing key(s) {', '.join(missing)}")
    unknown = sorted(str(k) for k in keys - set(required) - set(optional))
    if unknown:
        raise AnnotationError(f"op {name!r}: unknown key(s) {', '.join(unknown)}")
    out: dict[str, Any] = {"op": name}
    for k in required:
        out[k] = op[k]
    for k, default in optional.items():
        out[k] = op.get(k, default)
    for k in ("frame", "start", "end", "id"):
        if k in out and out[k] is not None:  # frames must exist, ids (but add's) be present: no limit here
            out[k] = _check_id(out[k], f"op {name!r}: {k!r}", limits and name == "add" and k == "id")
    given = out["ids"] if name == "merge" and isinstance(out["ids"], list | tuple) else ()
    for k in ("new_id", "into"):  # ids an op gives out (merging into a present id is fine)
        if k in out and out[k] is not None:
            out[k] = _check_id(out[k], f"op {name!r}: {k!r}", limits and out[k] not in given)
    for k in ("x", "y"):
        if k in out:
            out[k] = _check_coord(out[k], f"op {name!r}: {k!r}", limits)
    if name == "move" and not isinstance(out["propagate"], bool):
        raise AnnotationError(f"op 'move': 'propagate' must be true or false, got {out['propagate']!r}")
    if name == "review" and not isinstance(out["reviewed"], bool):
        raise AnnotationError(f"op 'review': 'reviewed' must be true or false, got {out['reviewed']!r}")
    if name == "flag":
        for k in FLAGS:
            out[k] = _check_opt_bool(out[k], f"op 'flag': {k!r}")
        if out["occluded"] is None and out["uncertain"] is None:
            raise AnnotationError("op 'flag': give 'occluded' and/or 'uncertain' (true or false)")
    if name == "merge":
        ids = out["ids"]
        if not isinstance(ids, list | tuple) or len(ids) < 2:
            raise AnnotationError(f"op 'merge': 'ids' must be a list of at least two ids, got {ids!r}")
        out["ids"] = [_check_id(i, "op 'merge': each of 'ids'", False) for i in ids]
        if len(set(out["ids"])) != len(out["ids"]):
            raise AnnotationError(f"op 'merge': 'ids' has duplicates: {out['ids']}")
    if name == "swap":
        ids = out["ids"]
        if not isinstance(ids, list | tuple) or len(ids) != 2:
            raise AnnotationError(f"op 'swap': 'ids' must be a list of two ids, got {ids!r}")
        out["ids"] = [_check_id(i, "op 'swap': each of 'ids'", False) for i in ids]
        if out["ids"][0] == out["ids"][1]:
            raise AnnotationError(f"op 'swap': 'ids' are the same id twice: {out['ids']}")
    return out


@dataclass(frozen=True)
class BaseFrame:
    """A frame of the base, parsed only when needed (most frames of a long run are never touched).

    Attributes:
        number: frame number.
        ids: the person ids of the base frame (known without parsing the people).
        reviewed: the base frame carries ``"reviewed": true``.
        load: returns the frame's :class:`LabelFrame` (may raise a ``LabelError``).
    """

    number: int
    ids: tuple[int, ...]
    reviewed: bool
    load: Callable[[], LabelFrame]

    @staticmethod
    def of(f: LabelFrame) -> BaseFrame:
        """An already parsed frame."""
        return BaseFrame(f.frame, tuple(p.id for p in f.people), bool(f.extra.get("reviewed")), lambda: f)


class Timeline:
    """The ground truth of every frame as a list of :class:`FrameState`, plus the frames' metadata.

    Frames are parsed from the base on first use; positions ``i`` index the frames in frame-number order.

    Args:
        base: the base frames, sorted by frame number.
    """

    def __init__(self, base: Sequence[BaseFrame]) -> None:
        self.base = list(base)
        self.numbers: list[int] = [f.number for f in self.base]
        self.pos: dict[int, int] = {n: i for i, n in enumerate(self.numbers)}
        self._meta: list[LabelFrame | None] = [None] * len(self.base)
        self._states: list[FrameState | None] = [None] * len(self.base)

    def _load(self, i: int) -> FrameState:
        f = self.base[i].load()
        extra = dict(f.extra)
        reviewed = bool(extra.pop("reviewed", False))
        self._meta[i] = LabelFrame(frame=f.frame, stamp_ns=f.stamp_ns, robot_pose=f.robot_pose, extra=extra)
        s = self._states[i] = FrameState(people={p.id: p for p in f.people}, reviewed=reviewed)
        return s

    def state(self, i: int) -> FrameState:
        """The state of the frame at position ``i``."""
        s = self._states[i]
        return self._load(i) if s is None else s

    def set_state(self, i: int, s: FrameState) -> None:
        self.state(i)  # the metadata must be loaded too
        self._states[i] = s

    def meta(self, i: int) -> LabelFrame:
        """Frame number, stamp, robot pose and extra keys (without ``reviewed``) at position ``i``."""
        m = self._meta[i]
        if m is None:
            self._load(i)
            m = self._meta[i]
            assert m is not None
        return m

    def ids_at(self, i: int) -> Iterable[int]:
        s = self._states[i]
        return self.base[i].ids if s is None else s.people.keys()

    def is_reviewed(self, i: int) -> bool:
        s = self._states[i]
        return self.base[i].reviewed if s is None else s.reviewed

    def __len__(self) -> int:
        return len(self.numbers)

    def index(self, n: int, what: str = "frame") -> int:
        """Position of frame number ``n``; AnnotationError when the run has no such frame."""
        if not _is_int(n) or n not in self.pos:
            lo = self.numbers[0] if self.numbers else None
            hi = self.numbers[-1] if self.numbers else None
            raise AnnotationError(f"unknown {what} {n!r} (the run has frames {lo}..{hi})")
        return self.pos[n]

    def label_frame(self, i: int) -> LabelFrame:
        """The materialised :class:`LabelFrame` at position ``i`` (people sorted by id)."""
        s = self.state(i)
        m = self.meta(i)
        extra = dict(m.extra)
        if s.reviewed:
            extra["reviewed"] = True
        people = tuple(s.people[k] for k in sorted(s.people))
        return LabelFrame(
            frame=m.frame, people=people, stamp_ns=m.stamp_ns, robot_pose=m.robot_pose, extra=extra
        )

    def used_ids(self) -> set[int]:
        out: set[int] = set()
        for i in range(len(self)):
            out.update(self.ids_at(i))
        return out

    def free_id(self) -> int:
        """The smallest non-negative id not used in any frame."""
        used = self.used_ids()
        k = 0
        while k in used:
            k += 1
        return k

    # ---- planning ---------------------------------------------------------------------------------------

    def plan(self, op: dict[str, Any], seq: int) -> tuple[dict[str, Any], dict[int, FrameState]]:
        """Compute an operation's effect without applying it.

        Args:
            op: a normalised operation (:func:`normalize_op`).
            seq: the sequence number its log record will have (stored in :attr:`FrameState.who`).

        Returns:
            ``(op, changes)``: the op with ids picked by the store filled in, and position → new state for
            every frame whose state changes.

        Raises:
            AnnotationError: unknown frame, person missing or already present, id clashes.
        """
        name = op["op"]
        handler = getattr(self, f"_plan_{name}")
        result: tuple[dict[str, Any], dict[int, FrameState]] = handler(dict(op), seq)
        return result

    def _person(self, i: int, k: int) -> LabelPerson:
        p = self.state(i).people.get(k)
        if p is None:
            raise AnnotationError(f"frame {self.numbers[i]}: there is no person id {k}")
        return p

    def _range(self, op: dict[str, Any], start_key: str = "start", end_key: str = "end") -> range:
        a = self.index(op[start_key], start_key)
        b = len(self) - 1 if op.get(end_key) is None else self.index(op[end_key], end_key)
        if b < a:
            raise AnnotationError(f"{end_key} {op[end_key]} comes before {start_key} {op[start_key]}")
        return range(a, b + 1)

    def _placed(self, i: int, p: LabelPerson, x: float, y: float) -> LabelPerson:
        # micrometre precision, as in the JSONL files, so that memory and files hold the same numbers
        x, y = round(x, 6), round(y, 6)
        pose: Pose2 | None = self.meta(i).robot_pose
        xo = yo = None
        if pose is not None:
            xo, yo = _to_odom(pose, x, y)
        return person_with(p, x=x, y=y, x_odom=xo, y_odom=yo, cov=None, source="manual")

    def _edited(self, i: int, p: LabelPerson, **changes: Any) -> LabelPerson:
        """``p`` with ``changes``, source manual, odom position recomputed when the frame has a pose."""
        pose: Pose2 | None = self.meta(i).robot_pose
        if pose is not None:
            changes["x_odom"], changes["y_odom"] = _to_odom(pose, p.x, p.y)
        return person_with(p, source="manual", **changes)

    @staticmethod
    def _with(
        s: FrameState,
        *,
        people: dict[int, LabelPerson] | None = None,
        reviewed: bool | None = None,
        touched: Iterable[int] = (),
        touch: Touch | None = None,
    ) -> FrameState:
        who = dict(s.who)
        if touch is not None:
            for k in touched:
                who[k] = touch
        return FrameState(
            people=s.people if people is None else people,
            reviewed=s.reviewed if reviewed is None else reviewed,
            who=who,
        )

    def _plan_add(self, op: dict[str, Any], seq: int) -> tuple[dict[str, Any], dict[int, FrameState]]:
        i, k = self.index(op["frame"]), op["id"]
        s = self.state(i)
        if k in s.people:
            raise AnnotationError(f"frame {op['frame']}: person id {k} already exists (move it instead)")
        p = self._placed(i, LabelPerson(id=k, x=op["x"], y=op["y"]), op["x"], op["y"])
        people = {**s.people, k: p}
        return op, {i: self._with(s, people=people, touched=[k], touch=Touch(seq, "edit"))}

    def _plan_move(self, op: dict[str, Any], seq: int) -> tuple[dict[str, Any], dict[int, FrameState]]:
        i, k = self.index(op["frame"]), op["id"]
        old = self._person(i, k)
        dx, dy = op["x"] - old.x, op["y"] - old.y
        s = self.state(i)
        changes = {
            i: self._with(
                s,
                people={**s.people, k: self._placed(i, old, op["x"], op["y"])},
                touched=[k],
                touch=Touch(seq, "edit"),
            )
        }
        if op["propagate"]:
            for j in range(i + 1, len(self)):
                sj = self.state(j)
                pj = sj.people.get(k)
                t = sj.who.get(k)
                if pj is None or sj.reviewed:
                    break
                if (t is not None and t.how == "edit") or (t is None and pj.source == "manual"):
                    break  # edited by hand here (in this log, or in the base ground truth)
                moved = self._placed(j, pj, pj.x + dx, pj.y + dy)
                changes[j] = self._with(
                    sj, people={**sj.people, k: moved}, touched=[k], touch=Touch(seq, "propagate")
                )
        return op, changes

    def _plan_delete(self, op: dict[str, Any], seq: int) -> tuple[dict[str, Any], dict[int, FrameState]]:
        i, k = self.index(op["frame"]), op["id"]
        self._person(i, k)
        s = self.state(i)
        people = {q: p for q, p in s.people.items() if q != k}
        return op, {i: self._with(s, people=people, touched=[k], touch=Touch(seq, "delete"))}

    def _relabel(self, frames: range, mapping: dict[int, int], seq: int, what: str) -> dict[int, FrameState]:
        """Every id of ``mapping`` present in the frames takes the id it maps to (ids mapping to one id must
        not share a frame; an id taken by someone outside the mapping is an error)."""
        changes: dict[int, FrameState] = {}
        for i in frames:
            ids_i = self.ids_at(i)
            if not any(k in ids_i for k in mapping):
                continue  # without parsing frames the ids are not in
            s = self.state(i)
            present = [k for k in mapping if k in s.people]
            if not present:
                continue
            n = self.numbers[i]
            for new in {mapping[k] for k in present}:
                same = [k for k in present if mapping[k] == new]
                if len(same) > 1:
                    raise AnnotationError(
                        f"{what}: ids {same} are both in frame {n}; they cannot be one person"
                    )
            moved = [k for k in present if mapping[k] != k]
            if not moved:
                continue
            for k in moved:
                if mapping[k] in s.people and mapping[k] not in mapping:
                    raise AnnotationError(f"{what}: id {mapping[k]} is already in frame {n} where id {k} is")
            people = {q: p for q, p in s.people.items() if q not in moved}
            for k in moved:
                people[mapping[k]] = self._edited(i, s.people[k], id=mapping[k])
            touched = list(dict.fromkeys(x for k in moved for x in (k, mapping[k])))
            changes[i] = self._with(s, people=people, touched=touched, touch=Touch(seq, "identity"))
        return changes

    def _need_present(self, frames: range, ids: Sequence[int], what: str) -> None:
        for i in frames:
            ids_i = self.ids_at(i)
            if any(k in ids_i for k in ids):
                return
        a, b = self.numbers[frames[0]], self.numbers[frames[-1]]
        raise AnnotationError(f"{what}: no id {' or '.join(map(str, ids))} in frames {a}..{b}")

    def _plan_set_id(self, op: dict[str, Any], seq: int) -> tuple[dict[str, Any], dict[int, FrameState]]:
        frames = self._range(op)
        k = op["id"]
        self._need_present(frames, [k], "set_id")
        if op["new_id"] is None:
            op["new_id"] = self.free_id()
        if op["new_id"] == k:
            raise AnnotationError(f"set_id: new_id equals id ({k})")
        return op, self._relabel(frames, {k: op["new_id"]}, seq, "set_id")

    def _plan_merge(self, op: dict[str, Any], seq: int) -> tuple[dict[str, Any], dict[int, FrameState]]:
        frames = self._range(op)
        self._need_present(frames, op["ids"], "merge")
        if op["into"] is None:
            op["into"] = self.free_id()
        return op, self._relabel(frames, dict.fromkeys(op["ids"], op["into"]), seq, "merge")

    def _plan_swap(self, op: dict[str, Any], seq: int) -> tuple[dict[str, Any], dict[int, FrameState]]:
        """Each of the two ids takes the other's in every frame of the range (where only one of them is
        there, it takes the other's id): two tracks that exchanged people at an encounter, put right."""
        frames = self._range(op)
        a, b = op["ids"]
        self._need_present(frames, [a, b], "swap")
        return op, self._relabel(frames, {a: b, b: a}, seq, "swap")

    def _plan_split(self, op: dict[str, Any], seq: int) -> tuple[dict[str, Any], dict[int, FrameState]]:
        frames = self._range(op, "frame", "end")
        k = op["id"]
        self._need_present(frames, [k], "split")
        if op["new_id"] is None:
            op["new_id"] = self.free_id()
        if op["new_id"] == k:
            raise AnnotationError(f"split: new_id equals id ({k})")
        return op, self._relabel(frames, {k: op["new_id"]}, seq, "split")

    def _plan_flag(self, op: dict[str, Any], seq: int) -> tuple[dict[str, Any], dict[int, FrameState]]:
        i, k = self.index(op["frame"]), op["id"]
        old = self._person(i, k)
        extra = dict(old.extra)
        for name in FLAGS:
            if op[name] is True:
                extra[name] = True
            elif op[name] is False:
                extra.pop(name, None)
        s = self.state(i)
        people = {**s.people, k: self._edited(i, old, extra=extra)}
        return op, {i: self._with(s, people=people, touched=[k], touch=Touch(seq, "flag"))}

    def _plan_review(self, op: dict[str, Any], seq: int) -> tuple[dict[str, Any], dict[int, FrameState]]:
        changes = {}
        for i in self._range(op):
            if self.is_reviewed(i) != op["reviewed"]:
                changes[i] = self._with(self.state(i), reviewed=op["reviewed"])
        return op, changes
