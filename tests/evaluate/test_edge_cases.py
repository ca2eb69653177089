"""Hand-made edge cases of the detection and tracking metrics, as tables."""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
import pytest
from evalfixtures import frame, random_sequence

from studio.evaluate import HOTA, ClearMOT, Evaluation, Identity, assign, evaluate, match_frame
from studio.labels import LabelSet

NAN = math.nan


def _run(gt: Sequence[dict], pred: Sequence[dict | None], radius: float = 0.2) -> Evaluation:
    gts = LabelSet.from_frames([frame(k, g) for k, g in enumerate(gt)])
    preds = LabelSet.from_frames([frame(k, p) for k, p in enumerate(pred) if p is not None])
    return evaluate(preds, gts, radius=radius)


def _eq(a: float, b: float) -> bool:
    return (math.isnan(a) and math.isnan(b)) or a == pytest.approx(b, abs=1e-12)


A0, B0 = (0.0, 0.0), (2.0, 0.0)
CASES: dict[str, tuple[Sequence[dict], Sequence[dict | None], dict[str, float]]] = {
    # name: (gt frames, pred frames, expected {metric: value})
    "perfect": (
        [{1: A0, 2: B0}] * 3,
        [{7: A0, 8: B0}] * 3,
        {
            "tp": 6,
            "fp": 0,
            "fn": 0,
            "f1": 1.0,
            "mota": 1.0,
            "motp": 0.0,
            "idf1": 1.0,
            "hota": 1.0,
            "id_switches": 0,
            "mt": 1.0,
            "pt": 0.0,
            "ml": 0.0,
        },
    ),
    "all misses": (
        [{1: A0, 2: B0}] * 4,
        [{}] * 4,
        {
            "tp": 0,
            "fp": 0,
            "fn": 8,
            "precision": NAN,
            "recall": 0.0,
            "f1": 0.0,
            "mota": 0.0,
            "motp": NAN,
            "idf1": 0.0,
            "hota": 0.0,
            "mt": 0.0,
            "pt": 0.0,
            "ml": 1.0,
        },
    ),
    "all false positives": (
        [{1: A0}] * 4,
        [{5: (1.0, 1.0), 6: (3.0, 3.0)}] * 4,
        {
            "tp": 0,
            "fp": 8,
            "fn": 4,
            "precision": 0.0,
            "recall": 0.0,
            "f1": 0.0,
            "mota": 1.0 - 12 / 4,
            "idf1": 0.0,
            "hota": 0.0,
            "ml": 1.0,
        },
    ),
    "empty ground-truth frames": (
        [{}, {}, {1: A0}],
        [{5: A0}, {}, {5: A0}],
        {
            "tp": 1,
            "fp": 1,
            "fn": 0,
            "precision": 0.5,
            "recall": 1.0,
            "mota": 0.0,
            "num_frames": 3,
            "idf1": 2 * 1 / (1 + 2),
        },
    ),
    "no ground truth at all": (
        [{}, {}],
        [{5: A0}, {}],
        {
            "tp": 0,
            "fp": 1,
            "fn": 0,
            "precision": 0.0,
            "recall": NAN,
            "f1": 0.0,
            "mota": NAN,
            "idf1": 0.0,
            "mt": NAN,
            "pt": NAN,
            "ml": NAN,
            "num_gt_tracks": 0,
        },
    ),
    "everything empty": (
        [{}, {}],
        [{}, {}],
        {"tp": 0, "fp": 0, "fn": 0, "precision": NAN, "recall": NAN, "f1": NAN, "mota": NAN, "idf1": NAN},
    ),
    "id swap": (
        # two people; the tracker swaps their ids from frame 2 on
        [{1: A0, 2: B0}] * 4,
        [{7: A0, 8: B0}] * 2 + [{8: A0, 7: B0}] * 2,
        {"tp": 8, "fp": 0, "fn": 0, "mota": 1.0 - 2 / 8, "id_switches": 2, "idf1": 0.5, "mt": 1.0},
    ),
    "fragmented track": (
        # tracked, tracked, lost, lost, tracked, lost (trailing misses are not a fragmentation)
        [{1: A0}] * 6,
        [{7: A0}, {7: A0}, {}, {}, {7: A0}, {}],
        {"tp": 3, "fn": 3, "frag": 1, "id_switches": 0, "mt": 0.0, "pt": 1.0, "ml": 0.0},
    ),
    "fragmented and re-identified under a new id": (
        [{1: A0}] * 4,
        [{7: A0}, {}, {9: A0}, {9: A0}],
        {"tp": 3, "fn": 1, "frag": 1, "id_switches": 1, "idf1": 2 * 2 / (4 + 3)},
    ),
    "one prediction between two people": (
        # equidistant: one match, one miss
        [{1: (0.0, 0.0), 2: (0.3, 0.0)}],
        [{7: (0.15, 0.0)}],
        {"tp": 1, "fp": 0, "fn": 1},
    ),
    "most pairs beat nearest neighbours": (
        # nearest-neighbour (the thesis) would give p→b twice; one-to-one with most pairs gives 2 TP
        [{1: (0.0, 0.0), 2: (0.35, 0.0)}],
        [{7: (0.18, 0.0), 8: (0.5, 0.0)}],
        {"tp": 2, "fp": 0, "fn": 0},
    ),
    "MT / PT / ML boundaries at 80 % and 20 %": (
        # track 1 tracked 4/5 = 80 % → MT; track 2 1/5 = 20 % → PT; track 3 0/5 → ML
        [{1: A0, 2: B0, 3: (5.0, 5.0)}] * 5,
        [{7: A0, 8: B0}] + [{7: A0}] * 3 + [{}],
        {"mt": 1 / 3, "pt": 1 / 3, "ml": 1 - 2 / 3, "tp": 5, "fn": 10},
    ),
}


@pytest.mark.parametrize("name", CASES)
def test_edge_case_table(name: str) -> None:
    gt, pred, expected = CASES[name]
    m = _run(gt, pred).to_json()
    for key, want in expected.items():
        got = m[key]
        got = NAN if got is None else got
        assert _eq(got, want), f"{name}: {key} = {got}, expected {want}"


RADIUS_CASES = [
    # (offset in metres, radius, matches?) — a distance equal to the radius matches
    (0.25, 0.25, True),
    (0.5, 0.5, True),
    (0.25 + 1e-9, 0.25, False),
    (0.25 - 1e-9, 0.25, True),
    (0.0, 0.2, True),
]


@pytest.mark.parametrize(("offset", "radius", "matches"), RADIUS_CASES)
def test_distance_exactly_at_radius_matches(offset: float, radius: float, matches: bool) -> None:
    fm = match_frame(np.array([[1.0, 2.0]]), np.array([[1.0 + offset, 2.0]]), radius=radius)
    assert fm.tp == int(matches)
    ev = _run([{1: (1.0, 2.0)}], [{5: (1.0 + offset, 2.0)}], radius=radius)
    assert ev.detection.tp == ev.clear.tp == int(matches)
    # HOTA similarity is 1 − d / radius: a pair at the radius has similarity 0, never a HOTA match
    if offset >= radius:
        assert ev.hota.deta == 0.0


def test_tie_between_two_predictions() -> None:
    fm = match_frame(np.array([[0.0, 0.0]]), np.array([[0.1, 0.0], [-0.1, 0.0]]), radius=0.2)
    assert (fm.tp, fm.fp, fm.fn) == (1, 1, 0)


def test_assign_prefers_more_pairs_then_less_distance() -> None:
    nan = np.nan
    cost = np.array([[0.18, 0.17], [nan, 0.15]]).T  # rows: preds p, q ; cols: gt a, b
    rows, cols = assign(cost)
    assert sorted(zip(rows.tolist(), cols.tolist(), strict=True)) == [(0, 0), (1, 1)]
    rows, cols = assign(np.full((2, 3), nan))
    assert len(rows) == len(cols) == 0
    rows, cols = assign(np.array([[1.0, 2.0], [2.0, 1.0]]))
    assert rows.tolist() == [0, 1]
    assert cols.tolist() == [0, 1]


def test_clear_mot_keeps_previous_correspondence() -> None:
    """An earlier match that is still within the radius is kept even if another pairing is closer."""
    clear = ClearMOT(radius=0.5)
    clear.update(frame(0, {1: (0.0, 0.0)}), frame(0, {7: (0.0, 0.0)}))
    # now hypothesis 8 is closer to object 1, but 7 is still within the radius: no switch, 8 is an FP
    f = clear.update(frame(1, {1: (0.0, 0.0)}), frame(1, {7: (0.4, 0.0), 8: (0.01, 0.0)}))
    assert f.matches == ((1, 7, 0.4),)
    assert f.fp_ids == (8,)
    assert f.switches == ()
    r = clear.compute()
    assert (r.tp, r.fp, r.id_switches) == (2, 1, 0)
    assert r.motp == pytest.approx(0.2)


def test_identity_switch_after_absence_still_counts() -> None:
    """motmetrics semantics: an object that comes back with another hypothesis is a switch."""
    clear = ClearMOT(radius=0.2)
    clear.update(frame(0, {1: A0}), frame(0, {7: A0}))
    clear.update(frame(1, {}), frame(1, {}))
    f = clear.update(frame(2, {1: A0}), frame(2, {9: A0}))
    assert f.switches == (1,)


def test_hand_checked_hota() -> None:
    """Values worked out by hand (they do not need TrackEval)."""
    r = 0.2
    # a perfect tracker: every similarity is 1
    h = HOTA(radius=r)
    for k in range(3):
        h.update(frame(k, {1: A0, 2: B0}), frame(k, {5: A0, 6: B0}))
    res = h.compute()
    assert (res.hota, res.deta, res.assa, res.loca) == (1.0, 1.0, 1.0, 1.0)
    # one person, constant offset d = r / 2 → S = 0.5: a TP for the 10 thresholds α ≤ 0.5 only;
    # there DetA = AssA = 1, LocA = 0.5; elsewhere DetA = AssA = 0 and LocA = 1 (TrackEval convention)
    h = HOTA(radius=r)
    for k in range(4):
        h.update(frame(k, {1: A0}), frame(k, {5: (r / 2, 0.0)}))
    res = h.compute()
    assert res.hota == pytest.approx(10 / 19)
    assert res.deta == pytest.approx(10 / 19)
    assert res.assa == pytest.approx(10 / 19)
    assert res.loca == pytest.approx((10 * 0.5 + 9 * 1.0) / 19)
    # identity split in two halves: 4 frames id 5 then 4 frames id 6, exact positions
    # DetA = 1; each TP's pair has TPA = 4, FNA = 4, FPA = 0 → A = 0.5 → HOTA = √0.5
    h = HOTA(radius=r)
    for k in range(8):
        h.update(frame(k, {1: A0}), frame(k, {5 if k < 4 else 6: A0}))
    res = h.compute()
    assert res.deta == 1.0
    assert res.assa == pytest.approx(0.5)
    assert res.hota == pytest.approx(math.sqrt(0.5))


def test_hand_checked_idf1() -> None:
    ident = Identity(radius=0.2)
    # GT 1 for 6 frames; prediction id 5 for frames 0-3, id 6 for frames 4-5, plus clutter id 9 in frame 0
    for k in range(6):
        pred = {5 if k < 4 else 6: A0}
        if k == 0:
            pred[9] = (3.0, 3.0)
        ident.update(frame(k, {1: A0}), frame(k, pred))
    r = ident.compute()
    assert (r.idtp, r.idfp, r.idfn) == (4, 3, 2)
    assert r.idf1 == pytest.approx(2 * 4 / (6 + 7))
    assert r.pairs == ((1, 5),)


@pytest.mark.parametrize("seed", range(40))
def test_mt_pt_ml_sum_to_one(seed: int) -> None:
    gts, preds = random_sequence(seed)
    clear = ClearMOT(radius=0.2)
    for g, p in zip(gts, preds, strict=True):
        clear.update(g, p)
    r = clear.compute()
    if r.num_gt_tracks:
        assert r.mt + r.pt + r.ml == 1.0
        assert r.num_mt + r.num_pt + r.num_ml == r.num_gt_tracks
        assert min(r.mt, r.pt, r.ml) >= 0.0
    else:
        assert math.isnan(r.mt)
        assert math.isnan(r.pt)
        assert math.isnan(r.ml)


def test_metric_reset() -> None:
    for cls in (ClearMOT, Identity, HOTA):
        m = cls(radius=0.2)
        m.update(frame(0, {1: A0}), frame(0, {5: (5.0, 5.0)}))
        first = m.compute()
        m.reset()
        m.update(frame(0, {1: A0}), frame(0, {5: (5.0, 5.0)}))
        assert str(m.compute()) == str(first)


def test_results_print_well() -> None:
    ev = _run([{1: A0}], [{5: A0}])
    text = str(ev.clear)
    assert text.startswith("ClearMOTResult")
    assert "mota" in text
    assert "1.0000" in text
    assert "MOTA" in str(ev)
    assert "IDF1" in str(ev)
    assert "HOTA" in str(ev)


def test_bad_radius() -> None:
    with pytest.raises(ValueError, match="radius"):
        ClearMOT(radius=0.0)
    with pytest.raises(ValueError, match="radius"):
        evaluate(LabelSet.from_frames([]), LabelSet.from_frames([]), radius=-1.0)


def test_metrics_follow_the_protocol() -> None:
    from studio.evaluate import Detection, Metric

    metrics: list[Metric[object]] = [Detection(), ClearMOT(), Identity(), HOTA()]
    for m in metrics:
        m.update(frame(0, {1: A0}), None)
        assert m.compute() is not None
