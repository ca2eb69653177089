"""Cross-checks against the reference implementations: motmetrics (CLEAR MOT, IDF1) and TrackEval (HOTA)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from evalfixtures import random_sequence

from studio.evaluate import ALPHAS, HOTA, ClearMOT, Identity, similarity_matrix
from studio.evaluate.base import frame_arrays

mm = pytest.importorskip("motmetrics")

SEEDS = range(60)
RADII = (0.2, 0.35)

MM_METRICS = [
    "num_frames",
    "num_matches",
    "num_switches",
    "num_false_positives",
    "num_misses",
    "num_fragmentations",
    "num_objects",
    "num_predictions",
    "num_unique_objects",
    "mostly_tracked",
    "partially_tracked",
    "mostly_lost",
    "mota",
    "motp",
    "idf1",
    "idp",
    "idr",
    "idtp",
    "idfp",
    "idfn",
]


def _motmetrics(gts, preds, radius):
    acc = mm.MOTAccumulator(auto_id=True)
    for g, p in zip(gts, preds, strict=True):
        gid, gxy = frame_arrays(g)
        pid, pxy = frame_arrays(p)
        d2 = mm.distances.norm2squared_matrix(gxy, pxy, max_d2=radius**2)
        # Euclidean distances (metres): the assignment then minimises summed distances and MOTP is in metres
        acc.update(gid, pid, np.sqrt(d2))
    mh = mm.metrics.create()
    return mh.compute(acc, metrics=MM_METRICS, name="x").iloc[0]


def _same(a: float, b: float) -> bool:
    if math.isnan(a) or math.isnan(b):
        return math.isnan(a) and math.isnan(b)
    return a == pytest.approx(b, rel=1e-12, abs=1e-15)


@pytest.mark.parametrize("radius", RADII)
@pytest.mark.parametrize("seed", SEEDS)
def test_clear_mot_and_idf1_equal_motmetrics(seed: int, radius: float) -> None:
    gts, preds = random_sequence(seed, radius=radius)
    clear, ident = ClearMOT(radius=radius), Identity(radius=radius)
    for g, p in zip(gts, preds, strict=True):
        clear.update(g, p)
        ident.update(g, p)
    c, i = clear.compute(), ident.compute()
    ref = _motmetrics(gts, preds, radius)
    # counts: exact
    assert c.num_frames == ref["num_frames"]
    assert c.tp == ref["num_matches"] + ref["num_switches"]
    assert c.id_switches == ref["num_switches"]
    assert c.fp == ref["num_false_positives"]
    assert c.fn == ref["num_misses"]
    assert c.fragmentations == ref["num_fragmentations"]
    assert c.num_gt == ref["num_objects"]
    assert c.num_pred == ref["num_predictions"]
    assert c.num_gt_tracks == ref["num_unique_objects"]
    assert (c.num_mt, c.num_pt, c.num_ml) == (
        ref["mostly_tracked"],
        ref["partially_tracked"],
        ref["mostly_lost"],
    )
    assert (i.idtp, i.idfp, i.idfn) == (ref["idtp"], ref["idfp"], ref["idfn"])
    # ratios: the same formulas on the same counts (MOTP sums distances in another order: 1e-12)
    if c.num_gt:
        assert _same(c.mota, ref["mota"])
    assert _same(c.motp, ref["motp"])
    assert _same(i.idf1, ref["idf1"])
    assert _same(i.idp, ref["idp"])
    assert _same(i.idr, ref["idr"])
    # MT / PT / ML are fractions of the ground-truth tracks that sum to exactly 1
    if c.num_gt_tracks:
        assert c.mt + c.pt + c.ml == 1.0
        assert c.mt == ref["mostly_tracked"] / ref["num_unique_objects"]
        assert c.ml == pytest.approx(ref["mostly_lost"] / ref["num_unique_objects"], abs=1e-15)


def test_fixtures_exercise_every_event() -> None:
    """The random fixtures do produce switches, fragmentations, misses, FPs and every MT/PT/ML class."""
    tot = dict.fromkeys(("sw", "frag", "fp", "fn", "mt", "pt", "ml", "none"), 0)
    for seed in SEEDS:
        gts, preds = random_sequence(seed)
        clear = ClearMOT(radius=0.2)
        for g, p in zip(gts, preds, strict=True):
            clear.update(g, p)
        c = clear.compute()
        tot["sw"] += c.id_switches
        tot["frag"] += c.fragmentations
        tot["fp"] += c.fp
        tot["fn"] += c.fn
        tot["mt"] += c.num_mt
        tot["pt"] += c.num_pt
        tot["ml"] += c.num_ml
        tot["none"] += any(p is None for p in preds)
    assert all(v > 0 for v in tot.values()), tot


# ---------------------------------------------------------------- HOTA vs TrackEval


def _trackeval_hota(seqs, radius):
    te = pytest.importorskip("trackeval")
    metric = te.metrics.HOTA()
    per_seq = {}
    for n, (gts, preds) in enumerate(seqs):
        gt_map: dict[int, int] = {}
        pr_map: dict[int, int] = {}
        data: dict = {"gt_ids": [], "tracker_ids": [], "similarity_scores": []}
        for g, p in zip(gts, preds, strict=True):
            gid, gxy = frame_arrays(g)
            pid, pxy = frame_arrays(p)
            data["gt_ids"].append(np.array([gt_map.setdefault(int(i), len(gt_map)) for i in gid], dtype=int))
            data["tracker_ids"].append(
                np.array([pr_map.setdefault(int(i), len(pr_map)) for i in pid], dtype=int)
            )
            data["similarity_scores"].append(similarity_matrix(gxy, pxy, radius=radius))
        data["num_gt_ids"], data["num_tracker_ids"] = len(gt_map), len(pr_map)
        data["num_gt_dets"] = sum(len(x) for x in data["gt_ids"])
        data["num_tracker_dets"] = sum(len(x) for x in data["tracker_ids"])
        data["num_timesteps"] = len(gts)
        per_seq[str(n)] = metric.eval_sequence(data)
    return per_seq["0"] if len(seqs) == 1 else metric.combine_sequences(per_seq)


def _check_hota(mine, ref) -> None:
    for name, field in (("HOTA", "hota"), ("DetA", "deta"), ("AssA", "assa"), ("LocA", "loca")):
        np.testing.assert_allclose(getattr(mine, f"{field}_alpha"), ref[name], rtol=1e-10, atol=1e-12)
        assert getattr(mine, field) == pytest.approx(float(np.mean(ref[name])), rel=1e-10, abs=1e-12)
    for name, field in (("DetRe", "detre"), ("DetPr", "detpr"), ("AssRe", "assre"), ("AssPr", "asspr")):
        assert getattr(mine, field) == pytest.approx(float(np.mean(ref[name])), rel=1e-10, abs=1e-12)


def test_alphas_are_trackeval_thresholds() -> None:
    assert len(ALPHAS) == 19
    assert ALPHAS[0] == pytest.approx(0.05)
    assert ALPHAS[-1] == pytest.approx(0.95)


@pytest.mark.parametrize("seed", range(30))
def test_hota_equals_trackeval(seed: int) -> None:
    radius = 0.3
    gts, preds = random_sequence(seed, radius=radius)
    h = HOTA(radius=radius)
    for g, p in zip(gts, preds, strict=True):
        h.update(g, p)
    _check_hota(h.compute(), _trackeval_hota([(gts, preds)], radius))


def test_hota_several_sequences_equals_trackeval_combined() -> None:
    radius = 0.25
    seqs = [random_sequence(s, radius=radius) for s in (3, 4, 5)]
    h = HOTA(radius=radius)
    for n, (gts, preds) in enumerate(seqs):
        for g, p in zip(gts, preds, strict=True):
            h.update(g, p, sequence=n)
    _check_hota(h.compute(), _trackeval_hota(seqs, radius))
