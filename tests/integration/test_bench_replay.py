"""``bench/replay_tracking.py --handovers``: when an output track goes on with another person."""

from __future__ import annotations

import pytest
from bench_loader import load_bench

from studio.evaluate import evaluate
from studio.labels import LabelFrame, LabelPerson, LabelSet


def _frame(i: int, people: dict[int, tuple[float, float]]) -> LabelFrame:
    return LabelFrame(i, tuple(LabelPerson(pid, x, y) for pid, (x, y) in people.items()), stamp_ns=i * 10**8)


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
    assert "frame    10 track   7: person 1 -> 2 after 1 frames; person 1 gone" in out
    assert "frame    15 track   8: person 3 -> 4 after 1 frames; person 3 still there, 0.50 m away" in out
    assert "frame    17 track   8: person 4 -> 3 after 1 frames; person 4 still there, 0.50 m away" in out
