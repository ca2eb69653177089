"""``--export-frames``: make the run directory a self-contained dataset (panoramas + labels + card)."""

from __future__ import annotations

from collections import Counter
from pathlib import Path
from typing import Any

from studio import __version__
from studio.detect.laser.classical import ClassicalLaserDetector

__all__ = ["FrameExporter", "dataset_card"]


class FrameExporter:
    """Writes each frame's panorama as ``frames/NNNNNN.jpg`` (the original JPEG bytes when there are any)."""

    def __init__(self, folder: Path) -> None:
        self.folder = folder
        self.folder.mkdir(parents=True, exist_ok=True)
        self.count = 0

    def on_frame(self, frame: Any, perception: Any) -> None:
        pano = frame.panorama
        if pano is None:
            return
        path = self.folder / f"{frame.index:06d}.jpg"
        if pano.encoded is not None and pano.encoding.lower() in ("jpeg", "jpg"):
            path.write_bytes(pano.encoded)
        else:
            import cv2

            ok, buf = cv2.imencode(".jpg", pano.image, [cv2.IMWRITE_JPEG_QUALITY, 92])
            if not ok:
                raise RuntimeError(f"could not encode frame {frame.index} as JPEG")
            path.write_bytes(buf.tobytes())
        self.count += 1

    def finish(self, run_dir: Path, result: Any, *, options: Any, recording: Path, rig: Any) -> None:
        from studio.atomic import atomic_write_text

        atomic_write_text(
            run_dir / "DATASET.md",
            dataset_card(result, options=options, recording=recording, rig=rig, n_images=self.count),
        )


def dataset_card(result: Any, *, options: Any, recording: Path, rig: Any, n_images: int) -> str:
    """A markdown dataset card: sensors, calibration, method, label provenance, known limits."""
    sources: Counter[str] = Counter()
    for lf in result.labels:
        for p in lf.people:
            sources[p.source or "unknown"] += 1
    n_labels = sum(sources.values())
    cam = rig.camera
    cam_pose = cam.pose.as_dict() if cam is not None and cam.pose is not None else None
    lines = [
        "# People in panoramas — dataset card",
        "",
        f"Made by `studio label` {__version__} from `{recording.name}`.",
        "",
        "## Contents",
        f"- `frames/NNNNNN.jpg`: {n_images} equirectangular panoramas"
        + (f" ({result.image_size[0]}×{result.image_size[1]})" if result.image_size else ""),
        "- `labels.yaml` (thesis format) and `labels.jsonl`: per frame, people with track ids, positions in "
        "the "
        f"base frame `{rig.base_frame}` and in the odom frame, covariance, source, panorama box",
        "- `boxes_coco.json`: COCO boxes (category person) with `track_id`, `position_base`, `position_odom`",
        "- `tracks_mot.csv`: MOTChallenge-style rows (1-based frame, id, box, score, odom x, y)",
        "- `detections.yaml`: per-frame fused detections before tracking",
        "- `review.jsonl`: the moments where identities are worth checking (two tracks that met, a track "
        "seen again after a gap, a track that began mid-run), each with its frame, tracks, a note and a "
        "doubt (0-1: the likeliest errors first)",
        "- `run.json`: options, versions, timings",
        "",
        "## Sensors and calibration",
        f"- camera: `{cam.topic}`, pose in `{rig.base_frame}`: {cam_pose}"
        if cam is not None
        else "- no camera",
    ]
    beam_deg = (getattr(result, "counts", None) or {}).get("laser_beam_deg") or {}
    sweep_ms = (getattr(result, "counts", None) or {}).get("laser_sweep_ms") or {}
    for las in rig.lasers:
        pose = las.pose.as_dict() if las.pose is not None else "from TF in the recording"
        line = f"- laser `{las.topic}`, pose: {pose}"
        c = getattr(las, "cloud", None)
        if c is not None:
            line += (
                f", a 3-D lidar's point clouds sliced into a planar scan (points {c.min_z:g} to "
                f"{c.max_z:g} m in its frame, the nearest of each bearing)"
            )
        step = beam_deg.get(las.topic)
        if step is not None:
            line += f", beams {step:.2f}° apart"
            if (options.laser_detector or "classical") == "classical" and options.sources != "camera":
                coarse = ClassicalLaserDetector().is_coarse(step)
                line += " (coarse-beam leg model)" if coarse else " (leg model for fine beams)"
        sweep = sweep_ms.get(las.topic)
        if sweep is not None:
            line += (
                f", swept in {sweep:.1f} ms (each beam placed and timed by its own measurement time)"
                if sweep > 0
                else ", no beam timing in its scans (all beams taken at the scan's stamp)"
            )
        lines.append(line)
    odo = rig.odometry
    matched = (
        options.method == "studio" and options.scan_matching and options.sources != "camera" and rig.lasers
    )
    if odo is not None:
        lines.append(f"- odometry: {odo}" + (", drift corrected by scan matching" if matched else ""))
    else:
        lines.append(
            "- odometry: none; the robot's motion from scan matching (the odom positions are in its frame, "
            "the first frame's pose its origin)"
            if matched
            else "- odometry: none (static robot assumed)"
        )
    lines += [
        "",
        "## How the labels were produced",
        f"- method `{options.method}`, sources `{options.sources}`"
        + (" (the rig has no camera: laser only)" if cam is None and options.sources == "both" else "")
        + ", image detector "
        f"`{options.image_detector or 'movenet'}`, laser detector `{options.laser_detector or 'classical'}`",
        "- people boxes on perspective views around the horizon, mapped back to the panorama;",
        "  laser people from a classical leg detector (legs paired with the previous scans) with a",
        "  static-world filter; fused on the sphere",
        "  with the camera pose above; tracked in the odom frame, corrected by scan matching (UKF, global",
        "  nearest neighbour); positions in the odom frame are given in the recording's own odometry,",
        "  tracks RTS-smoothed, tracklets stitched.",
        f"- {n_labels} person labels; by source: "
        + ", ".join(f"{k} {v} ({100.0 * v / max(n_labels, 1):.0f} %)" for k, v in sources.most_common()),
        "  (`fused`: box confirmed by laser; `laser`: laser only, on a rig with a camera output only near",
        "  frames where the camera saw that person, alone or in one box with someone beside them; `image`:",
        "  range from the box's foot row;",
        '  people marked `"interpolated": true` in labels.jsonl bridge a gap of up to '
        f"{options.tracking.interpolate_max_gap_s:g} s with the smoother)",
        "",
        "## Known limits",
        "- These are automatic labels: check them (`studio annotate`) before using them as ground truth. "
        "Identity switches lie mostly at the moments `review.jsonl` lists (on simulated recordings 94 % "
        "within 2 s of one, 7.6 per minute); the annotator's key c goes from one to the next, key x to the "
        "most doubtful one.",
        "- Image-only positions assume a flat floor at z = 0 of the base frame and visible feet.",
        "- Someone who stands on one spot for most of the time the laser sees it may be filtered out as "
        "structure, unless the laser saw the spot empty from within 4 m while the robot moved.",
    ]
    if options.method == "studio":
        lines.append(
            f"- A track spanning less than {options.tracking.min_track_duration_s:g} s is left out: someone "
            "seen only that briefly has no label (most such pieces were a few frames of someone whose own "
            "track went on around them)."
        )
    if (cam is None or options.sources == "laser") and options.min_walk_m > 0:
        lines.append(
            f"- Without the camera a track is kept only if it walked {options.min_walk_m:g} m somewhere "
            "(furniture stands still), over places the laser saw free most of the time or saw someone leave: "
            "someone who stood still for the whole recording is not labelled, nor a walk through a crowd "
            "so dense that its path was occupied 30 % of the time."
        )
    lines += [
        f"- The recording did not end as a recorder ends it, and was read as far as it goes: {n}."
        for n in result.notes
        if "its recording was interrupted" in n  # studio.io's notes on unfinished or cut recordings
    ]
    if any("oracle" in n for n in result.notes) or (options.image_detector or "").startswith("oracle"):
        lines.append("- Boxes come from the ORACLE detector (ground truth with noise): simulated data only.")
    return "\n".join(lines) + "\n"
