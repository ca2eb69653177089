"""``studio label RECORDING --rig RIG --out RUN``."""

from __future__ import annotations

import argparse
import time
from pathlib import Path
from typing import Any

from studio.atomic import atomic_dir, check_replaceable
from studio.errors import StudioError

__all__ = ["RUN_OUTPUTS", "run", "run_label"]

# What a run directory holds (``run.json`` first: it marks an earlier run, which a new one replaces);
# ``metrics.json`` is ``studio demo``'s. A directory holding anything else (annotations, the user's files)
# is never replaced.
RUN_OUTPUTS = (
    "run.json",
    "labels.yaml",
    "labels.jsonl",
    "detections.yaml",
    "tracks_mot.csv",
    "boxes_coco.json",
    "image_detections.jsonl",
    "review.jsonl",
    "recording.rrd",
    "frames",
    "DATASET.md",
    "metrics.json",
)


def run_label(
    recording: Path,
    rig_path: Path,
    out: Path,
    *,
    options: Any,
    write_rrd: bool = True,
    ground_truth: Path | None = None,
    quiet: bool = False,
) -> dict[str, Any]:
    """Label ``recording`` into the run directory ``out`` (written atomically; an earlier run there is
    replaced, a directory holding anything else is refused). Returns run.json's content."""
    from tqdm import tqdm

    from studio.io import load_rig
    from studio.pipeline import label_recording, observations_to_frames
    from studio.pipeline.outputs import write_label_files, write_run_json

    if not recording.exists():
        raise StudioError(f"{recording}: no such recording")
    check_replaceable(out, RUN_OUTPUTS, "studio label run")
    rig = load_rig(rig_path)
    bars: list[Any] = []

    def progress(done: int, total: int) -> None:
        if not bars:  # made on the first frame, so an unreadable recording prints only its error
            # disable=None: no bar when stderr is not a terminal (logs, CI)
            bars.append(
                tqdm(
                    total=total,
                    unit="frame",
                    desc="labeling",
                    disable=True if quiet else None,
                    leave=False,
                    mininterval=0.5,
                )
            )
        bar = bars[0]
        bar.total = total
        bar.update(done - bar.n)

    hooks: list[Any] = []
    t0 = time.perf_counter()
    with atomic_dir(out, outputs=RUN_OUTPUTS, what="studio label run") as tmp:
        exporter = None
        if options.export_frames:
            from studio.pipeline.export import FrameExporter

            exporter = FrameExporter(tmp / "frames")
            hooks.append(exporter)
        logger = None
        if write_rrd:
            try:
                from studio.viz.log import RunLogger
            except ModuleNotFoundError as exc:
                if not (exc.name or "").startswith("studio.viz"):
                    raise
            else:
                logger = RunLogger(tmp / "recording.rrd", rig=rig)
                hooks.append(logger)

        def on_frame(frame: Any, pf: Any) -> None:
            for h in hooks:
                h.on_frame(frame, pf)

        try:
            result = label_recording(recording, rig, options=options, progress=progress, on_frame=on_frame)
        finally:
            for bar in bars:
                bar.close()
        detections = observations_to_frames(result.detections)
        result.counts["review_points"] = write_label_files(
            tmp,
            result.labels,
            detections,
            image_size=result.image_size,
            image_detections=result.image_detections,
        )
        if logger is not None:
            t_viz = time.perf_counter()
            logger.finish(result, ground_truth=ground_truth)
            result.timings_s["rerun_logging"] = logger.seconds + (time.perf_counter() - t_viz)
        if exporter is not None:
            exporter.finish(tmp, result, options=options, recording=recording, rig=rig)
        info = {
            "recording": str(recording),
            "rig": str(rig_path),
            "options": options.as_dict(),
            "image_detector": options.image_detector or ("movenet" if result.camera is not None else None),
            "image_size": result.image_size,
            "timings_s": {k: round(v, 3) for k, v in result.timings_s.items()},
            "wall_s": round(time.perf_counter() - t0, 3),
            "counts": result.counts,
            "notes": result.notes,
            "rrd": "recording.rrd" if logger is not None else None,
        }
        write_run_json(tmp, info)
    return info


def run(args: argparse.Namespace) -> int:
    from studio.pipeline import LabelOptions

    options = LabelOptions(
        method=args.method,
        sources=args.sources,
        image_detector=args.image_detector,
        laser_detector=args.laser_detector,
        export_frames=args.export_frames,
        **({} if args.min_walk is None else {"min_walk_m": args.min_walk}),
    )
    gt = Path(args.ground_truth) if args.ground_truth else None
    if gt is not None:
        if args.no_rrd:
            raise StudioError(
                "--ground-truth is shown beside the labels in the Rerun recording, which --no-rrd leaves "
                "out: drop one of them (studio evaluate compares a run with ground truth)"
            )
        if not gt.is_file():
            raise StudioError(f"{gt}: no such ground-truth file")
        from studio.labels import read_labels

        read_labels(gt)  # a broken file is one error now, not after the whole recording is labeled
    info = run_label(
        Path(args.recording),
        Path(args.rig),
        Path(args.out),
        options=options,
        write_rrd=not args.no_rrd,
        ground_truth=gt,
    )
    c = info["counts"]
    print(
        f"labeled {c['frames']} frames, {c['tracks']} tracks, {c['observations']} observations "
        f"in {info['wall_s']:.1f} s → {args.out}"
    )
    n = c.get("review_points", 0)
    if n:
        print(
            f"{n} moment{'s' * (n != 1)} where identities are worth checking: {args.out}/review.jsonl "
            f"(studio annotate {args.out}: key c the next, key x the most doubtful)"
        )
    for note in info["notes"]:
        print(f"note: {note}")
    return 0
