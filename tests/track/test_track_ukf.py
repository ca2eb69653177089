"""The online UKF + GNN tracker: life-cycle tables, association through crossings, per-observation noise."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from studio.track import (
    Observations,
    Tracker,
    TrackingError,
    UkfTracker,
    UkfTrackerConfig,
    track_sequence,
)

T0 = 1_700_000_000_000_000_000
S = 1_000_000_000  # ns per second


def obs(t_s: float, *xy: tuple[float, float], sigma: float = 0.05) -> Observations:
    return Observations.create(T0 + round(t_s * S), np.array(xy, float).reshape(-1, 2), sigma_m=sigma)


def states(tracker: UkfTracker) -> dict[int, str]:
    return {e.track_id: e.state for e in tracker.tracks}


def test_is_a_tracker():
    assert isinstance(UkfTracker(), Tracker)


def test_config_is_checked():
    with pytest.raises(ValueError, match="confirm_hits"):
        UkfTrackerConfig(confirm_hits=0)
    with pytest.raises(ValueError, match="confirm_window_s"):
        UkfTrackerConfig(confirm_window_s=float("nan"))
    with pytest.raises(ValueError, match="probability"):
        UkfTrackerConfig(gate_prob=1.5)
    with pytest.raises(ValueError, match="confirm_min_span_s"):
        UkfTrackerConfig(confirm_min_span_s=0.5, confirm_window_s=0.45)
    with pytest.raises(ValueError, match="confirm_min_span_s"):
        UkfTrackerConfig(confirm_min_span_s=-0.1)


@pytest.mark.parametrize(("hz", "confirmed_at"), [(10, 2), (40, 8), (7.5, 2)])
def test_confirming_hits_must_span_the_minimum_time(hz: float, confirmed_at: int) -> None:
    """Three hits of a 40 Hz scanner come within 50 ms: with a 0.18 s span the track is confirmed by its
    9th hit (0.2 s after the first) instead of its 3rd; at 10 Hz and slower the 3rd hit spans it already."""
    cfg = UkfTrackerConfig(confirm_hits=3, confirm_window_s=0.45, confirm_min_span_s=0.18)
    tr = UkfTracker(config=cfg)
    got = []
    for k in range(confirmed_at + 2):
        tr.step(obs(k / hz, (0.01 * k, 0.0)))
        got.append(states(tr)[0])
    assert got.index("confirmed") == confirmed_at
    assert set(got[confirmed_at:]) == {"confirmed"}


def test_single_clutter_hit_dies_tentative():
    tr = UkfTracker(config=UkfTrackerConfig(confirm_hits=3, confirm_window_s=0.45))
    assert tr.step(obs(0.0, (1.0, 1.0))) == []  # tentative tracks are not reported
    assert states(tr) == {0: "tentative"}
    for k in (1, 2):
        assert tr.step(obs(0.1 * k)) == []
        assert states(tr) == {0: "tentative"}
    tr.step(obs(0.3))
    tr.step(obs(0.4))
    assert states(tr) == {0: "tentative"}
    tr.step(obs(0.5))  # the first frame after the 0.45 s window, without 3 hits
    assert states(tr) == {}


# (hits per frame at 10 Hz, M, window s, state after each frame ("-" deleted))
T, D = "tentative", "-"
LIFE = [
    ("confirmed after M hits", [1, 1, 1], 3, 0.45, [T, T, "confirmed"]),
    ("M in the window with a miss", [1, 0, 1, 1], 3, 0.45, [T, T, T, "confirmed"]),
    ("M-th hit on the window's last frame", [1, 0, 0, 1, 1], 3, 0.45, [T, T, T, T, "confirmed"]),
    ("too few hits in the window", [1, 0, 1, 0, 0, 0], 3, 0.45, [T, T, T, T, T, D]),
    ("a hit right after the window does not save it", [1, 0, 1, 0, 0, 1], 3, 0.45, [T] * 5 + [D]),
    ("confirmed at once (M=1)", [1, 0], 1, 0.0, ["confirmed", "lost"]),
    # an image detector every third frame: confirmed only with a window that spans 3 of its frames
    ("every third frame, 0.45 s", [1, 0, 0, 1, 0, 0, 1], 3, 0.45, [T] * 5 + [D, D]),
    ("every third frame, 0.65 s", [1, 0, 0, 1, 0, 0, 1], 3, 0.65, [T] * 6 + ["confirmed"]),
]


@pytest.mark.parametrize(("name", "hits", "M", "window", "expected"), LIFE, ids=[c[0] for c in LIFE])
def test_life_cycle_table(name, hits, M, window, expected):
    cfg = UkfTrackerConfig(confirm_hits=M, confirm_window_s=window, tentative_max_coast_s=10.0)
    tr = UkfTracker(config=cfg)
    got = []
    for k, h in enumerate(hits):
        tr.step(obs(0.1 * k, (0.5 * 0.1 * k, 0.0)) if h else obs(0.1 * k))
        got.append(states(tr).get(0, "-"))
    assert got == expected


def test_coasting_and_deletion_in_seconds_with_irregular_dt():
    tr = UkfTracker(config=UkfTrackerConfig(max_coast_s=1.0))
    for k in range(5):
        tr.step(obs(0.1 * k, (0.1 * k, 0.0)))  # walking at 1 m/s along x
    assert states(tr) == {0: "confirmed"}
    last = 0.4
    # irregular frames without the person: lost until more than 1.0 s unseen
    for dt, expected in [(0.03, "lost"), (0.5, "lost"), (0.42, "lost"), (0.05, "lost"), (0.01, "-")]:
        last += dt
        est = tr.step(obs(last))
        assert states(tr).get(0, "-") == expected, (last, expected)
        if expected == "lost":
            (e,) = est
            assert e.det_index == -1
            assert e.xy[0] == pytest.approx(last, abs=0.1)  # coasts at its velocity


def test_one_long_step_deletes_and_a_returning_lost_track_keeps_its_id():
    tr = UkfTracker(config=UkfTrackerConfig(max_coast_s=1.0))
    for k in range(4):
        tr.step(obs(0.1 * k, (0.0, 0.0)))
    tr.step(obs(0.4))
    tr.step(obs(0.6))
    assert states(tr) == {0: "lost"}
    (e,) = tr.step(obs(0.7, (0.02, 0.0)))
    assert (e.track_id, e.state, e.det_index) == (0, "confirmed", 0)
    tr.step(obs(2.5))  # 1.8 s unseen in one step
    assert states(tr) == {}


def test_same_stamp_twice_and_decreasing_stamps():
    tr = UkfTracker()
    tr.step(obs(0.0, (0.0, 0.0)))
    tr.step(obs(0.0, (0.0, 0.0)))  # dt = 0 is fine
    with pytest.raises(TrackingError, match="must not decrease"):
        tr.step(obs(-0.1))


def test_two_targets_crossing_keep_their_ids():
    # two people walk towards each other along x, 0.4 m apart in y; 10 % of frames miss one of them
    rng = np.random.default_rng(0)
    frames, truth = [], []
    for k in range(80):
        t = 0.1 * k
        a, b = np.array([-4.0 + t, 0.2]), np.array([4.0 - t, -0.2])
        truth.append({0: a, 1: b})
        pts = [p + rng.normal(0, 0.03, 2) for p in (a, b) if rng.random() > 0.1]
        frames.append(obs(t, *[tuple(p) for p in pts], sigma=0.03))
    res = track_sequence(UkfTracker(), frames)
    tracks = res.tracks()
    assert len(tracks) == 2
    for tid, pts in tracks.items():
        xs = np.array([p.xy for _, p in pts])
        assert np.ptp(np.sign(xs[:, 1])) == 0, f"track {tid} changed sides"


def test_birth_suppressed_next_to_a_confirmed_track_and_gate_blocks_jumps():
    cfg = UkfTrackerConfig(birth_min_separation_m=0.3)
    tr = UkfTracker(config=cfg)
    for k in range(4):
        tr.step(obs(0.1 * k, (0.0, 0.0)))
    # a duplicate 0.2 m away starts nothing, a person 1 m away starts a tentative track
    tr.step(obs(0.4, (0.0, 0.0), (0.2, 0.0), (1.0, 0.0)))
    assert sorted(states(tr).values()) == ["confirmed", "tentative"]
    # with 5 cm noise, a detection 1.5 m off the prediction is outside the gate
    (e,) = tr.step(obs(0.5, (1.5, 1.5)))
    assert (e.track_id, e.det_index) == (0, -1)


def test_measurement_noise_comes_from_each_observation():
    def after(sigma: float) -> float:
        tr = UkfTracker(config=UkfTrackerConfig(confirm_hits=1, confirm_window_s=0.0))
        tr.step(obs(0.0, (0.0, 0.0), sigma=0.05))
        (e,) = tr.step(obs(0.1, (0.1, 0.0), sigma=sigma))
        return float(e.xy[0])

    assert after(0.01) > after(0.05) > after(0.5)
    assert after(0.01) == pytest.approx(0.1, abs=0.01)


def test_track_sequence_reports_coasting_only_on_request():
    frames = [obs(0.1 * k, (0.0, 0.0)) for k in range(4)] + [obs(0.5)]
    plain = track_sequence(UkfTracker(), frames)
    coasting = track_sequence(UkfTracker(), frames, include_coasting=True)
    assert [len(f.points) for f in plain] == [0, 0, 1, 1, 0]
    assert [len(f.points) for f in coasting] == [0, 0, 1, 1, 1]
    assert coasting.frames[-1].points[0].det_index == -1


def test_appearance_gate_prevents_swaps_between_close_people(sim):
    # seed 3: three of the simulated walkers pass within a few cm of each other (a real crowd's worst case)
    scene = sim.random_scene(4, 40.0, seed=3)
    sim.occlude(scene, 0, 10.0, 1.5)
    det = sim.detect(scene, seed=13)
    plain = track_sequence(UkfTracker(), det.observations)
    cfg = UkfTrackerConfig(appearance_gate=15.0, appearance_weight=0.1)
    with_app = track_sequence(UkfTracker(config=cfg), det.observations)
    n_plain, _ = sim.id_switches(plain, det.owner)
    n_app, _ = sim.id_switches(with_app, det.owner)
    assert n_app < n_plain


def test_an_observation_is_compared_with_where_the_track_was_when_it_was_measured():
    # a walker at 1.5 m/s seen by a sweeping scanner: every other frame's detection was measured 75 ms
    # after the frame's stamp, the last one 0.3 s after it (a scan far off the camera frame), 0.45 m ahead
    # of where the walker was at that stamp: taken at its time it is theirs, taken at the stamp it is gated
    # out and the track coasts
    def last_det_index(with_times: bool) -> int:
        tr = UkfTracker()
        det = -2
        for k in range(40):
            t, dt = 0.1 * k, (0.0, 0.075)[k % 2] if k < 39 else 0.3
            o = obs(t, (1.5 * (t + dt), 0.0), sigma=0.03)
            if with_times:
                o = replace(o, dt_s=np.array([dt]))
            for e in tr.step(o):  # none while tentative
                det = e.det_index
        return det

    assert last_det_index(True) == 0
    assert last_det_index(False) == -1
