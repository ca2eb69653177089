"""``studio calibrate extrinsics|project`` (DESIGN.md §2); ``targets``, ``intrinsics`` and ``people`` live in
:mod:`studio.commands.calibrate_targets` and :mod:`studio.commands.calibrate_people`.

* ``extrinsics --correspondences FILE.csv --image-size WxH [--folds K] [--json OUT] --out calib.yaml``:
  fits the camera pose with the central and the dual-lens camera model, prints both models'
  cross-validated errors and keeps the dual-lens one only when it pays off
  (:mod:`studio.calibrate.lens`), writes ``calib.yaml`` (a rig fragment: ``camera.pose``,
  ``camera.lens_offset`` when the dual-lens model is kept, + a ``calibration`` block) and
  ``<out stem>_report.txt`` / ``_report.png`` / ``_report.rrd`` (Rerun, for
  ``studio view FILE --blueprint calibration``) beside it.
* ``project --rig RIG_OR_CALIB.yaml --points FILE.csv --image-size WxH --out UV.csv``: projects ``x,y,z``
  rows with the camera (pose and lens offset) of a rig.yaml or a calib.yaml and writes ``u,v`` in the same
  order.

Every input problem raises a :class:`~studio.errors.StudioError` before any file is written.
"""

from __future__ import annotations

import argparse
import datetime as _dt
import json
import math
from pathlib import Path
from typing import Any

import yaml

from studio.atomic import atomic_write_text, out_file
from studio.errors import StudioError
from studio.yamlload import load_yaml

__all__ = ["load_camera", "load_camera_pose", "run"]


def run(args: argparse.Namespace) -> int:
    if args.calib_command == "extrinsics":
        return _extrinsics(args)
    if args.calib_command == "project":
        return _project(args)
    if args.calib_command in ("targets", "intrinsics"):
        from studio.commands import calibrate_targets

        fn = (
            calibrate_targets.run_targets
            if args.calib_command == "targets"
            else calibrate_targets.run_intrinsics
        )
        return fn(args)
    if args.calib_command == "people":
        from studio.commands.calibrate_people import run_people

        return run_people(args)
    raise StudioError(f"unknown calibrate subcommand '{args.calib_command}'")


def _extrinsics(args: argparse.Namespace) -> int:
    from studio.calibrate.csvio import read_columns
    from studio.calibrate.lens import choose_lens_model
    from studio.calibrate.report import write_report
    from studio.viz.calibration import write_calibration_rrd

    out = out_file(args.out, "--out", inputs=[args.correspondences])
    json_out = out_file(args.json, "--json", inputs=[args.correspondences, args.out])
    stem = out.with_suffix("") if out.suffix else out
    for report in ("_report.txt", "_report.png", "_report.rrd"):  # written beside --out
        out_file(stem.with_name(stem.name + report), "--out", inputs=[args.correspondences, args.out])
    if args.folds < 2:
        raise StudioError(f"--folds must be at least 2, got {args.folds}")
    W, H = args.image_size
    table = read_columns(args.correspondences, ("x", "y", "z", "u", "v"), optional=("z",))
    xyz, uv = table.values[:, :3], table.values[:, 3:]
    labels = table.labels()
    choice = choose_lens_model(xyz, uv, image_size=(W, H), folds=int(args.folds), labels=labels)
    cv = choice.kept
    fit = cv.fit
    metrics = choice.to_json()
    pose = {k: round(v, 6) + 0.0 for k, v in fit.pose.as_dict().items()}
    camera: dict[str, Any] = {"pose": pose}
    model = "spherical model"
    if choice.dual_kept:
        camera["lens_offset"] = round(fit.lens_offset, 6) + 0.0
        model = "dual-lens spherical model, lens offset fitted"
    calib: dict[str, Any] = {
        "camera": camera,
        "calibration": {
            "method": f"extrinsics from correspondences ({model}, robust least squares)",
            "correspondences": str(args.correspondences),
            "image_size": [int(W), int(H)],
            "n": fit.n,
            "n_outliers": fit.n_outliers,
            "outlier_threshold_px": round(fit.threshold_px, 3),
            "z_constant": fit.z_constant,
            "lens_model": choice.reason,
            "cross_validation": {k: v for k, v in metrics.items() if k not in ("z_constant", "lens_model")},
            "date": _dt.datetime.now(_dt.UTC).strftime("%Y-%m-%dT%H:%M:%SZ"),
        },
    }
    if fit.z_constant:
        calib["calibration"]["note"] = "all points share one z: camera z is relative to that plane"

    print(f"studio calibrate extrinsics: {args.correspondences} ({fit.n} points, image {W}×{H} px)")
    if W != 2 * H:
        print(f"warning: {W}×{H} is not 2:1; an equirectangular panorama spans 360°×180°; check --image-size")
    p = fit.pose.as_dict()
    print(
        f"camera pose: x {p['x']:+.4f} m  y {p['y']:+.4f} m  z {p['z']:+.4f} m  "
        f"roll {math.degrees(p['roll']):+.3f}°  pitch {math.degrees(p['pitch']):+.3f}°  "
        f"yaw {math.degrees(p['yaw']):+.3f}°"
    )
    print(cv.table())
    print(_lens_table(choice))
    if cv.folds != int(args.folds):
        print(f"note: {fit.n} points: {cv.folds}-fold cross-validation instead of --folds {args.folds}")
    if fit.n_outliers:
        rej = [labels[i] for i in range(fit.n) if not fit.inliers[i]]
        shown = ", ".join(rej[:12]) + (f" and {len(rej) - 12} more" if len(rej) > 12 else "")
        print(f"rejected as outliers (> {fit.threshold_px:.1f} px): {shown}")

    text = "# studio calibrate extrinsics: camera pose T_base_cam (metres, radians)\n"
    text += yaml.safe_dump(calib, sort_keys=False, default_flow_style=None, allow_unicode=True)
    try:  # the calibration last: a report that cannot be written leaves no new calibration behind
        txt, png = write_report(stem, cv, xyz, uv, source=str(args.correspondences), labels=labels)
        rrd = stem.with_name(stem.name + "_report.rrd")
        write_calibration_rrd(rrd, cv, xyz, uv)
        if json_out is not None:
            atomic_write_text(json_out, json.dumps(metrics, indent=2) + "\n")
        atomic_write_text(out, text)
    except OSError as exc:
        raise StudioError(f"cannot write the calibration output: {exc}") from None
    print(
        f"calibration written to {out}; report {txt}, {png}" + (f"; metrics {json_out}" if json_out else "")
    )
    print(f"view it: studio view {rrd} --blueprint calibration")
    return 0


def _lens_table(choice: Any) -> str:
    """Both lens models' held-out column errors, the kept one marked, and the reason."""
    head = "lens model (held-out column px)"
    lines = [f"{head:<38} {'mean':>8} {'median':>8}"]
    rows = [("central (one centre)", choice.single, not choice.dual_kept)]
    if choice.dual is not None:
        f = choice.dual.fit
        rows.append(
            (
                f"dual-lens b {f.lens_offset * 100:+.2f}±{f.lens_offset_std * 100:.2f} cm",
                choice.dual,
                choice.dual_kept,
            )
        )
    for name, cv, kept in rows:
        j = cv.to_json()
        lines.append(
            f"{name:<38} {j['col_px_mean']:>8.2f} {j['col_px_median']:>8.2f}" + ("  <- kept" if kept else "")
        )
    lines.append(choice.reason)
    return "\n".join(lines)


def load_camera_pose(path: str) -> Any:
    """The camera pose ``T_base_cam`` (:class:`~studio.geometry.se.Pose3`) of a rig.yaml or calib.yaml.

    Raises:
        StudioError: missing/unreadable file, invalid YAML or rig, no camera pose.
    """
    return load_camera(path).pose


def load_camera(path: str) -> Any:
    """The camera (:class:`~studio.io.rig.CameraConfig`: pose, lens offset) of a rig.yaml or calib.yaml.

    Raises:
        StudioError: missing/unreadable file, invalid YAML or rig, no camera pose.
    """
    from studio.io.rig import parse_rig

    p = Path(path)
    try:
        data = load_yaml(p.read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise StudioError(f"rig file not found: {p}") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise StudioError(f"cannot read {p}: {exc}") from None
    except yaml.YAMLError as exc:
        raise StudioError(f"{p}: not valid YAML: {getattr(exc, 'problem', None) or exc}") from None
    if not isinstance(data, dict):
        raise StudioError(f"{p}: expected a rig.yaml or calib.yaml mapping")
    data = {k: v for k, v in data.items() if k != "calibration"}
    cam = data.get("camera")
    if "base_frame" not in data:
        # calib.yaml: a rig fragment; validate its pose with the rig's own checks
        if not isinstance(cam, dict):
            raise StudioError(f"{p}: no 'camera' with a 'pose' (expected a rig.yaml or calib.yaml)")
        data = {"base_frame": "base_link", "camera": {"topic": cam.get("topic", "/camera"), **cam}}
    rig = parse_rig(data, source=str(p))
    if rig.camera is None or rig.camera.pose is None:
        raise StudioError(f"{p}: the rig has no camera pose ('camera.pose'); calibrate it first")
    return rig.camera


def _project(args: argparse.Namespace) -> int:
    import numpy as np

    from studio.calibrate.csvio import read_points, write_uv
    from studio.calibrate.extrinsics import project_points

    out = out_file(args.out, "--out", inputs=[args.points, args.rig])
    cam = load_camera(args.rig)
    xyz = read_points(args.points)
    W, H = args.image_size
    uv = project_points(cam.pose, xyz, image_size=(W, H), lens_offset=cam.lens_offset)
    try:
        write_uv(out, uv)
    except OSError as exc:
        raise StudioError(f"--out {out}: cannot write ({exc.strerror or exc})") from None
    bad = int((~np.isfinite(uv).all(axis=1)).sum())
    note = f" ({bad} at the camera centre left empty)" if bad else ""
    print(f"studio calibrate project: {len(xyz)} points → {out}{note}")
    return 0
