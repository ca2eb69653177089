"""Benchmark: cube faces and detector views from a 1920×960 panorama, ViewRenderer vs py360convert's e2c.

Run: ``.venv/bin/python bench/bench_geometry.py [--frames 30] [--sizes 256 480]``

Prints, per face size, the median time per frame after the first (cached LUTs on both sides) of
``py360convert.e2c(..., cube_format="dict")`` and of :class:`studio.geometry.ViewRenderer` rendering the 6
faces (one stacked remap, and 6 separate remaps), the speed-up, and the pixel difference between the two.

py360convert's conventions, worked out here (and checked by the orientation search below): its faces
``F R B L U D`` are our ``front right back left up down`` with the same orientation (no flips); but it puts
the outermost pixel *centres* on the cube edges (``linspace(-0.5, 0.5, face_w)``), i.e. its focal length is
``(face_w - 1) / 2`` instead of ``face_w / 2`` (a field of view of ``2·atan(face_w / (face_w - 1))``, slightly
more than 90°). It also uses ``u = (az'/2π + 0.5)·W - 0.5`` with the azimuth ``az'`` clockwise, which is
our pixel convention. The pixel difference is reported both against views with py360convert's focal
length (same sampling: differences are interpolation only) and against our exact 90° faces.

Also times 8 horizon views rendered straight at a detector input size (256×256).
"""

from __future__ import annotations

import argparse
import math
import statistics
import time
from collections.abc import Callable
from functools import partial
from typing import Any

import cv2
import numpy as np

from studio.geometry import PerspectiveView, ViewRenderer, cube_faces, horizon_views

PY360_KEYS = {"front": "F", "right": "R", "back": "B", "left": "L", "up": "U", "down": "D"}


def make_panorama(width: int = 1920, height: int = 960, *, seed: int = 0) -> np.ndarray:
    """A textured synthetic panorama: smooth colour noise, a fine grid and an azimuth/elevation gradient."""
    rng = np.random.default_rng(seed)
    noise = rng.random((height // 8, width // 8, 3)).astype(np.float32)
    img = cv2.resize(noise, (width, height), interpolation=cv2.INTER_CUBIC) * 160.0
    jj, ii = np.mgrid[0:height, 0:width]
    img[..., 0] += 60.0 * (ii / width)
    img[..., 1] += 60.0 * (jj / height)
    img[(ii % 40 < 2) | (jj % 40 < 2)] = 250.0
    return np.clip(img, 0, 255).astype(np.uint8)


Timing = tuple[float, float, float, float]  # first ms, median wall ms, min wall ms, median CPU ms


def time_interleaved(fns: dict[str, Callable[[], Any]], frames: int) -> dict[str, Timing]:
    """Time each function once per round, ``frames`` rounds after a first call.

    Interleaved, so a busy machine slows all of them alike; the process CPU time (all threads) is
    reported too, as it is less disturbed by other processes than the wall-clock time.
    """
    first: dict[str, float] = {}
    for name, fn in fns.items():
        t0 = time.perf_counter()
        fn()
        first[name] = (time.perf_counter() - t0) * 1e3
    wall: dict[str, list[float]] = {name: [] for name in fns}
    cpu: dict[str, list[float]] = {name: [] for name in fns}
    for _ in range(frames):
        for name, fn in fns.items():
            t0, c0 = time.perf_counter(), time.process_time()
            fn()
            wall[name].append((time.perf_counter() - t0) * 1e3)
            cpu[name].append((time.process_time() - c0) * 1e3)
    return {k: (first[k], statistics.median(wall[k]), min(wall[k]), statistics.median(cpu[k])) for k in fns}


def report(res: dict[str, Timing], ref: str | None) -> None:
    """Print one line per method (and its speed-up over ``ref``)."""
    for name, (f1, med, best, cpu) in res.items():
        line = f"  {name:26s} first {f1:7.1f} ms | per frame: median {med:6.2f} ms, min {best:6.2f} ms"
        line += f", CPU {cpu:6.2f} ms"
        if ref is not None and name != ref:
            r = res[ref]
            line += f" | speed-up ×{r[1] / med:.2f} median, ×{r[2] / best:.2f} min, ×{r[3] / cpu:.2f} CPU"
        print(line)


def render_each(renderer: ViewRenderer, pano: np.ndarray, views: list[PerspectiveView]) -> list[np.ndarray]:
    """One ``remap`` call per view."""
    return [renderer.render(pano, v) for v in views]


def best_orientation(ours: np.ndarray, theirs: np.ndarray) -> tuple[str, float]:
    """Which of the 8 flips/rotations of ``ours`` matches ``theirs`` best, and its mean abs diff."""
    cands = {
        "identity": ours,
        "flip-lr": ours[:, ::-1],
        "flip-ud": ours[::-1],
        "rot180": ours[::-1, ::-1],
        "transpose": ours.transpose(1, 0, 2),
        "rot90": np.rot90(ours, 1),
        "rot270": np.rot90(ours, 3),
        "anti-transpose": np.rot90(ours, 2).transpose(1, 0, 2),
    }
    scores = {
        k: float(np.abs(v.astype(np.float32) - theirs.astype(np.float32)).mean()) for k, v in cands.items()
    }
    k = min(scores, key=lambda name: scores[name])
    return k, scores[k]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--frames", type=int, default=30, help="timed frames after the first (median)")
    ap.add_argument("--sizes", type=int, nargs="+", default=[256, 480], help="cube face sizes, px")
    ap.add_argument("--threads", type=int, default=None, help="cv2.setNumThreads (default: OpenCV's choice)")
    args = ap.parse_args()
    if args.threads is not None:
        cv2.setNumThreads(args.threads)
    import py360convert

    pano = make_panorama()
    h, w = pano.shape[:2]
    threads = cv2.getNumThreads()
    print(f"panorama {w}×{h} uint8, OpenCV {cv2.__version__}, {threads} threads, {args.frames} frames")

    for s in args.sizes:
        renderer = ViewRenderer()
        faces = cube_faces(s)
        order = list(faces.values())
        fns: dict[str, Callable[[], Any]] = {
            "py360convert.e2c": partial(py360convert.e2c, pano, face_w=s, cube_format="dict"),
            "ViewRenderer.render_many": partial(renderer.render_many, pano, order),
            "ViewRenderer.render ×6": partial(render_each, renderer, pano, order),
        }
        res = time_interleaved(fns, args.frames)
        print(f"\ncube faces {s}×{s} px ×6")
        report(res, "py360convert.e2c")

        theirs = py360convert.e2c(pano, face_w=s, cube_format="dict")
        ours = dict(zip(faces, renderer.render_many(pano, order), strict=True))
        fov_p = 2.0 * math.atan(s / (s - 1.0))  # py360convert's sampling: f = (s - 1) / 2
        same = {
            k: renderer.render(pano, PerspectiveView(v.yaw, v.pitch, fov_p, s, s, name=k + "-py360"))
            for k, v in faces.items()
        }
        print("  face  orientation   mean|Δ| vs py360-sampled view  mean|Δ| vs exact 90° face  p99|Δ| (same)")
        for k in faces:
            t = theirs[PY360_KEYS[k]]
            orient, _ = best_orientation(ours[k], t)
            d_same = np.abs(same[k].astype(np.float32) - t.astype(np.float32))
            d_90 = np.abs(ours[k].astype(np.float32) - t.astype(np.float32))
            print(
                f"  {k:5s} {orient:12s}  {d_same.mean():10.3f} levels{'':17s}{d_90.mean():8.3f} levels"
                f"{'':10s}{np.percentile(d_same, 99):6.1f}"
            )

    views = horizon_views(count=8, fov=math.radians(90.0), width=256, height=256)
    renderer = ViewRenderer()
    fns = {
        "ViewRenderer.render_many": partial(renderer.render_many, pano, views),
        "ViewRenderer.render ×8": partial(render_each, renderer, pano, views),
    }
    res = time_interleaved(fns, args.frames)
    print("\n8 horizon views 256×256 px, 90° fov (detector input size)")
    report(res, None)


if __name__ == "__main__":
    main()
