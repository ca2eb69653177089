"""``studio calibrate targets`` and ``studio calibrate intrinsics`` (issue #7 parts 1 and 3).

``run_targets(args)`` options (argparse attributes): ``recording``, ``rig``, ``target`` (``ball`` |
``board``), ``out`` (CSV), ``ball_radius`` (m, 0.25), ``board_width`` (m, 0.8), ``max_offset`` (s, 0.5;
0 turns the time-offset search off), ``include_moving`` (bool), ``json`` (report file or None).

``run_intrinsics(args)`` options: ``source`` (a recording, or a folder of panorama images), ``rig`` (needed
for a recording), ``pattern`` (``(cols, rows)`` inner corners, (8, 5)), ``square`` (m, 0.07),
``face_size`` (px or None), ``every`` (use every n-th panorama, 1), ``json`` (report file or None).
"""

from __future__ import annotations

import argparse
import io
import json
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from studio.atomic import atomic_write_text, out_file
from studio.geometry.equirect import not_equirect

__all__ = ["run_intrinsics", "run_targets", "write_correspondences"]

_IMAGE_SUFFIXES = (".jpg", ".jpeg", ".png")


def write_correspondences(
    path: str | Path,
    xyz: NDArray[np.float64],
    uv: NDArray[np.float64],
    stamp_ns: NDArray[np.int64],
    *,
    target: str,
    still: NDArray[np.bool_] | None = None,
    t0_ns: int | None = None,
) -> None:
    """Write ``x,y,z,u,v,t,stamp_ns,still,target`` rows.

    Units: metres in the base frame, px, seconds since ``t0_ns`` (default: the first stamp), ns.
    """
    t0 = int(stamp_ns.min()) if t0_ns is None and stamp_ns.size else int(t0_ns or 0)
    buf = io.StringIO()
    buf.write("x,y,z,u,v,t,stamp_ns,still,target\n")
    st = np.ones(xyz.shape[0], dtype=bool) if still is None else still
    for p, q, s, k in zip(xyz, uv, stamp_ns, st, strict=True):
        buf.write(
            f"{p[0]:.5f},{p[1]:.5f},{p[2]:.5f},{q[0]:.4f},{q[1]:.4f},{(int(s) - t0) * 1e-9:.4f},{int(s)},"
            f"{int(bool(k))},{target}\n"
        )
    atomic_write_text(path, buf.getvalue())


def _fit_summary(
    xyz: NDArray[np.float64], uv: NDArray[np.float64], size: tuple[int, int]
) -> dict[str, Any] | None:
    from studio.calibrate.extrinsics import CalibrationError, fit_extrinsics

    try:
        fit = fit_extrinsics(xyz, uv, image_size=size)
    except CalibrationError:
        return None
    res = np.hypot(fit.residual_px[fit.inliers, 0], fit.residual_px[fit.inliers, 1])
    return {
        "pose": {k: round(v, 6) for k, v in fit.pose.as_dict().items()},
        "n": int(fit.n),
        "n_outliers": int(fit.n_outliers),
        "residual_px_mean": round(float(res.mean()), 4) if res.size else None,
    }


def run_targets(args: argparse.Namespace) -> int:
    """Extract target correspondences from a calibration recording and write them as CSV."""
    from tqdm import tqdm

    from studio.calibrate.targets import TargetError, iter_panoramas, read_scans
    from studio.io import load_rig, open_recording

    target = str(getattr(args, "target", "ball"))
    if target not in ("ball", "board"):
        raise TargetError(f"--target must be ball or board, got '{target}'")
    out_file(args.out, "--out", inputs=[args.recording, args.rig])
    out_file(getattr(args, "json", None), "--json", inputs=[args.recording, args.rig, args.out])
    rig = load_rig(args.rig)
    if rig.camera is None:
        raise TargetError(f"{args.rig}: the rig has no camera")
    report: dict[str, Any] = {"target": target, "recording": str(args.recording)}
    with open_recording(args.recording) as rec:
        scans = read_scans(rec, rig)
        n_img = 0
        size = (0, 0)
        if target == "ball":
            from studio.calibrate.targets.ball import ball_correspondences, find_ball_in_panorama

            radius = float(getattr(args, "ball_radius", 0.25))
            dets: list[tuple[int, float, float]] = []
            for pano in tqdm(iter_panoramas(rec, rig), desc="ball in panoramas", unit="image", leave=False):
                n_img += 1
                size = (pano.width, pano.height)
                hit = find_ball_in_panorama(pano.image)
                if hit is not None:
                    dets.append((pano.stamp_ns, hit[0], hit[1]))
            res = ball_correspondences(
                scans, dets, radius=radius, image_size=size,
                max_offset_s=float(getattr(args, "max_offset", 0.5)),
                n_images=n_img,
            )  # fmt: skip
            keep = np.ones(res.still.shape, bool) if getattr(args, "include_moving", False) else res.still
            xyz, uv, st, still = res.xyz[keep], res.uv[keep], res.stamp_ns[keep], res.still[keep]
            report.update(
                n_images=n_img, n_ball_images=res.n_ball_images, n_still_stations=int(res.still.sum()),
                n_moving_rows=int((~res.still).sum()), time_offset_s=res.offset_s,
                offset_curve=res.offset_curve,
            )  # fmt: skip
        else:
            from studio.calibrate.targets.board import board_calibration

            panos = tqdm(iter_panoramas(rec, rig), desc="board in panoramas", unit="image", leave=False)
            bres = board_calibration(scans, panos, width=float(getattr(args, "board_width", 0.8)))
            n_img, size = bres.n_images, bres.image_size
            xyz, uv, st, still = bres.xyz, bres.uv, bres.stamp_ns, np.ones(bres.xyz.shape[0], bool)
            report.update(bres.to_json())
    write_correspondences(args.out, xyz, uv, st, target=target, still=still)
    fit = _fit_summary(xyz, uv, size)
    report.update(rows=int(xyz.shape[0]), image_size=list(size), fit=fit)
    if getattr(args, "json", None):
        atomic_write_text(args.json, json.dumps(report, indent=2) + "\n")
    print(
        f"studio calibrate targets: {target}, {n_img} panoramas, {xyz.shape[0]} correspondences → {args.out}"
    )
    if target == "ball":
        off = report.get("time_offset_s")
        print(f"  time offset (image stamp − capture): {'not found' if off is None else f'{off:+.3f} s'}")
    else:
        share = report.get("homography", {}).get("hit_share")
        if share is not None:
            print(f"  per-face homographies: {share * 100:.1f} % of board laser points within "
                  f"{report['homography']['hit_px']:g} px of the board line (thesis Table 4.4)")  # fmt: skip
    if fit is not None:
        pose = " ".join(f"{k}={v:+.4f}" for k, v in fit["pose"].items())
        print(f"  spherical fit: {pose}  ({fit['n']} rows, mean residual {fit['residual_px_mean']} px)")
    return 0


def _images_in(folder: Path) -> Iterator[NDArray[np.uint8]]:
    import cv2

    from studio.calibrate.targets import TargetError

    files = sorted(p for p in folder.iterdir() if p.suffix.lower() in _IMAGE_SUFFIXES)
    if not files:
        raise TargetError(f"{folder}: no .jpg or .png panoramas")
    for f in files:
        img = cv2.imread(str(f), cv2.IMREAD_COLOR)
        if img is None:
            raise TargetError(f"{f}: cannot read the image")
        if (wrong := not_equirect(img.shape[1], img.shape[0])) is not None:
            raise TargetError(f"{f} is {wrong}")
        yield np.asarray(img, dtype=np.uint8)


def run_intrinsics(args: argparse.Namespace) -> int:
    """Per-face checkerboard calibration of the panoramas of a recording (or a folder) and the verdict."""
    from studio.calibrate.targets import TargetError, iter_panoramas
    from studio.calibrate.targets.checkerboard import calibrate_faces
    from studio.io import load_rig, open_recording

    src = Path(args.source)
    if not src.exists():
        raise TargetError(f"{src}: no such recording or folder of panoramas")
    if src.is_file() and src.suffix.lower() in _IMAGE_SUFFIXES:
        raise TargetError(f"{src} is one image: give the folder that holds the panoramas of the checkerboard")
    out_file(getattr(args, "json", None), "--json", inputs=[src, getattr(args, "rig", None)])
    pattern = tuple(getattr(args, "pattern", (8, 5)))
    kw = {"pattern": (int(pattern[0]), int(pattern[1])), "square": float(getattr(args, "square", 0.07)),
          "face_size": getattr(args, "face_size", None)}  # fmt: skip
    every = max(int(getattr(args, "every", 1) or 1), 1)
    if src.is_dir() and not (src / "metadata.yaml").exists():
        imgs = (img for k, img in enumerate(_images_in(src)) if k % every == 0)
        rep = calibrate_faces(imgs, **kw)  # type: ignore[arg-type]
    else:
        if getattr(args, "rig", None) is None:
            raise TargetError("--rig is needed to read the panoramas of a recording")
        rig = load_rig(args.rig)
        with open_recording(src) as rec:
            rep = calibrate_faces((p.image for p in iter_panoramas(rec, rig, every=every)), **kw)  # type: ignore[arg-type]
    if getattr(args, "json", None):
        atomic_write_text(args.json, json.dumps(rep.to_json(), indent=2) + "\n")
    print(f"studio calibrate intrinsics: {rep.n_panoramas} panoramas, faces {rep.face_size} px (f ideal "
          f"{rep.face_size / 2:g} px)")  # fmt: skip
    print(rep.table())
    return 0
