"""The report of a calibration: a text summary and a PNG (residual arrows on the panorama, error histogram).

``write_report(stem, cv, xyz, uv)`` writes ``<stem>_report.txt`` and ``<stem>_report.png`` atomically.
The PNG is drawn with OpenCV on a canvas shaped like the panorama (scaled down): a 30° grid, every
correspondence as a dot (green inlier, red rejected outlier), an arrow from the observed pixel to the
pixel predicted by the cross-validated pose (inliers magnified, the factor is written on the image),
and below a histogram of the held-out column errors.
"""

from __future__ import annotations

import datetime as _dt
import math
import os
from pathlib import Path

import cv2
import numpy as np
from numpy.typing import ArrayLike, NDArray

from studio.atomic import atomic_write_bytes, atomic_write_text
from studio.calibrate.extrinsics import CrossValidation

__all__ = ["draw_report", "report_text", "write_report"]

_GREEN = (90, 200, 60)
_RED = (60, 60, 230)
_GRID = (70, 70, 70)
_TEXT = (235, 235, 235)


def report_text(
    cv: CrossValidation, xyz: ArrayLike, uv: ArrayLike, *, source: str = "", labels: list[str] | None = None
) -> str:
    """The text report: pose, cross-validated errors, and one line per correspondence.

    Args:
        cv: the cross-validation (its ``fit`` is the calibration).
        xyz: ``(N, 3)`` metres; uv: ``(N, 2)`` px — the correspondences it was computed from.
        source: where the correspondences came from (shown in the header).
        labels: names of the rows (e.g. ``line 7``); default ``row i``.
    """
    p = np.asarray(xyz, dtype=np.float64)
    q = np.asarray(uv, dtype=np.float64)
    fit = cv.fit
    W, H = fit.image_size
    pose = fit.pose.as_dict()
    out = [
        "studio calibrate extrinsics — report",
        f"date: {_dt.datetime.now(_dt.UTC).strftime('%Y-%m-%dT%H:%M:%SZ')}",
        f"correspondences: {source or '(arrays)'}; image {W}×{H} px; {fit.n} points",
        "",
        "camera pose T_base_cam (metres, degrees):",
        "  x {x:+.4f}  y {y:+.4f}  z {z:+.4f}".format(**pose),
        "  roll {:+.3f}  pitch {:+.3f}  yaw {:+.3f}".format(
            *(math.degrees(pose[k]) for k in ("roll", "pitch", "yaw"))
        ),
        f"fit: {fit.n - fit.n_outliers} inliers, {fit.n_outliers} outliers rejected "
        f"(threshold {fit.threshold_px:.2f} px, noise scale σ {fit.sigma_px:.2f} px)",
        "",
        cv.table(),
        "",
        "per correspondence: in-sample residual (du, dv) and held-out (cross-validated) errors, px",
        f"{'row':>10} {'x':>8} {'y':>8} {'z':>6} {'u':>9} {'v':>9} {'du':>8} {'dv':>8} "
        f"{'cv_du':>8} {'cv_dv':>8} {'fold':>4}  status",
    ]
    for i in range(len(p)):
        name = labels[i] if labels is not None else f"row {i + 1}"
        du, dv = fit.residual_px[i]
        out.append(
            f"{name:>10} {p[i, 0]:8.3f} {p[i, 1]:8.3f} {p[i, 2]:6.2f} {q[i, 0]:9.2f} {q[i, 1]:9.2f} "
            f"{du:8.2f} {dv:8.2f} {cv.col_err_px[i]:8.2f} {cv.row_err_px[i]:8.2f} {cv.fold[i] + 1:4d}  "
            f"{'inlier' if fit.inliers[i] else 'OUTLIER'}"
        )
    return "\n".join(out) + "\n"


def _arrow_scale(err: NDArray[np.float64], W: int) -> float:
    """A magnification that makes the typical residual arrow about 1 % of the width long."""
    med = float(np.nanmedian(err)) if np.isfinite(err).any() else 0.0
    if med <= 0:
        return 1.0
    raw = 0.01 * W / med
    steps = [1, 2, 5, 10, 20, 50, 100, 200, 500]
    return float(max([s for s in steps if s <= max(raw, 1)], default=1))


def draw_report(
    cv: CrossValidation, uv: ArrayLike, *, width: int = 1600, background: NDArray[np.uint8] | None = None
) -> NDArray[np.uint8]:
    """The report image (BGR ``uint8``): residual arrows on a panorama-shaped canvas + column histogram.

    Args:
        cv: the cross-validation.
        uv: ``(N, 2)`` observed pixels, px.
        width: image width, px (the panorama part is ``width × width·H/W``).
        background: optional panorama (BGR, any size) drawn dimmed under the arrows.
    """
    fit = cv.fit
    W, H = fit.image_size
    q = np.asarray(uv, dtype=np.float64)
    s = width / W
    ph = max(1, round(H * s))
    hist_h = max(160, width // 6)
    img = np.zeros((ph + hist_h, width, 3), np.uint8)
    if background is not None:
        bg = cv2.resize(background, (width, ph), interpolation=cv2.INTER_AREA)
        img[:ph] = (bg.astype(np.float32) * 0.45).astype(np.uint8)
    else:
        img[:ph] = (28, 28, 28)
    for deg in range(0, 360, 30):
        x = round(deg / 360 * width)
        cv2.line(img, (x, 0), (x, ph - 1), _GRID, 1)
    for deg in range(-60, 90, 30):
        y = round((0.5 - deg / 180) * ph)
        cv2.line(img, (0, y), (width - 1, y), _GRID, 1)
    cv2.line(img, (0, ph // 2), (width - 1, ph // 2), (110, 110, 110), 1)
    err = np.hypot(cv.col_err_px, cv.row_err_px)
    k = _arrow_scale(err[fit.inliers], W)
    fs = max(0.4, width / 2400)
    for i in np.argsort(fit.inliers):  # outliers first, inliers drawn on top
        col = _GREEN if fit.inliers[i] else _RED
        a = (round(q[i, 0] * s), round(q[i, 1] * s))
        if np.isfinite(err[i]):
            mag = k if fit.inliers[i] else 1.0  # outliers at true size: they are large anyway
            d = np.array([cv.col_err_px[i], cv.row_err_px[i]]) * mag * s
            d = np.clip(d, -width / 4, width / 4)
            b = (round(a[0] + d[0]), round(a[1] + d[1]))
            cv2.arrowedLine(img, a, b, col, 1, cv2.LINE_AA, tipLength=0.25)
        cv2.circle(img, a, 3, col, -1, cv2.LINE_AA)
    j = cv.to_json()
    cv2.putText(
        img,
        f"held-out residuals x{k:g} (outliers x1); column mean {j['col_px_mean']:.2f} px, median "
        f"{j['col_px_median']:.2f} px; row mean {j['row_px_mean']:.2f} px; outliers {j['n_outliers']} (red)",
        (8, round(22 * fs / 0.6)),
        cv2.FONT_HERSHEY_SIMPLEX,
        fs,
        _TEXT,
        1,
        cv2.LINE_AA,
    )
    _histogram(img[ph:], cv.col_err_px[fit.inliers], fs)
    return img


def _histogram(panel: NDArray[np.uint8], values: NDArray[np.float64], fs: float) -> None:
    panel[:] = (18, 18, 18)
    h, w = panel.shape[:2]
    v = values[np.isfinite(values)]
    top = 30
    cv2.putText(
        panel,
        "held-out column error of inliers (px)",
        (8, 20),
        cv2.FONT_HERSHEY_SIMPLEX,
        fs,
        _TEXT,
        1,
        cv2.LINE_AA,
    )
    if len(v) == 0:
        return
    lim = max(1.0, float(np.percentile(np.abs(v), 98)) * 1.1)
    counts, edges = np.histogram(np.clip(v, -lim, lim), bins=41, range=(-lim, lim))
    bw = (w - 40) / len(counts)
    peak = max(1, int(counts.max()))
    for c, e in zip(counts, edges[:-1], strict=True):
        x0 = round(20 + (e + lim) / (2 * lim) * (w - 40))
        y0 = round(h - 24 - c / peak * (h - top - 30))
        cv2.rectangle(panel, (x0, y0), (round(x0 + bw) - 1, h - 24), _GREEN, -1)
    for t in (-lim, 0.0, lim):
        x = round(20 + (t + lim) / (2 * lim) * (w - 40))
        cv2.line(panel, (x, h - 24), (x, h - 18), _TEXT, 1)
        cv2.putText(panel, f"{t:+.1f}", (max(0, x - 20), h - 4), cv2.FONT_HERSHEY_SIMPLEX, fs * 0.8, _TEXT, 1)


def write_report(
    stem: str | os.PathLike[str],
    cv: CrossValidation,
    xyz: ArrayLike,
    uv: ArrayLike,
    *,
    source: str = "",
    labels: list[str] | None = None,
    background: NDArray[np.uint8] | None = None,
) -> tuple[Path, Path]:
    """Write ``<stem>_report.txt`` and ``<stem>_report.png`` (atomically); returns their paths."""
    base = Path(stem)
    txt = base.with_name(base.name + "_report.txt")
    png = base.with_name(base.name + "_report.png")
    text = report_text(cv, xyz, uv, source=source, labels=labels)
    ok, buf = cv2.imencode(".png", draw_report(cv, uv, background=background))
    if not ok:  # pragma: no cover - OpenCV always encodes a uint8 BGR image
        raise RuntimeError("PNG encoding failed")
    atomic_write_text(txt, text)
    atomic_write_bytes(png, buf.tobytes())
    return txt, png
