"""Evaluate predicted labels against ground truth: every metric, per-frame values and splits.

Example:
    >>> from studio.evaluate import evaluate
    >>> ev = evaluate("run/labels.jsonl", "ground_truth.jsonl", radius=0.2)  # doctest: +SKIP
    >>> print(ev)  # a readable table  # doctest: +SKIP
    >>> ev.to_json()["mota"]  # the keys of DESIGN.md §2, plus extras  # doctest: +SKIP
    >>> ev.frames[10].fp_ids  # per-frame values for the viewer / annotation page  # doctest: +SKIP
"""

from __future__ import annotations

import math
import os
from collections.abc import Hashable, Mapping, Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np

from studio.evaluate.align import DEFAULT_STAMP_TOLERANCE_NS, align_frames
from studio.evaluate.base import safe_div
from studio.evaluate.clear import ClearMOT, ClearMOTResult
from studio.evaluate.detection import Detection, DetectionResult
from studio.evaluate.hota import HOTA, HOTAResult
from studio.evaluate.identity import Identity, IdentityResult
from studio.geometry.se import wrap_angle
from studio.labels.base import LabelFrame, LabelPerson, LabelSet
from studio.labels.errors import LabelError
from studio.labels.formats import read_labels

__all__ = [
    "JSON_KEYS",
    "Evaluation",
    "FrameEval",
    "SplitResult",
    "evaluate",
    "evaluate_sequences",
    "robot_motion",
]

LabelsLike = LabelSet | str | os.PathLike[str]

JSON_KEYS = (
    "precision",
    "recall",
    "f1",
    "tp",
    "fp",
    "fn",
    "mota",
    "motp",
    "idf1",
    "hota",
    "id_switches",
    "mt",
    "pt",
    "ml",
    "num_frames",
    "num_gt_tracks",
)


@dataclass(frozen=True)
class FrameEval:
    """Evaluation of one ground-truth frame (for the viewer and the annotation page).

    Attributes:
        sequence: sequence name (``"0"`` for a single pair of files).
        frame, stamp_ns: the ground-truth frame's index and stamp (ns, None when absent).
        pred_frame: index of the aligned predicted frame (None: no prediction for this frame).
        tp, fp, fn: detection counts of this frame (one-to-one matching within the radius).
        matches: detection pairs ``(gt_id, pred_id, distance_m)``.
        fn_ids, fp_ids: ground-truth ids missed / predicted ids unmatched by the detection matching.
        id_switches: CLEAR MOT identity switches in this frame; switch_ids: their ground-truth ids.
        mot_fp, mot_fn: CLEAR MOT false positives / misses in this frame (usually equal to fp, fn; they
            differ when keeping an earlier correspondence costs a match).
        moving: robot moving at this frame (from the prediction file's ``robot_pose``), None if unknown.
    """

    sequence: str
    frame: int
    stamp_ns: int | None
    pred_frame: int | None
    tp: int
    fp: int
    fn: int
    matches: tuple[tuple[int, int, float], ...]
    fn_ids: tuple[int, ...]
    fp_ids: tuple[int, ...]
    id_switches: int
    switch_ids: tuple[int, ...]
    mot_fp: int
    mot_fn: int
    moving: bool | None

    @property
    def num_gt(self) -> int:
        return self.tp + self.fn


@dataclass(frozen=True)
class SplitResult:
    """Metrics over a subset of frames (robot static / moving).

    Identity metrics (IDF1, HOTA) need whole tracks and are not split; MOTA uses the per-frame CLEAR MOT
    events of the whole sequence.
    """

    num_frames: int
    num_gt: int
    tp: int
    fp: int
    fn: int
    precision: float
    recall: float
    f1: float
    mota: float
    id_switches: int

    @staticmethod
    def of(frames: Sequence[FrameEval]) -> SplitResult:
        tp = sum(f.tp for f in frames)
        fp = sum(f.fp for f in frames)
        fn = sum(f.fn for f in frames)
        n_gt = tp + fn
        errors = sum(f.mot_fp + f.mot_fn + f.id_switches for f in frames)
        return SplitResult(
            num_frames=len(frames),
            num_gt=n_gt,
            tp=tp,
            fp=fp,
            fn=fn,
            precision=safe_div(tp, tp + fp),
            recall=safe_div(tp, tp + fn),
            f1=safe_div(2 * tp, 2 * tp + fp + fn),
            mota=1.0 - safe_div(errors, n_gt),
            id_switches=sum(f.id_switches for f in frames),
        )


@dataclass(frozen=True)
class Evaluation:
    """Everything :func:`evaluate` measured.

    Attributes:
        detection, clear, identity, hota: the metric results (see their classes).
        frames: per-frame values, in evaluation order.
        radius: match radius, metres.
        frame_matching: ``"stamp"`` or ``"index"`` (``"mixed"`` across sequences that differ).
        splits: ``{"static": …, "moving": …}`` when the prediction file has robot poses and stamps.
        sequences: per-sequence evaluations (only from :func:`evaluate_sequences` with several pairs).
        num_pred_frames_unmatched: predicted frames without a ground-truth frame (ignored).
        num_frames_interpolated: ground-truth frames compared with predictions interpolated to their stamp
            (between two predicted frames; :func:`~studio.evaluate.align.align_frames`).
        max_range: the annotated range, metres from the robot (None: everywhere); see :func:`evaluate`.
    """

    detection: DetectionResult
    clear: ClearMOTResult
    identity: IdentityResult
    hota: HOTAResult
    frames: tuple[FrameEval, ...]
    radius: float
    frame_matching: str
    splits: Mapping[str, SplitResult] = field(default_factory=dict)
    sequences: Mapping[str, Evaluation] = field(default_factory=dict)
    num_pred_frames_unmatched: int = 0
    num_frames_interpolated: int = 0
    max_range: float | None = None

    def metrics(self) -> dict[str, Any]:
        """The flat metric dictionary (NaN for undefined values) without splits and sequences."""
        d, c, i, h = self.detection, self.clear, self.identity, self.hota
        return {
            "precision": d.precision,
            "recall": d.recall,
            "f1": d.f1,
            "tp": d.tp,
            "fp": d.fp,
            "fn": d.fn,
            "mota": c.mota,
            "motp": c.motp,
            "idf1": i.idf1,
            "hota": h.hota,
            "id_switches": c.id_switches,
            "mt": c.mt,
            "pt": c.pt,
            "ml": c.ml,
            "num_frames": c.num_frames,
            "num_gt_tracks": c.num_gt_tracks,
            # extras
            "idp": i.idp,
            "idr": i.idr,
            "deta": h.deta,
            "assa": h.assa,
            "loca": h.loca,
            "frag": c.fragmentations,
            "mot_tp": c.tp,
            "mot_fp": c.fp,
            "mot_fn": c.fn,
            "num_mt": c.num_mt,
            "num_pt": c.num_pt,
            "num_ml": c.num_ml,
            "num_gt": c.num_gt,
            "num_pred": c.num_pred,
            "num_pred_tracks": c.num_pred_tracks,
            "num_pred_frames_unmatched": self.num_pred_frames_unmatched,
            "num_frames_interpolated": self.num_frames_interpolated,
            "radius": self.radius,
            "frame_matching": self.frame_matching,
            "max_range": self.max_range,
        }

    def to_json(self) -> dict[str, Any]:
        """JSON-ready dictionary: the DESIGN.md keys first, extras after; undefined values are None."""
        out = self.metrics()
        if self.splits:
            out["splits"] = {k: vars(v).copy() for k, v in self.splits.items()}
        if self.sequences:
            out["sequences"] = {k: v.to_json() for k, v in self.sequences.items()}
        result: dict[str, Any] = _jsonable(out)
        return result

    def table(self) -> str:
        """A readable multi-line summary for the terminal."""
        return _table(self)

    def __str__(self) -> str:
        return self.table()


def _jsonable(v: Any) -> Any:
    if isinstance(v, dict):
        return {k: _jsonable(x) for k, x in v.items()}
    if isinstance(v, list | tuple):
        return [_jsonable(x) for x in v]
    if isinstance(v, np.integer):
        return int(v)
    if isinstance(v, float | np.floating):
        return None if math.isnan(v) else float(v)
    return v


def robot_motion(
    pred: LabelSet, *, static_speed: float = 0.05, static_yaw_rate: float = 0.1
) -> dict[int, bool | None]:
    """Whether the robot moves at each predicted frame, from ``robot_pose`` and ``stamp_ns``.

    Speed and yaw rate come from the previous frame that has a pose and a stamp (the next one for the
    first frame). The robot is *moving* when speed > ``static_speed`` (m/s) or
    |yaw rate| > ``static_yaw_rate`` (rad/s).

    Returns:
        ``{pred_frame_index: moving}``; None when it cannot be told (no pose, no stamp, a lone frame).
    """
    usable = sorted(
        (f for f in pred.frames if f.robot_pose is not None and f.stamp_ns is not None),
        key=lambda f: int(f.stamp_ns),  # type: ignore[arg-type]
    )
    out: dict[int, bool | None] = {f.frame: None for f in pred.frames}
    for k, f in enumerate(usable):
        other = usable[k - 1] if k > 0 else (usable[1] if len(usable) > 1 else None)
        if other is None:
            continue
        dt = abs(int(f.stamp_ns) - int(other.stamp_ns)) * 1e-9  # type: ignore[arg-type]
        if dt <= 0:
            continue
        a, b = f.robot_pose, other.robot_pose
        assert a is not None
        assert b is not None
        speed = math.hypot(a.x - b.x, a.y - b.y) / dt
        yaw_rate = abs(float(wrap_angle(a.yaw - b.yaw))) / dt
        out[f.frame] = bool(speed > static_speed or yaw_rate > static_yaw_rate)
    return out


_RUN_FILES = ("labels.jsonl", "labels.yaml", "ground_truth.jsonl", "ground_truth.yaml")


def _load(x: LabelsLike) -> LabelSet:
    """A label set, or read one from a file; a run directory stands for its labels file."""
    if isinstance(x, LabelSet):
        return x
    path = Path(x)
    if path.is_dir():
        for name in _RUN_FILES:
            if (path / name).is_file():
                return read_labels(path / name)
        raise LabelError(f"{path}: is a directory with no {' / '.join(_RUN_FILES)}")
    if not path.exists():
        raise LabelError(f"{path}: no such file")
    return read_labels(path)


FRAMES = ("base", "odom")


def _in_odom(ls: LabelSet) -> LabelSet:
    """The label set with every position replaced by its odom-frame one (``x_odom``, ``y_odom``).

    Raises:
        LabelError: a person without odom-frame coordinates.
    """
    frames = []
    for f in ls.frames:
        people = []
        for p in f.people:
            if p.x_odom is None or p.y_odom is None:
                name = ls.meta.get("path", "labels")
                raise LabelError(
                    f"{name}: frame {f.frame}, person {p.id} has no x_odom / y_odom (needed to compare "
                    "positions in the odom frame)"
                )
            # odom positions are interpolated as they are: no base-frame position to rebuild them from
            people.append(replace(p, x=p.x_odom, y=p.y_odom, x_odom=None, y_odom=None, cov=None))
        frames.append(replace(f, people=tuple(people)))
    return replace(ls, frames=tuple(frames))


def evaluate(
    pred: LabelsLike,
    gt: LabelsLike,
    *,
    radius: float = 0.2,
    frame: str = "base",
    stamp_tolerance_ns: int = DEFAULT_STAMP_TOLERANCE_NS,
    static_speed: float = 0.05,
    static_yaw_rate: float = 0.1,
    max_range: float | None = None,
) -> Evaluation:
    """Compare predicted labels with ground truth.

    Args:
        pred: predictions (a :class:`LabelSet` or a ``.yaml`` / ``.jsonl`` path).
        gt: ground truth (same kinds).
        radius: match radius, metres (a pair at exactly ``radius`` matches).
        frame: ``"base"`` compares the positions in the robot's base frame (``x``, ``y``), ``"odom"`` those in
            the odom frame (``x_odom``, ``y_odom``: ground truth annotated on a map of the recording, which
            every person of both files must then have).
        stamp_tolerance_ns: largest stamp difference when aligning frames by stamp, ns.
        static_speed, static_yaw_rate: robot motion thresholds of the static / moving split (m/s, rad/s).
        max_range: the ground truth lists the people within this many metres of the robot only (an
            annotator's or a simulator's limit; None: everyone, wherever). Ground-truth people farther away
            and the predictions within ``radius`` of them are left out, and so are predictions farther away
            that lie within ``radius`` of nobody listed: a right label beyond the annotated range is no false
            positive, a person just beyond it no miss. Ranges are measured in the base frame (``x``, ``y``).

    Raises:
        LabelError: a file is missing or malformed, or the two share no frame.
    """
    return evaluate_sequences(
        {"0": (pred, gt)},
        radius=radius,
        frame=frame,
        max_range=max_range,
        stamp_tolerance_ns=stamp_tolerance_ns,
        static_speed=static_speed,
        static_yaw_rate=static_yaw_rate,
    )


def evaluate_sequences(
    pairs: Mapping[str, tuple[LabelsLike, LabelsLike]] | Sequence[tuple[LabelsLike, LabelsLike]],
    *,
    radius: float = 0.2,
    frame: str = "base",
    stamp_tolerance_ns: int = DEFAULT_STAMP_TOLERANCE_NS,
    static_speed: float = 0.05,
    static_yaw_rate: float = 0.1,
    max_range: float | None = None,
) -> Evaluation:
    """Evaluate several ``(pred, gt)`` sequences: overall metrics plus one :class:`Evaluation` each.

    Identities are per sequence (id 3 of one sequence is not id 3 of another); overall counts equal the
    sums of the per-sequence counts (motmetrics ``compute_overall`` / TrackEval ``combine_sequences``).
    ``max_range``: see :func:`evaluate`.
    """
    if not radius > 0:
        raise ValueError(f"radius must be positive, got {radius}")
    if max_range is not None and not max_range > 0:
        raise ValueError(f"max_range must be positive, got {max_range}")
    if max_range is not None and frame != "base":
        raise ValueError("max_range is measured in the base frame: use it with frame='base'")
    named = dict(pairs) if isinstance(pairs, Mapping) else {str(k): p for k, p in enumerate(pairs)}
    if not named:
        raise ValueError("no sequence to evaluate")
    if frame not in FRAMES:
        raise ValueError(f"frame must be one of {', '.join(FRAMES)}, got {frame!r}")
    loaded = {str(k): (_load(p), _load(g)) for k, (p, g) in named.items()}
    if frame == "odom":
        loaded = {k: (_in_odom(p), _in_odom(g)) for k, (p, g) in loaded.items()}
    overall = _Run(radius)
    per_seq: dict[str, Evaluation] = {}
    modes: set[str] = set()
    unmatched = made = 0
    for name, (p, g) in loaded.items():
        al = align_frames(p, g, stamp_tolerance_ns=stamp_tolerance_ns)
        motion = robot_motion(p, static_speed=static_speed, static_yaw_rate=static_yaw_rate)
        modes.add(al.mode)
        unmatched += al.num_pred_unmatched
        made += al.num_interpolated
        one = _Run(radius)
        for gf, pf in al.pairs:
            moving = None if pf is None else motion.get(pf.frame)
            if max_range is not None:
                gf, pf = _within_range(gf, pf, max_range, radius)
            overall.add(name, gf, pf, moving)
            if len(loaded) > 1:
                one.add(name, gf, pf, moving)
        if len(loaded) > 1:
            per_seq[name] = one.result(al.mode, al.num_pred_unmatched, al.num_interpolated)
    mode = modes.pop() if len(modes) == 1 else "mixed"
    ev = replace(overall.result(mode, unmatched, made), max_range=max_range)
    if per_seq:
        ev = replace(ev, sequences={k: replace(v, max_range=max_range) for k, v in per_seq.items()})
    return ev


def _within_range(
    gf: LabelFrame, pf: LabelFrame | None, max_range: float, radius: float
) -> tuple[LabelFrame, LabelFrame | None]:
    """The frames with what lies outside the annotated range left out (:func:`evaluate`'s ``max_range``)."""

    def far(p: LabelPerson) -> bool:
        return math.hypot(p.x, p.y) > max_range

    listed = [p for p in gf.people if not far(p)]
    unlisted = [p for p in gf.people if far(p)]
    if pf is not None:

        def near(p: LabelPerson, people: list[LabelPerson]) -> bool:
            return any(math.hypot(p.x - q.x, p.y - q.y) <= radius for q in people)

        # one that may match someone listed stays; else one inside the range, unless someone unlisted is there
        kept = [p for p in pf.people if near(p, listed) or not (far(p) or near(p, unlisted))]
        pf = replace(pf, people=tuple(kept))
    return replace(gf, people=tuple(listed)), pf


class _Run:
    """All metrics fed together, plus the per-frame records."""

    def __init__(self, radius: float) -> None:
        self.radius = radius
        self.det = Detection(radius=radius)
        self.clear = ClearMOT(radius=radius)
        self.ident = Identity(radius=radius)
        self.hota = HOTA(radius=radius)
        self.frames: list[FrameEval] = []

    def add(self, seq: Hashable, gf: LabelFrame, pf: LabelFrame | None, moving: bool | None) -> None:
        fm = self.det.update(gf, pf, sequence=seq)
        cf = self.clear.update(gf, pf, sequence=seq)
        self.ident.update(gf, pf, sequence=seq)
        self.hota.update(gf, pf, sequence=seq)
        gids = gf.ids()
        pids = pf.ids() if pf is not None else np.zeros(0, dtype=np.int64)
        self.frames.append(
            FrameEval(
                sequence=str(seq),
                frame=gf.frame,
                stamp_ns=gf.stamp_ns,
                pred_frame=None if pf is None else pf.frame,
                tp=fm.tp,
                fp=fm.fp,
                fn=fm.fn,
                matches=tuple(
                    (int(gids[i]), int(pids[j]), float(dd))
                    for i, j, dd in zip(fm.gt_index, fm.pred_index, fm.distance, strict=True)
                ),
                fn_ids=tuple(int(gids[i]) for i in fm.fn_index),
                fp_ids=tuple(int(pids[j]) for j in fm.fp_index),
                id_switches=len(cf.switches),
                switch_ids=cf.switches,
                mot_fp=len(cf.fp_ids),
                mot_fn=len(cf.fn_ids),
                moving=moving,
            )
        )

    def result(self, mode: str, unmatched: int, interpolated: int) -> Evaluation:
        splits: dict[str, SplitResult] = {}
        if any(f.moving is not None for f in self.frames):
            splits["static"] = SplitResult.of([f for f in self.frames if f.moving is False])
            splits["moving"] = SplitResult.of([f for f in self.frames if f.moving is True])
        return Evaluation(
            detection=self.det.compute(),
            clear=self.clear.compute(),
            identity=self.ident.compute(),
            hota=self.hota.compute(),
            frames=tuple(self.frames),
            radius=self.radius,
            frame_matching=mode,
            splits=splits,
            num_pred_frames_unmatched=unmatched,
            num_frames_interpolated=interpolated,
        )


def _f(v: float, pct: bool = False) -> str:
    if isinstance(v, float) and math.isnan(v):
        return "n/a"
    return f"{100 * v:5.1f} %" if pct else f"{v:.3f}"


def _table(ev: Evaluation) -> str:
    d, c, i, h = ev.detection, ev.clear, ev.identity, ev.hota
    lines = [
        f"{c.num_frames} frames (matched by {ev.frame_matching}), radius {ev.radius:g} m, "
        + ("" if ev.max_range is None else f"within {ev.max_range:g} m of the robot, ")
        + f"{c.num_gt_tracks} ground-truth tracks, {c.num_pred_tracks} predicted tracks",
        "",
        f"  Detection   precision {_f(d.precision)}   recall {_f(d.recall)}   F1 {_f(d.f1)}"
        f"   (TP {d.tp}, FP {d.fp}, FN {d.fn})",
        f"  CLEAR MOT   MOTA {_f(c.mota)}   MOTP {_f(c.motp)} m   ID switches {c.id_switches}"
        f"   fragmentations {c.fragmentations}",
        f"              MT {_f(c.mt, True)}   PT {_f(c.pt, True)}   ML {_f(c.ml, True)}"
        f"   ({c.num_mt} / {c.num_pt} / {c.num_ml} of {c.num_gt_tracks})",
        f"  Identity    IDF1 {_f(i.idf1)}   IDP {_f(i.idp)}   IDR {_f(i.idr)}",
        f"  HOTA        HOTA {_f(h.hota)}   DetA {_f(h.deta)}   AssA {_f(h.assa)}   LocA {_f(h.loca)}",
    ]
    if ev.num_frames_interpolated:
        lines.append(
            f"  ({ev.num_frames_interpolated} ground-truth frames lie between two predicted frames: "
            "compared with the predictions interpolated to their stamps)"
        )
    missing = sum(f.pred_frame is None for f in ev.frames)
    if missing:
        lines.append(
            f"  ({missing} ground-truth frames have no predicted frame: their people count as misses)"
        )
    if ev.num_pred_frames_unmatched:
        lines.append(f"  ({ev.num_pred_frames_unmatched} predicted frames have no ground truth: ignored)")
    if ev.splits:
        lines += ["", f"  {'split':<10}{'frames':>7}{'P':>8}{'R':>8}{'F1':>8}{'MOTA':>8}{'IDSW':>6}"]
        for name, s in ev.splits.items():
            lines.append(
                f"  {name:<10}{s.num_frames:>7}{_f(s.precision):>8}{_f(s.recall):>8}"
                f"{_f(s.f1):>8}{_f(s.mota):>8}{s.id_switches:>6}"
            )
    if ev.sequences:
        lines += ["", f"  {'sequence':<16}{'frames':>7}{'F1':>8}{'MOTA':>8}{'IDF1':>8}{'HOTA':>8}{'IDSW':>6}"]
        for name, e in ev.sequences.items():
            lines.append(
                f"  {name:<16}{e.clear.num_frames:>7}{_f(e.detection.f1):>8}{_f(e.clear.mota):>8}"
                f"{_f(e.identity.idf1):>8}{_f(e.hota.hota):>8}{e.clear.id_switches:>6}"
            )
    return "\n".join(lines)
