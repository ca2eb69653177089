"""Where a person should look first when checking a run's identities: the tracker's doubtful decisions.

Labels are output with one identity per track, but the identity decisions behind them are not all equally
sure. Almost every identity switch left in the labels lies at one of three kinds of moment, which can be
found from the labels alone (no ground truth, no tracker internals), so a run lists them in
``review.jsonl`` and the annotation studio jumps from one to the next:

* ``encounter``: two tracks came within ``encounter_m`` of each other (one point per pair and meeting, at
  the last frame they were that close): did each keep its person?
* ``gap``: a track is observed again after ``gap_s`` or more without an observation (frames where it was
  absent or only interpolated): is it the same person?
* ``start``: a track begins more than ``edge_s`` after the run's first frame: is it someone already
  labelled under another identity?

Points of one track less than ``merge_s`` apart are one point (the first). Measured on the simulated
``moving`` seeds 1–70 (session 70, docs/results.md; ``bench/replay_tracking.py --switches``): 46 of the 49
identity switches lie within 2 s of a point on one of their two tracks, with 7.6 points per minute of
recording (the same points moved 6 s later: 7); laser only, seeds 1–12: 51 of 55 at 7.8 per minute.

Each point also carries a ``doubt`` in [0, 1], from the labels alone, so that the likeliest errors can be
checked first (:func:`doubt`): an encounter is the more doubtful the farther from the robot it happened
(fewer beams and pixels on the people), a gap the farther the track moved unobserved and the longer it
lasted, and a start where another track stands within 1 m or one was last observed within 3 m in the
30 s before (someone labelled before, under another identity). Measured on the same seeds (session 71,
docs/results.md): the more doubtful half of the points, 3.8 per minute, lie within 2 s of 45 of the 48
switches the points catch (the earlier half in time, 23); laser only 44 of 51; on the held-out seeds
71–80, made after the weights were chosen, 10 of 13 and laser only 32 of 38.

Format of ``review.jsonl`` (one object per point, in frame order)::

    {"frame": 412, "stamp_ns": 1683731234000000000, "ids": [3, 5], "kind": "encounter",
     "note": "tracks 3 and 5 came within 0.42 m: did each keep its person?", "doubt": 0.42}

``doubt`` may be missing (a file written before session 71): such points count as 0.5.
"""

from __future__ import annotations

import itertools
import json
import math
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from studio.atomic import atomic_write_text
from studio.labels.base import LabelFrame, LabelPerson
from studio.labels.errors import LabelError

__all__ = [
    "FIRST_DOUBT",
    "REVIEW_KINDS",
    "ReviewConfig",
    "ReviewPoint",
    "doubt",
    "read_review",
    "review_jsonl",
    "review_points",
    "write_review",
]

REVIEW_KINDS = ("encounter", "gap", "start")

FIRST_DOUBT = 0.3
"""Points of this doubt or more are the ones to check first (the Rerun log's warnings): on simulated
``moving`` seeds 1–70, 39 % of the points (3.0 per minute), within 2 s of 42 of the 48 switches the points
catch."""


@dataclass(frozen=True)
class ReviewConfig:
    """Options of :func:`review_points` (see the module docstring).

    Attributes:
        encounter_m: two tracks this close (metres) in one frame met.
        gap_s: a track observed again after this long (seconds) without an observation resumes a gap.
        edge_s: a track that begins this long (seconds) after the first frame starts mid-run.
        merge_s: points of one track less than this apart (seconds) are one.
    """

    encounter_m: float = 0.5
    gap_s: float = 1.0
    edge_s: float = 1.0
    merge_s: float = 1.0

    def __post_init__(self) -> None:
        if not all(v > 0 for v in (self.encounter_m, self.gap_s, self.edge_s, self.merge_s)):
            raise ValueError("ReviewConfig: encounter_m, gap_s, edge_s and merge_s must be positive")


@dataclass(frozen=True)
class ReviewPoint:
    """One moment to check: ``frame`` (the labels' frame number) and its stamp, the tracks involved, the
    kind (one of :data:`REVIEW_KINDS`), a sentence for the person checking and how doubtful it is (0–1,
    :func:`doubt`)."""

    frame: int
    stamp_ns: int
    ids: tuple[int, ...]
    kind: str
    note: str
    doubt: float = 0.5

    def to_json(self) -> dict[str, Any]:
        return {
            "frame": self.frame,
            "stamp_ns": self.stamp_ns,
            "ids": list(self.ids),
            "kind": self.kind,
            "note": self.note,
            "doubt": round(self.doubt, 2),
        }


def doubt(
    kind: str,
    *,
    range_m: float = 0.0,
    jump_m: float = 0.0,
    gap_s: float = 0.0,
    other_within_1m: bool = False,
    ended_within_3m: bool = False,
) -> float:
    """How doubtful a point of ``kind`` is, 0–1: an encounter 0.3 + 0.3 · min(1, range / 8 m) (its range
    from the robot); a gap 0.3 · min(1, jump / 1.5 m) + 0.1 · min(1, gap / 20 s) (how far the track moved
    unobserved, how long); a start 0.2, + 0.2 with another track within 1 m, + 0.2 where another track was
    last observed within 3 m in the 30 s before. Weighed on simulated ``moving`` seeds 1–70 (camera) and
    1–12 (laser only): encounters there held a switch three times as often as gaps and starts. Rounded to
    hundredths, as ``review.jsonl`` stores it."""
    if kind == "encounter":
        value = 0.3 + 0.3 * min(1.0, range_m / 8.0)
    elif kind == "gap":
        value = 0.3 * min(1.0, jump_m / 1.5) + 0.1 * min(1.0, gap_s / 20.0)
    elif kind == "start":
        value = 0.2 + 0.2 * other_within_1m + 0.2 * ended_within_3m
    else:
        raise ValueError(f"unknown review point kind {kind!r}")
    return round(value, 2)


def review_points(frames: Sequence[LabelFrame], config: ReviewConfig | None = None) -> list[ReviewPoint]:
    """The moments of ``frames`` (a run's labels, in time order) where identities are worth checking.

    Raises:
        ValueError: a frame has no stamp (times come from the stamps).
    """
    cfg = config or ReviewConfig()
    if not frames:
        return []
    if any(f.stamp_ns is None for f in frames):
        raise ValueError("review points need stamped frames")
    stamps = [int(f.stamp_ns) for f in frames]  # type: ignore[arg-type]
    t0 = stamps[0]
    found: list[tuple[int, tuple[int, ...], str, str, float]] = []  # (frame position, ids, kind, note, doubt)
    last_seen: dict[int, int] = {}  # track -> position of its last observed label
    last_xy: dict[int, tuple[float, float]] = {}  # track -> where (odometry frame) it was last observed
    close: dict[tuple[int, int], list[tuple[int, float, float]]] = {}  # pair -> (position, distance, range)
    for i, f in enumerate(frames):
        here = {p.id for p in f.people}
        for p in f.people:
            xy = _odom(p)
            if p.id not in last_seen and (stamps[i] - t0) / 1e9 > cfg.edge_s:
                near = any(math.hypot(q.x - p.x, q.y - p.y) < 1.0 for q in f.people if q.id != p.id)
                ended = any(
                    tid not in here
                    and 0 <= (stamps[i] - stamps[j]) / 1e9 <= _ENDED_S
                    and math.dist(last_xy[tid], xy) < _ENDED_M
                    for tid, j in last_seen.items()
                    if j >= 0
                )
                note = f"track {p.id} begins: is it someone labelled before?"
                found.append(
                    (i, (p.id,), "start", note, doubt("start", other_within_1m=near, ended_within_3m=ended))
                )
            j = last_seen.get(p.id, -1)
            if p.extra.get("interpolated"):
                last_seen[p.id] = j  # begun, not observed
                continue
            if j >= 0 and (stamps[i] - stamps[j]) / 1e9 >= cfg.gap_s:
                gap = (stamps[i] - stamps[j]) / 1e9
                note = f"track {p.id} seen again after {gap:.1f} s: the same person?"
                found.append(
                    (i, (p.id,), "gap", note, doubt("gap", jump_m=math.dist(last_xy[p.id], xy), gap_s=gap))
                )
            last_seen[p.id] = i
            last_xy[p.id] = xy
        for pa, pb in itertools.combinations(sorted(f.people, key=lambda q: q.id), 2):
            d = math.hypot(pa.x - pb.x, pa.y - pb.y)
            if d < cfg.encounter_m:
                rng = 0.5 * (math.hypot(pa.x, pa.y) + math.hypot(pb.x, pb.y))
                close.setdefault((pa.id, pb.id), []).append((i, d, rng))
    for (a, b), run in close.items():
        start = 0
        for k in range(1, len(run) + 1):
            if k == len(run) or (stamps[run[k][0]] - stamps[run[k - 1][0]]) / 1e9 > cfg.merge_s:
                nearest = min(d for _, d, _ in run[start:k])
                note = f"tracks {a} and {b} came within {nearest:.2f} m: did each keep its person?"
                found.append(
                    (run[k - 1][0], (a, b), "encounter", note, doubt("encounter", range_m=run[k - 1][2]))
                )
                start = k
    return _merged(found, frames, stamps, cfg)


_ENDED_S = 30.0  # a start near where another track was last observed this recently is doubtful ...
_ENDED_M = 3.0  # ... this near (metres)


def _odom(p: LabelPerson) -> tuple[float, float]:
    """Where a label is in the odometry frame (the robot frame for labels without odometry positions)."""
    if p.x_odom is None or p.y_odom is None:
        return (p.x, p.y)
    return (p.x_odom, p.y_odom)


def _merged(
    found: list[tuple[int, tuple[int, ...], str, str, float]],
    frames: Sequence[LabelFrame],
    stamps: list[int],
    cfg: ReviewConfig,
) -> list[ReviewPoint]:
    """The points in frame order, without those that follow a kept point of each of their tracks by less
    than ``merge_s``."""
    found.sort(key=lambda x: (x[0], REVIEW_KINDS.index(x[2]), x[1]))
    last: dict[int, int] = {}  # track -> stamp of its last kept point
    out = []
    for i, ids, kind, note, how in found:
        if all(tid in last and (stamps[i] - last[tid]) / 1e9 < cfg.merge_s for tid in ids):
            continue
        for tid in ids:
            last[tid] = stamps[i]
        out.append(ReviewPoint(frames[i].frame, stamps[i], ids, kind, note, how))
    return out


def review_jsonl(points: Sequence[ReviewPoint]) -> str:
    """``review.jsonl``'s text."""
    return "".join(json.dumps(p.to_json(), separators=(",", ":")) + "\n" for p in points)


def write_review(path: Path, points: Sequence[ReviewPoint]) -> None:
    """Write ``review.jsonl`` atomically."""
    atomic_write_text(path, review_jsonl(points))


def read_review(path: Path) -> list[ReviewPoint]:
    """The points of a ``review.jsonl`` (empty when the file does not exist: a run made before it).

    Raises:
        LabelError: a line is not a review point.
    """
    if not path.is_file():
        return []
    out = []
    for n, line in enumerate(path.read_text(encoding="utf-8").splitlines(), 1):
        if not line.strip():
            continue
        try:
            obj = json.loads(line)
            ids = tuple(int(v) for v in obj["ids"])
            how = float(obj.get("doubt", 0.5))
            if not 0.0 <= how <= 1.0:
                raise ValueError(f"doubt {how} not in [0, 1]")
            point = ReviewPoint(
                int(obj["frame"]), int(obj["stamp_ns"]), ids, str(obj["kind"]), str(obj["note"]), how
            )
        except (ValueError, TypeError, KeyError) as exc:
            raise LabelError(f"{path}:{n}: not a review point ({exc})") from None
        out.append(point)
    return out
