"""Automatic labels vs ground truth in the recording (issue 5, item 3).

The ground truth is drawn with the colour of the track it matched most often (unmatched identities in
white), in the odom frame and on the panorama; false positives (red) and misses (magenta) are marked in the
bird's-eye view; per-frame TP / FP / FN / ID switches, the mean position error and running F1 / MOTA are
time series; every frame where the two disagree gets a text-log row (``compare/events``), so the user can
jump to it from the log view or see it as a tick on the timeline. Frames are aligned as ``studio evaluate``
aligns them (:func:`studio.evaluate.evaluate`).
"""

from __future__ import annotations

from collections import Counter
from typing import Any

import numpy as np
import rerun as rr

from studio.geometry import EquirectCamera
from studio.labels.base import LabelFrame, LabelSet
from studio.viz import paths as ep
from studio.viz.colors import ERROR_FN, ERROR_FP, GT_UNMATCHED, id_color
from studio.viz.draw import vertical_strips
from studio.viz.series import FloatArray, _odom_xy, _scalars, _times, send_points, send_strips

__all__ = ["log_ground_truth"]

_PERSON_HEIGHT = 1.8


def log_ground_truth(
    rec: rr.RecordingStream,
    labels: list[LabelFrame],
    gt: LabelSet,
    *,
    camera: EquirectCamera | None = None,
    radius: float = 0.2,
) -> Any:
    """Log ground truth against the run's labels: positions, errors, per-frame metrics, events.

    Frames are aligned as ``studio evaluate`` does (by stamp when both sides have stamps, else by index).
    Returns the :class:`studio.evaluate.Evaluation`.
    """
    from studio.evaluate import evaluate

    pred = LabelSet.from_frames(labels)
    ev = evaluate(pred, gt, radius=radius)
    by_frame = pred.by_frame()
    gt_frames = gt.by_frame()
    votes: dict[int, Counter[int]] = {}
    for fe in ev.frames:
        for g, pr, _ in fe.matches:
            votes.setdefault(g, Counter())[pr] += 1
    colour = {g: id_color(c.most_common(1)[0][0]) for g, c in votes.items()}

    index: list[int] = []
    stamps: list[int] = []
    rows: list[Any] = []
    for fe in ev.frames:
        pf = by_frame.get(fe.pred_frame) if fe.pred_frame is not None else None
        stamp = fe.stamp_ns if fe.stamp_ns is not None else (pf.stamp_ns if pf is not None else None)
        if stamp is None:
            continue
        index.append(fe.pred_frame if fe.pred_frame is not None else fe.frame)
        stamps.append(int(stamp))
        rows.append((fe, gt_frames[fe.frame], pf))
    if not rows:
        return ev
    idx = _times(index, stamps)

    # ground-truth people (odom frame and panorama) and error markers
    pos, col, lab, lengths = [], [], [], []
    err_pos, err_col, err_lab, err_len = [], [], [], []
    pan: list[FloatArray] = []
    pan_col: list[tuple[int, int, int]] = []
    pan_lab: list[str] = []
    pan_len: list[int] = []
    for fe, gf, pf in rows:
        pose = gf.robot_pose or (pf.robot_pose if pf is not None else None)
        for p in gf.people:
            x, y = _odom_xy(p, pose)
            pos.append((x, y, 0.0))
            col.append(colour.get(p.id, GT_UNMATCHED))
            lab.append(f"GT {p.id}")
        lengths.append(len(gf.people))
        n_err = 0
        gmap = {p.id: p for p in gf.people}
        for g in fe.fn_ids:
            x, y = _odom_xy(gmap[g], pose)
            err_pos.append((x, y, 0.05))
            err_col.append(ERROR_FN)
            err_lab.append(f"miss GT {g}")
            n_err += 1
        if pf is not None:
            pmap = {p.id: p for p in pf.people}
            for q in fe.fp_ids:
                x, y = _odom_xy(pmap[q], pf.robot_pose)
                err_pos.append((x, y, 0.05))
                err_col.append(ERROR_FP)
                err_lab.append(f"false {q}")
                n_err += 1
        err_len.append(n_err)
        if camera is not None:
            base = gf.xy()
            up, _ = camera.project(np.c_[base, np.full(len(base), _PERSON_HEIGHT)])
            low, _ = camera.project(np.c_[base, np.zeros(len(base))])
            vs, keep = vertical_strips(low, up, camera.width)
            pan.extend(vs)
            pan_col.extend(colour.get(gf.people[i].id, GT_UNMATCHED) for i in keep)
            pan_lab.extend(f"GT {gf.people[i].id}" for i in keep)
            pan_len.append(len(vs))
    send_points(rec, f"{ep.ODOM}/ground_truth", idx, pos, col, lab, lengths, radius=0.2, show_labels=False)
    send_points(
        rec, f"{ep.ODOM}/errors", idx, err_pos, err_col, err_lab, err_len, radius=0.28, show_labels=True
    )
    if camera is not None:
        send_strips(
            rec,
            f"{ep.PANORAMA}/ground_truth",
            idx,
            pan,
            pan_col,
            pan_len,
            radius=6.0 * max(camera.width / 1920, 0.25),
            labels=pan_lab,
            image=True,
        )

    _eval_series(rec, rows, index, stamps)
    rec.log(ep.COMPARE_SUMMARY, rr.TextDocument(f"```\n{ev}\n```", media_type="text/markdown"), static=True)
    return ev


def _eval_series(rec: rr.RecordingStream, rows: list[Any], index: list[int], stamps: list[int]) -> None:
    fes = [r[0] for r in rows]
    for key, colour in (
        ("tp", (40, 200, 90)),
        ("fp", ERROR_FP),
        ("fn", ERROR_FN),
        ("id_switches", (255, 200, 0)),
    ):
        _scalars(
            rec,
            f"{ep.METRICS}/eval/{key}",
            index,
            stamps,
            [getattr(fe, key) for fe in fes],
            name=key,
            color=colour,
        )
    tp = np.cumsum([fe.tp for fe in fes])
    fp = np.cumsum([fe.fp for fe in fes])
    fn = np.cumsum([fe.fn for fe in fes])
    err = np.cumsum([fe.mot_fp + fe.mot_fn + fe.id_switches for fe in fes])
    ngt = np.cumsum([fe.num_gt for fe in fes])
    f1 = np.where(2 * tp + fp + fn > 0, 2 * tp / np.maximum(2 * tp + fp + fn, 1), 1.0)
    ok = ngt > 0
    mota = 1.0 - err[ok] / ngt[ok]
    _scalars(
        rec,
        f"{ep.METRICS}/eval/running_f1",
        index,
        stamps,
        f1.tolist(),
        name="running F1",
        color=(120, 220, 255),
    )
    _scalars(
        rec,
        f"{ep.METRICS}/eval/running_mota",
        list(np.asarray(index)[ok]),
        list(np.asarray(stamps)[ok]),
        mota.tolist(),
        name="running MOTA",
        color=(255, 140, 60),
    )
    e_idx, e_st, e_val = [], [], []
    for fe, i, s in zip(fes, index, stamps, strict=True):
        if fe.matches:
            e_idx.append(i)
            e_st.append(s)
            e_val.append(float(np.mean([m[2] for m in fe.matches])))
    _scalars(
        rec,
        f"{ep.METRICS}/eval/error_m",
        e_idx,
        e_st,
        e_val,
        name="mean position error, m",
        color=(200, 120, 255),
    )
    # disagreement events: one text log row per frame where labels and ground truth disagree
    t_idx, t_st, text, level = [], [], [], []
    for fe, i, s in zip(fes, index, stamps, strict=True):
        parts = []
        if fe.fp:
            parts.append(
                f"{fe.fp} false positive{'s' * (fe.fp > 1)} (track {', '.join(map(str, fe.fp_ids))})"
            )
        if fe.fn:
            parts.append(f"{fe.fn} missed (GT {', '.join(map(str, fe.fn_ids))})")
        if fe.id_switches:
            parts.append(f"ID switch (GT {', '.join(map(str, fe.switch_ids))})")
        if parts:
            t_idx.append(i)
            t_st.append(s)
            text.append(f"frame {i}: " + "; ".join(parts))
            level.append("ERROR" if fe.id_switches else "WARN")
    if text:
        rec.send_columns(
            ep.COMPARE_EVENTS, indexes=_times(t_idx, t_st), columns=rr.TextLog.columns(text=text, level=level)
        )
