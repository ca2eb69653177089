"""Fit the classical laser detector's leg model on the real labelled scans and cross-validate it.

    .venv/bin/python bench/laser_sweep.py            # leave-one-bag-out numbers + the fitted LegModel literal
    .venv/bin/python bench/laser_sweep.py --thin 2 3 # the model for coarse scanners (0.5–1.1° beams)

Positives: segments within 0.15 m of a labelled leg in ``legs_labelled/*`` (automatically extracted labels
inside a ±15° / 5 m wedge). Negatives: every segment of ``negative_2.bag`` (empty rooms, 3 scanners) and the
segments of the labelled bags outside an 18° / 5.4 m wedge (people walk only inside the 15° / 5 m wedge).
Segments inside the wedge without a label are left out. The printed ``LegModel(...)`` goes into
``studio/detect/laser/classical.py`` as ``LEG_MODEL``.

These scans have 0.35° beams. A copy with every K-th beam (:func:`thinned`) is what a scanner with K times
coarser beams sees of the same scene: legs with the returns of legs K times farther away. The held-out
numbers are also given on copies thinned by 2 and 3 (0.70° and 1.05°: how the model does on a coarser
scanner, or on legs 2–3 times farther than the labelled ones). ``--thin 2 3`` fits on those copies alone:
``LEG_MODEL_COARSE``, which the detector uses for scans with beams 0.38° apart or more. ``--far`` adds thinned
copies to the recorded scans instead (one model for all; tried, not kept: docs/results.md, session 31).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np
from scipy.optimize import minimize

sys.path.insert(0, str(Path(__file__).resolve().parent))
from laser_data import DATA, Scan, labelled_scans, read_scans

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


def thinned(scan: Scan, k: int, phase: int) -> Scan:
    """Every ``k``-th beam of ``scan`` from ``phase``: the scene as a scanner with ``k`` times coarser beams
    sees it, so a leg ``r`` metres away gets the returns of a leg ``k r`` metres away (the labelled people
    walk within 5 m; the thinned copies teach the model legs out to 10–15 m)."""
    return Scan(
        scan.topic, scan.stamp_ns, scan.points[phase::k], scan.valid[phase::k], scan.angle_increment * k
    )


def copies_of(
    scan: Scan, noise: float, far: tuple[int, ...], rng: np.random.Generator
) -> list[tuple[Scan, str]]:
    """The scan as recorded, plus the augmented copies ``noise`` (extra range noise, metres) and ``far``
    (beam thinning factors) ask for, each with its group suffix."""
    out = [(scan, "")]
    if noise > 0:
        out.append(
            (
                Scan(
                    scan.topic,
                    scan.stamp_ns,
                    noisy(scan.points, noise, rng),
                    scan.valid,
                    scan.angle_increment,
                ),
                "+noise",
            )
        )
    out += [(thinned(scan, k, int(rng.integers(k))), f"+far{k}") for k in far]
    return out


def collect(
    params: SegmentParams, *, noise: float = 0.0, far: tuple[int, ...] = ()
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Features ``(S, F)``, labels ``(S,)`` (1 leg, 0 not, −1 unknown) and group names of all segments.

    ``noise`` > 0 adds a copy of every scan with that much extra Gaussian range noise (metres), so the model
    also learns legs and clutter from scanners noisier than the one that recorded these bags; ``far`` adds a
    copy thinned by each factor (:func:`thinned`), legs and clutter as seen from farther away. Their groups
    carry a ``+noise`` / ``+farK`` suffix.
    """
    feats, ys, groups = [], [], []
    rng = np.random.default_rng(0)
    for bag in sorted((DATA / "legs_labelled").glob("*.bag")):
        for scan0, legs in labelled_scans(bag):
            for scan, tag in copies_of(scan0, noise, far, rng):
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
        for scan, tag in copies_of(scan0, noise, far, rng):
            segs = segment_scan(scan.points, scan.valid, params=params)
            if segs:
                feats.append(segment_features(scan.points, segs, scan.valid))
                ys.append(np.zeros(len(segs), dtype=int))
                groups += ["negative_2" + scan.topic + tag] * len(segs)
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


def literal(model: LegModel, name: str = "LEG_MODEL") -> str:
    """The model as the Python source committed in classical.py, bound to ``name``."""

    def block(name: str, values: tuple[float, ...]) -> str:
        rows = [", ".join(repr(v) for v in values[i : i + 9]) for i in range(0, len(values), 9)]
        return f"    {name}=(\n" + "".join(f"        {r},\n" for r in rows) + "    ),\n"

    return (
        f"# fmt: off\n{name} = LegModel(\n"
        + block("mean", model.mean)
        + block("std", model.std)
        + block("coef", model.coef)
        + f"    bias={model.bias!r},\n)\n# fmt: on"
    )


REPORT_FAR = (2, 3)  # thinned copies the held-out numbers are also given on, trained on or not


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--l2", type=float, default=1e-3)
    ap.add_argument("--jump-min", type=float, default=SegmentParams.jump_min)
    ap.add_argument("--jump-beams", type=float, default=SegmentParams.jump_beams)
    ap.add_argument("--min-points", type=int, default=SegmentParams.min_points)
    ap.add_argument("--noise", type=float, default=0.0, help="noise augmentation: extra range noise, m")
    ap.add_argument(
        "--far", type=int, nargs="*", default=[], help="range augmentation: train on copies thinned by these"
    )
    ap.add_argument(
        "--thin",
        type=int,
        nargs="*",
        default=[],
        help="fit for scanners with K times coarser beams: train on those copies only",
    )
    args = ap.parse_args()
    if any(k < 2 for k in [*args.far, *args.thin]) or args.min_points < 2:
        ap.error("--far / --thin factors and --min-points must be >= 2")
    params = SegmentParams(jump_min=args.jump_min, jump_beams=args.jump_beams, min_points=args.min_points)
    far = tuple(sorted(set(REPORT_FAR) | set(args.far) | set(args.thin)))
    feats, y, g = collect(params, noise=args.noise, far=far)
    keep = y >= 0
    feats, y, g = feats[keep], y[keep], g[keep].astype(str)
    split = np.char.partition(g, "+")
    base, kind = split[:, 0], np.char.add(split[:, 1], split[:, 2])
    train = np.isin(kind, ["", "+noise"] + [f"+far{k}" for k in args.far])
    if args.thin:
        train = np.isin(kind, [f"+far{k}" for k in args.thin])
    labelled = sorted({x for x in base if x.startswith("positive")})
    negs = sorted({x for x in base if x.startswith("negative")})
    prob = np.zeros(len(y))
    for i, name in enumerate(labelled):  # leave one labelled bag (and one negative scanner) out
        out = (base == name) | (base == negs[i % len(negs)])  # every copy of the held-out bags
        prob[out] = fit(feats[~out & train], y[~out & train], l2=args.l2)(feats[out])
    n_neg_scans = 435 + 435 + 434  # negative_2: left, rear, right scans
    neg = np.char.startswith(base, "negative")
    print("held-out segment-level (leave-one-bag-out); farK: every K-th beam, legs as if K times farther")
    print(
        f"{'thr':>5} "
        + " ".join(f"{c or 'recorded':>9} recall  neg/scan" for c in ["", *map("+far{}".format, far)])
    )
    for t in (0.3, 0.4, 0.5, 0.6, 0.7, 0.8, 0.9):
        row = []
        for c in ["", *(f"+far{k}" for k in far)]:
            m = kind == c
            rec = ((prob >= t) & (y == 1) & m).sum() / ((y == 1) & m).sum()
            row.append(f"{rec:16.3f} {((prob >= t) & neg & m).sum() / n_neg_scans:9.2f}")
        print(f"{t:5.2f} " + " ".join(row))
    model = fit(feats[train], y[train], l2=args.l2)
    print("\n" + literal(model, "LEG_MODEL_COARSE" if args.thin else "LEG_MODEL"))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
