"""Fit the classical laser detector's leg model on the real labelled scans and cross-validate it.

    .venv/bin/python bench/laser_sweep.py            # leave-one-bag-out numbers + the fitted LegModel literal

Positives: segments within 0.15 m of a labelled leg in ``legs_labelled/*`` (automatically extracted labels
inside a ±15° / 5 m wedge). Negatives: every segment of ``negative_2.bag`` (empty rooms, 3 scanners) and the
segments of the labelled bags outside an 18° / 5.4 m wedge (people walk only inside the 15° / 5 m wedge).
Segments inside the wedge without a label are left out. The printed ``LegModel(...)`` goes into
``studio/detect/laser/classical.py`` as ``LEG_MODEL``.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np
from scipy.optimize import minimize

sys.path.insert(0, str(Path(__file__).resolve().parent))
from laser_data import DATA, labelled_scans, read_scans

from studio.detect.laser.classical import LegModel, leg_basis
from studio.detect.laser.segment import SegmentParams, segment_features, segment_scan

MATCH_RADIUS = 0.15


def in_wedge(xy: np.ndarray, *, deg: float, rmax: float) -> np.ndarray:
    """Points inside ``|bearing| <= deg`` and ``range <= rmax`` of the laser."""
    ang = np.degrees(np.arctan2(xy[:, 1], xy[:, 0]))
    return (np.abs(ang) <= deg) & (np.hypot(xy[:, 0], xy[:, 1]) <= rmax)


def noisy(points: np.ndarray, sigma: float, rng: np.random.Generator) -> np.ndarray:
    """``points`` (laser frame) with Gaussian range noise of ``sigma`` metres added along each beam."""
    r = np.hypot(points[:, 0], points[:, 1])
    with np.errstate(invalid="ignore", divide="ignore"):
        return points * ((r + rng.normal(0.0, sigma, len(r))) / r)[:, None]


def collect(params: SegmentParams, *, noise: float = 0.0) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Features ``(S, F)``, labels ``(S,)`` (1 leg, 0 not, −1 unknown) and group names of all segments.

    ``noise`` > 0 adds a second copy of every scan with that much extra Gaussian range noise (metres), so the
    model also learns legs and clutter from scanners noisier than the one that recorded these bags; its
    groups carry a ``+noise`` suffix.
    """
    feats, ys, groups = [], [], []
    rng = np.random.default_rng(0)
    copies = [(0.0, "")] + ([(noise, "+noise")] if noise > 0 else [])
    for bag in sorted((DATA / "legs_labelled").glob("*.bag")):
        for (scan0, legs), (sig, tag) in ((x, c) for x in labelled_scans(bag) for c in copies):
            scan = scan0 if sig == 0 else type(scan0)(
                scan0.topic, scan0.stamp_ns, noisy(scan0.points, sig, rng), scan0.valid, scan0.angle_increment
            )  # fmt: skip
            segs = segment_scan(scan.points, scan.valid, params=params)
            if not segs:
                continue
            f = segment_features(scan.points, segs, scan.valid)
            c = np.array([scan.points[s].mean(0) for s in segs])
            d = np.full(len(segs), np.inf)
            if len(legs):
                d = np.hypot(*(c[:, None, :] - legs[None, :, :]).transpose(2, 0, 1)).min(1)
            y = np.where(d < MATCH_RADIUS, 1, np.where(in_wedge(c, deg=18.0, rmax=5.4), -1, 0))
            feats.append(f)
            ys.append(y)
            groups += [bag.name.split("_extracted")[0] + tag] * len(segs)
    for scan0 in read_scans(DATA / "negative_2.bag"):
        for sig, tag in copies:
            pts = scan0.points if sig == 0 else noisy(scan0.points, sig, rng)
            segs = segment_scan(pts, scan0.valid, params=params)
            if segs:
                feats.append(segment_features(pts, segs, scan0.valid))
                ys.append(np.zeros(len(segs), dtype=int))
                groups += ["negative_2" + scan0.topic + tag] * len(segs)
    return np.concatenate(feats), np.concatenate(ys), np.array(groups)


def fit(features: np.ndarray, y: np.ndarray, *, l2: float = 1e-3) -> LegModel:
    """Class-balanced L2-regularised logistic regression on the standardised hinge basis."""
    x = leg_basis(features)
    mu, sd = x.mean(0), x.std(0) + 1e-9
    z = np.column_stack([(x - mu) / sd, np.ones(len(x))])
    w = np.where(y == 1, 0.5 / y.mean(), 0.5 / (1.0 - y.mean()))

    def loss(b: np.ndarray) -> tuple[float, np.ndarray]:
        t = z @ b
        p = 1.0 / (1.0 + np.exp(-t))
        reg = np.r_[b[:-1], 0.0]
        val = float(np.mean(w * (np.logaddexp(0.0, t) - y * t)) + 0.5 * l2 * reg @ reg)
        return val, z.T @ (w * (p - y)) / len(y) + l2 * reg

    b = minimize(loss, np.zeros(z.shape[1]), jac=True, method="L-BFGS-B").x
    r = lambda a: tuple(round(float(v), 6) for v in a)  # noqa: E731
    return LegModel(mean=r(mu), std=r(sd), coef=r(b[:-1]), bias=round(float(b[-1]), 6))


def literal(model: LegModel) -> str:
    """The model as the Python source committed in classical.py."""

    def block(name: str, values: tuple[float, ...]) -> str:
        rows = [", ".join(repr(v) for v in values[i : i + 9]) for i in range(0, len(values), 9)]
        return f"    {name}=(\n" + "".join(f"        {r},\n" for r in rows) + "    ),\n"

    return (
        "# fmt: off\nLEG_MODEL = LegModel(\n"
        + block("mean", model.mean)
        + block("std", model.std)
        + block("coef", model.coef)
        + f"    bias={model.bias!r},\n)\n# fmt: on"
    )


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--l2", type=float, default=1e-3)
    ap.add_argument("--jump-min", type=float, default=SegmentParams.jump_min)
    ap.add_argument("--jump-beams", type=float, default=SegmentParams.jump_beams)
    ap.add_argument("--noise", type=float, default=0.0, help="noise augmentation: extra range noise, m")
    args = ap.parse_args()
    params = SegmentParams(jump_min=args.jump_min, jump_beams=args.jump_beams)
    feats, y, g = collect(params, noise=args.noise)
    keep = y >= 0
    feats, y, g = feats[keep], y[keep], g[keep]
    g = g.astype(str)
    base = np.char.replace(g, "+noise", "")
    clean = ~np.char.endswith(g, "+noise")
    labelled = sorted({x for x in base if x.startswith("positive")})
    negs = sorted({x for x in base if x.startswith("negative")})
    prob = np.zeros(len(y))
    for i, name in enumerate(labelled):  # leave one labelled bag (and one negative scanner) out
        out = (base == name) | (base == negs[i % len(negs)])  # both copies of the held-out bags
        prob[out] = fit(feats[~out], y[~out], l2=args.l2)(feats[out])
    # held-out numbers on the recorded scans only (the noisy copies are training data)
    p_c, y_c = prob[clean], y[clean]
    n_neg_scans = {"negative_2/left_scan": 435, "negative_2/rear_scan": 435, "negative_2/right_scan": 434}
    neg = np.char.startswith(g[clean], "negative")
    print("held-out segment-level (leave-one-bag-out):")
    print(f"{'thr':>5} {'leg recall':>10} {'neg seg/scan':>12}")
    for t in (0.3, 0.4, 0.5, 0.6, 0.7, 0.8, 0.9):
        rec = ((p_c >= t) & (y_c == 1)).sum() / (y_c == 1).sum()
        fpps = ((p_c >= t) & neg).sum() / sum(n_neg_scans.values())
        print(f"{t:5.2f} {rec:10.3f} {fpps:12.2f}")
    model = fit(feats, y, l2=args.l2)
    print("\n" + literal(model))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
