"""Files of a labeled run (DESIGN.md §2): labels.yaml, labels.jsonl, detections.yaml, tracks_mot.csv,
boxes_coco.json, review.jsonl, run.json. Every writer is atomic; :func:`write_run` builds the whole run
directory in a temporary sibling and renames it into place, so a failed run never leaves half its files."""

from __future__ import annotations

import contextlib
import json
import platform
import sys
from collections.abc import Sequence
from importlib import metadata
from pathlib import Path
from typing import Any

from studio import __version__
from studio.atomic import atomic_write_text
from studio.labels import LabelFrame, review_points, write_labels_jsonl, write_labels_yaml, write_review

__all__ = [
    "coco_json",
    "image_detections_jsonl",
    "mot_csv",
    "package_versions",
    "write_label_files",
    "write_run_json",
]


def mot_csv(labels: Sequence[LabelFrame]) -> str:
    """MOTChallenge-style rows ``frame,id,bb_left,bb_top,bb_width,bb_height,conf,x,y,z``.

    ``frame`` is 1-based; the box is the panorama box (-1 when the person has none); ``x, y`` are the
    odom-frame position when known, else the base-frame one; ``z`` is -1.
    """
    rows = []
    for f in labels:
        for p in f.people:
            if p.box is not None:
                u1, v1, u2, v2 = p.box
                bb = f"{u1:.1f},{v1:.1f},{u2 - u1:.1f},{v2 - v1:.1f}"
            else:
                bb = "-1,-1,-1,-1"
            x, y = (p.x_odom, p.y_odom) if p.x_odom is not None and p.y_odom is not None else (p.x, p.y)
            conf = 1.0 if p.score is None else p.score
            rows.append(f"{f.frame + 1},{p.id},{bb},{conf:.3f},{x:.3f},{y:.3f},-1")
    return "\n".join(rows) + ("\n" if rows else "")


def coco_json(
    labels: Sequence[LabelFrame],
    *,
    image_size: tuple[int, int] | None,
    file_pattern: str = "frames/{:06d}.jpg",
) -> dict[str, Any]:
    """COCO detection JSON of the panorama boxes, each annotation with its track id and positions."""
    w, h = image_size if image_size is not None else (0, 0)
    images: list[dict[str, Any]] = []
    anns: list[dict[str, Any]] = []
    for f in labels:
        images.append(
            {
                "id": f.frame,
                "file_name": file_pattern.format(f.frame),
                "width": w,
                "height": h,
                "stamp_ns": f.stamp_ns,
            }
        )
        for p in f.people:
            if p.box is None:
                continue
            u1, v1, u2, v2 = p.box
            anns.append(
                {
                    "id": len(anns) + 1,
                    "image_id": f.frame,
                    "category_id": 1,
                    "bbox": [round(u1, 1), round(v1, 1), round(u2 - u1, 1), round(v2 - v1, 1)],
                    "area": round((u2 - u1) * (v2 - v1), 1),
                    "iscrowd": 0,
                    "track_id": p.id,
                    "score": p.score,
                    "position_base": [round(p.x, 3), round(p.y, 3)],
                    "position_odom": None
                    if p.x_odom is None or p.y_odom is None
                    else [round(p.x_odom, 3), round(p.y_odom, 3)],
                    "source": p.source,
                }
            )
    return {
        "info": {
            "description": "studio auto-labels: people boxes on equirectangular panoramas",
            "version": __version__,
        },
        "images": images,
        "annotations": anns,
        "categories": [{"id": 1, "name": "person", "supercategory": "person"}],
    }


def package_versions() -> dict[str, str]:
    out = {"studio": __version__, "python": sys.version.split()[0], "platform": platform.platform()}
    for name in (
        "numpy",
        "scipy",
        "opencv-python-headless",
        "onnxruntime",
        "rosbags",
        "filterpy",
        "rerun-sdk",
    ):
        with contextlib.suppress(metadata.PackageNotFoundError):
            out[name] = metadata.version(name)
    return out


def write_label_files(
    run_dir: Path,
    labels: Sequence[LabelFrame],
    detections: Sequence[LabelFrame],
    *,
    image_size: tuple[int, int] | None,
    image_detections: Sequence[tuple[int, int, Any]] = (),
) -> int:
    """labels.yaml/.jsonl, detections.yaml, tracks_mot.csv, boxes_coco.json, review.jsonl (the moments
    where identities are worth checking, :mod:`studio.labels.review`) and the raw image detections
    (``image_detections.jsonl``, when the image detector ran) in ``run_dir``. Returns how many review
    points there are."""
    write_labels_yaml(run_dir / "labels.yaml", labels)
    write_labels_jsonl(run_dir / "labels.jsonl", labels)
    points = review_points(labels)
    write_review(run_dir / "review.jsonl", points)
    write_labels_yaml(run_dir / "detections.yaml", detections)
    atomic_write_text(run_dir / "tracks_mot.csv", mot_csv(labels))
    atomic_write_text(run_dir / "boxes_coco.json", json.dumps(coco_json(labels, image_size=image_size)))
    if image_detections:
        atomic_write_text(run_dir / "image_detections.jsonl", image_detections_jsonl(image_detections))
    return len(points)


def image_detections_jsonl(dets: Sequence[tuple[int, int, Any]]) -> str:
    """The image detector's raw output per frame, as ``studio detect-image`` writes it, plus frame/stamp."""
    lines = []
    for frame, stamp, d in dets:
        boxes = [
            [round(float(v), 1) for v in b] + [round(float(s), 4)]
            for b, s in zip(d.boxes, d.scores, strict=True)
        ]
        lines.append(
            json.dumps(
                {"frame": frame, "stamp_ns": stamp, "width": d.width, "height": d.height, "boxes": boxes},
                separators=(",", ":"),
            )
        )
    return "\n".join(lines) + ("\n" if lines else "")


def write_run_json(run_dir: Path, info: dict[str, Any]) -> None:
    atomic_write_text(
        run_dir / "run.json", json.dumps({**info, "versions": package_versions()}, indent=2, default=str)
    )
