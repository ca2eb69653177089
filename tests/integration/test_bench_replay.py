"""``bench/replay_tracking.py --handovers``: when an output track goes on with another person."""

from __future__ import annotations

import numpy as np
import pytest
from bench_loader import load_bench

from studio.evaluate import evaluate
from studio.fuse.base import PersonObservations
from studio.geometry.se import Pose2
from studio.labels import LabelFrame, LabelPerson, LabelSet
from studio.pipeline.base import FrameResult
from studio.track.base import Observations
from studio.track.offline import tracks_from_hits


def _frame(i: int, people: dict[int, tuple[float, float]], period_ns: int = 10**8) -> LabelFrame:
    return LabelFrame(
        i, tuple(LabelPerson(pid, x, y) for pid, (x, y) in people.items()), stamp_ns=i * period_ns
    )


def test_handovers_tells_a_hand_off_from_a_neighbour(capsys: pytest.CaptureFixture[str]) -> None:
    # person 1 walks away and is gone from frame 10, when person 2 appears 0.45 m from where 1 was; track 7
    # follows 1, then 2. Persons 3 and 4 walk 0.5 m apart; track 8 follows 3, takes 4 in frame 15, and
    # goes back to 3 in frame 17. Track 9 follows 4 all along (so 4 is matched to it except in 15-16).
    gt, pred = [], []
    for i in range(20):
        g = {3: (5.0 + 0.1 * i, 0.0), 4: (5.0 + 0.1 * i, 0.5)}
        if i < 10:
            g[1] = (0.1 * i, 0.0)
        else:
            g[2] = (0.9 - 0.1 * (i - 10), 0.45)
        gt.append(_frame(i, g))
        p = {7: g[1] if i < 10 else g[2], 8: g[4] if i in (15, 16) else g[3]}
        if i not in (15, 16):
            p[9] = g[4]
        pred.append(_frame(i, p))
    truth = LabelSet.from_frames(gt)
    ev = evaluate(LabelSet.from_frames(pred), truth)
    kinds = load_bench("replay_tracking").handovers(ev, truth)
    assert kinds == {"the first one gone": 1, "0.4-0.6 m": 2}
    out = capsys.readouterr().out
    assert "frame    10 track   7: person 1 -> 2 after 0.1 s; person 1 gone" in out
    assert "frame    15 track   8: person 3 -> 4 after 0.1 s; person 3 still there, 0.50 m away" in out
    assert "frame    17 track   8: person 4 -> 3 after 0.1 s; person 4 still there, 0.50 m away" in out


def test_switches_tells_an_exchange_undone_from_one_for_good(capsys: pytest.CaptureFixture[str]) -> None:
    # persons 3 and 4 walk 0.5 m apart; their tracks 8 and 9 exchange them in frames 15-16 and exchange
    # them back in frame 17. Persons 5 and 6 walk 3 m apart; their tracks 10 and 11 exchange them in
    # frame 12 for good.
    gt, pred = [], []
    for i in range(20):
        g = {3: (5.0 + 0.1 * i, 0.0), 4: (5.0 + 0.1 * i, 0.5), 5: (0.0, 0.1 * i), 6: (3.0, 0.1 * i)}
        gt.append(_frame(i, g))
        back = i in (15, 16)
        later = i >= 12
        pred.append(
            _frame(
                i,
                {
                    8: g[4 if back else 3],
                    9: g[3 if back else 4],
                    10: g[6 if later else 5],
                    11: g[5 if later else 6],
                },
            )
        )
    truth = LabelSet.from_frames(gt)
    ev = evaluate(LabelSet.from_frames(pred), truth)
    kinds, taken, undone, check, first, n_points, n_first = load_bench("replay_tracking").switches(
        pred, ev, truth
    )
    assert kinds == {"encounter": 4, "other": 2}
    assert taken == 6  # each went onto the other's track
    assert undone == 4
    assert (check, first, n_points, n_first) == (0, 0, 0, 0)  # 0.5 m apart, begun with the run: no point
    out = capsys.readouterr().out
    assert (
        "frame    15 person   3 at  6.5 m, nearest other 0.50 m: "
        "track 8 (its last match, frame 14) -> 9 [encounter] (it had person 4, frame 14) undone" in out
    )
    assert (
        "frame    12 person   5 at  1.2 m, nearest other 3.00 m: "
        "track 10 (its last match, frame 11) -> 11 [other] (it had person 6, frame 11)\n" in out
    )


def test_switches_names_the_track_clear_mot_kept_not_the_nearest(capsys: pytest.CaptureFixture[str]) -> None:
    """Person 1 is on track 1; in frames 3-5 track 2 comes nearer to them (0.01 m) while track 1 stays
    within the radius (0.15 m): CLEAR MOT keeps its correspondence (no switch), the per-frame detection
    matching takes track 2. Track 1 ends at frame 6: the switch is from track 1 to track 2."""
    gt, pred = [], []
    for i in range(10):
        gt.append(_frame(i, {1: (2.0, 0.0)}))
        p = {}
        if i < 6:
            p[1] = (2.15 if i >= 3 else 2.0, 0.0)
        if i >= 3:
            p[2] = (2.01, 0.0)
        pred.append(_frame(i, p))
    truth = LabelSet.from_frames(gt)
    ev = evaluate(LabelSet.from_frames(pred), truth)
    assert ev.frames[4].matches[0][1] == 2  # the detection matching
    kinds, taken, *_ = load_bench("replay_tracking").switches(pred, ev, truth)
    assert sum(kinds.values()) == 1
    assert taken == 0  # track 2 had nobody before
    out = capsys.readouterr().out
    assert (
        "frame     6 person   1 at  2.0 m, nearest other  inf m: track 1 (its last match, frame 5) -> 2"
        in (out)
    )


@pytest.mark.parametrize(
    ("period_ns", "kind", "check"), [(10**8, "after a gap", 1), (10**9 // 30, "other", 0)]
)
def test_a_switch_after_a_gap_is_counted_in_seconds_not_frames(
    period_ns: int, kind: str, check: int, capsys: pytest.CaptureFixture[str]
) -> None:
    """Person 1 goes unmatched for 15 frames, then track 2 takes them: 1.5 s at 10 Hz is a gap, 0.5 s at
    30 Hz is not. Track 2 begins 2 s into the run at 10 Hz (a review point, so the switch is one to
    check), 0.67 s into it at 30 Hz (no point)."""
    gt, pred = [], []
    for i in range(30):
        gt.append(_frame(i, {1: (2.0, 0.0)}, period_ns))
        p = {} if 5 <= i < 20 else {1 if i < 5 else 2: (2.0, 0.0)}
        pred.append(_frame(i, p, period_ns))
    truth = LabelSet.from_frames(gt)
    ev = evaluate(LabelSet.from_frames(pred), truth)
    kinds, _, _, to_check, first, n_points, n_first = load_bench("replay_tracking").switches(pred, ev, truth)
    assert kinds == {kind: 1}
    assert to_check == n_points == check
    # track 2 begins where track 1 was last seen: doubt 0.4, a point to check first
    assert first == n_first == check
    assert ("to check" in capsys.readouterr().out) == bool(check)


def test_switches_reads_the_predictions_as_the_evaluator_aligned_them() -> None:
    """Predictions on every other frame only (the evaluator interpolates the frames between): person 1 goes
    from track 1 to track 2 at frame 10, one switch, found where the evaluator found it."""
    gt = [_frame(i, {1: (2.0 + 0.05 * i, 0.0)}) for i in range(20)]
    pred = [_frame(i, {1 if i < 10 else 2: (2.0 + 0.05 * i, 0.0)}) for i in range(0, 20, 2)]
    truth = LabelSet.from_frames(gt)
    ev = evaluate(LabelSet.from_frames(pred), truth)
    assert ev.metrics()["id_switches"] == 1
    kinds, *_ = load_bench("replay_tracking").switches(pred, ev, truth)
    assert sum(kinds.values()) == 1


def _walk(swap: bool) -> tuple[list[Observations], dict[int, list[tuple[int, int]]]]:
    """Two people walking side by side 1 m apart at 1 m/s, observed at 10 Hz; each wears other colours.
    Their tracks as a tracker that kept them apart (``swap`` False) or exchanged them halfway made them."""
    rng = np.random.default_rng(0)
    obs = []
    for i in range(40):
        xy = np.array([[0.1 * i, 0.0], [0.1 * i, 1.0]]) + rng.normal(0.0, 0.03, (2, 2))
        colours = np.array([[50, 40, 20, 50, 40, 20], [50, -30, -30, 50, -30, -30]], np.float32)
        colours += rng.normal(0.0, 2.0, colours.shape).astype(np.float32)
        cov = np.tile(0.03**2 * np.eye(2), (2, 1, 1))
        obs.append(Observations(i * 10**8, xy, cov, ("fused", "fused"), np.ones(2), colours, np.arange(2)))
    tracks = {t: [(i, t if not swap or i < 20 else 1 - t) for i in range(40)] for t in (0, 1)}
    return obs, tracks


def test_an_exchange_halfway_fits_the_trackers_model_worse() -> None:
    bench = load_bench("replay_tracking")
    kept = bench.association_likelihood(*_walk(False), accel_sigma=0.65, init_speed_sigma=1.0)
    swapped = bench.association_likelihood(*_walk(True), accel_sigma=0.65, init_speed_sigma=1.0)
    assert kept[2] == swapped[2] == 80  # every observation is described and has neighbours
    assert swapped[0] > kept[0] + 100  # a 1 m jump sideways at 1 m/s
    assert swapped[1] > kept[1] + 50  # next to the exchange, a track's colours mix both people's


def test_capture_keeps_the_hits_of_the_last_call() -> None:
    bench = load_bench("replay_tracking")
    obs, tracks = _walk(False)

    def tracker(o: list[Observations], *, config: object) -> object:
        return tracks_from_hits(o, {t: [h for h in v if h[0] < len(o)] for t, v in tracks.items()})

    run, seen = bench.capture(tracker)
    run(obs[:10], config=None)
    run(obs, config=None)
    observations, hits, _ = seen["last"]
    assert len(observations) == 40
    assert {t: sorted(h) for t, h in hits.items()} == tracks


def test_jitter_moves_every_observation_by_the_given_noise_and_repeats_per_seed() -> None:
    bench = load_bench("replay_tracking")
    n = 2000
    people = PersonObservations(
        np.zeros((n, 2)),
        np.tile(np.eye(2), (n, 1, 1)),
        np.ones(n),
        ("laser",) * n,
        ("laser-only",) * n,
        np.full((n, 4), np.nan),
        np.full(n, -1),
        np.arange(n),
    )
    fused = [FrameResult(0, 0, Pose2(), people)]
    a = bench.jitter(fused, 0.005, (1, 3))[0].observations.xy
    assert np.std(a) == pytest.approx(0.005, rel=0.05)
    assert np.array_equal(a, bench.jitter(fused, 0.005, (1, 3))[0].observations.xy)
    assert not np.array_equal(a, bench.jitter(fused, 0.005, (2, 3))[0].observations.xy)
    assert np.array_equal(fused[0].observations.xy, np.zeros((n, 2)))  # the input is not changed


def test_summary_totals_each_jitter_seed_and_their_spread() -> None:
    bench = load_bench("replay_tracking")
    Run = bench.Run
    runs = [
        Run(1, 1, 3, 0.9, 0.8, 0.7, 1.5),
        Run(1, 2, 1, 0.8, 0.8, 0.7, 1.5),
        Run(2, 1, 6, 0.9, 0.8, 0.7, 1.5),
        Run(2, 2, 2, 0.8, 0.8, 0.7, 1.5),
    ]
    lines = bench.summary(runs)
    assert lines[0].startswith("jitter seed 1: IDSW 3 1 = 4 (1.33/min); F1 0.8500")
    assert lines[1].startswith("jitter seed 2: IDSW 6 2 = 8 (2.67/min)")
    assert lines[2] == "over 2 jitter seeds: IDSW mean 6.0 sd 2.8 (min 4, max 8)"
    # one jitter seed: the total only; one run: nothing to sum up
    assert bench.summary(runs[:2]) == [
        "all: IDSW 3 1 = 4 (1.33/min); F1 0.8500 MOTA 0.8000 IDF1 0.7000; "
        "targets met by 1/2 (≤ 1 switch/min), 0/2 (F1 ≥ 0.95), 0/2 (MOTA ≥ 0.85)"
    ]
    # each recording on its own: 2 switches in 2 minutes meet the rate, 3 do not; F1 and MOTA at the line do
    edge = [Run(0, 1, 2, 0.95, 0.85, 0.9, 2.0), Run(0, 2, 3, 0.9, 0.9, 0.9, 2.0)]
    assert bench.summary(edge)[0].endswith(
        "targets met by 1/2 (≤ 1 switch/min), 1/2 (F1 ≥ 0.95), 2/2 (MOTA ≥ 0.85)"
    )
    assert bench.summary(runs[:1]) == []


@pytest.mark.parametrize("stage", load_bench("replay_tracking").STAGES)
def test_without_switches_a_tracking_stage_off(stage: str) -> None:
    """``--without STAGE``: each name is an optional stage of the offline tracker, which then runs without it
    (two walkers 1 m apart in other colours: two people, two tracks, whichever stage is off)."""
    from dataclasses import replace

    from studio.pipeline.base import PIPELINE_TRACKING
    from studio.track.offline import track_offline

    assert getattr(PIPELINE_TRACKING, stage) is not None
    config = replace(PIPELINE_TRACKING, **{stage: None})
    obs, _ = _walk(False)
    result = track_offline(obs, config=config)
    assert len(result.track_ids()) == 2
