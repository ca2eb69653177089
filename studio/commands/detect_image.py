"""``studio detect-image PANORAMA... --out FILE.jsonl [--image-detector NAME|PATH]``.

Runs the image people detector alone. One JSON line per image, in the order given:
``{"image", "width", "height", "boxes": [[u1, v1, u2, v2, score], ...], "keypoints": [[[u, v, score] × 17],
...]}`` (panorama px; ``u2`` may exceed ``width`` for a box across the seam; ``keypoints`` only when the
detector has them). The file is written atomically once every image is done.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path
from typing import Any

import cv2
import numpy as np

from studio.atomic import out_file, write_out
from studio.detect.image import ImageDetections, get_image_detector
from studio.errors import StudioError
from studio.geometry.equirect import not_equirect
from studio.io.decode import looks_dual_fisheye

__all__ = ["detection_record", "read_panorama", "run"]


def read_panorama(path: str | Path) -> np.ndarray:
    """Decode an image file as BGR uint8 ``(H, W, 3)``; StudioError when missing, unreadable or not an
    equirectangular panorama (twice as wide as high)."""
    p = Path(path)
    if not p.is_file():
        raise StudioError(f"image not found: {p}")
    data = np.fromfile(str(p), dtype=np.uint8)
    img = cv2.imdecode(data, cv2.IMREAD_COLOR) if data.size else None
    if img is None:
        raise StudioError(f"cannot decode image: {p}")
    if (wrong := not_equirect(img.shape[1], img.shape[0])) is not None:
        raise StudioError(f"{p} is {wrong}")
    if looks_dual_fisheye(img):
        raise StudioError(f"{p} is two fisheye circles side by side, not an equirectangular panorama")
    return np.ascontiguousarray(img)


def _r(x: float) -> float:
    return round(float(x), 2)


def detection_record(image: str, det: ImageDetections) -> dict[str, Any]:
    """The JSON object of one image (see the module docstring)."""
    rec: dict[str, Any] = {
        "image": image,
        "width": det.width,
        "height": det.height,
        "boxes": [
            [*(_r(v) for v in b), round(float(s), 4)] for b, s in zip(det.boxes, det.scores, strict=True)
        ],
    }
    if det.keypoints is not None:
        rec["keypoints"] = [
            [[_r(k[0]), _r(k[1]), round(float(k[2]), 4)] for k in person] for person in det.keypoints
        ]
    return rec


def run(args: argparse.Namespace) -> int:
    paths = [str(p) for p in args.panoramas]
    for p in paths:  # fail before loading the model
        if not Path(p).is_file():
            raise StudioError(f"image not found: {p}")
    out = out_file(args.out, "--out", inputs=paths)
    detector = get_image_detector(args.image_detector)
    lines = []
    show = sys.stderr.isatty() and len(paths) > 1
    bar: Any = None
    if show:
        from tqdm import tqdm

        bar = tqdm(total=len(paths), unit="image", desc="detect-image", file=sys.stderr)
    try:
        for p in paths:
            det = detector.detect(read_panorama(p))
            lines.append(json.dumps(detection_record(p, det), separators=(",", ":")))
            if bar is not None:
                bar.update(1)
    finally:
        if bar is not None:
            bar.close()
    write_out(out, "".join(line + "\n" for line in lines), "--out")
    n = sum(len(json.loads(line)["boxes"]) for line in lines)
    print(f"{len(paths)} image(s), {n} people → {args.out} ({detector.name})")
    return 0
