"""Pass one looks at the quiet part of the panorama less often (``LabelOptions.quiet_view_period_s``)."""

from __future__ import annotations

import threading
import time
from pathlib import Path

import numpy as np
import pytest

import studio.detect.image as image_detectors
from studio.detect.image import ImageDetections
from studio.io import load_rig
from studio.pipeline import LabelOptions
from studio.pipeline.perceive import QuietViews, perceive

W = 360  # one column per degree
MS = 1_000_000


def _box(u1: float, u2: float) -> np.ndarray:
    return np.array([[u1, 100.0, u2, 150.0]])


def test_whole_panorama_every_period_and_at_the_start():
    q = QuietViews(0.4, margin_deg=0.0)
    looks = []
    for n in range(8):  # images every 0.2 s, each detection finishes before the next starts
        looks.append(q.start(n * 200 * MS, W))
        q.finish(_box(100, 110))
    whole = [c is None for c in looks]
    # the first three cannot know yet (up to two detections may still run), then every other one
    assert whole == [True, True, True, False, True, False, True, False]
    assert (q.whole, q.partial) == (5, 3)


def test_partial_look_uses_only_detections_three_back_and_recent():
    q = QuietViews(10.0, recent_s=1.0, margin_deg=5.0)
    for n in range(6):
        q.start(n * 200 * MS, W)
        q.finish(_box(10 * n, 10 * n + 4))
    # started: detection 6; 4 and 5 may still run (their boxes are ignored), 1 … 3 lie within 1 s before it
    cols = q.start(6 * 200 * MS, W)
    assert cols is not None
    assert cols.shape == (W,)
    on = set(np.flatnonzero(cols).tolist())
    for n in (1, 2, 3):
        assert set(range(10 * n - 5, 10 * n + 4 + 5)) <= on
    assert not on & set(range(40, 60))  # detections 4 and 5
    assert not on & set(range(5))  # detection 0: 1.2 s before
    assert 45 not in on


def test_partial_look_wraps_the_seam_and_can_be_empty():
    q = QuietViews(10.0, margin_deg=10.0)
    for n in range(3):
        q.start(n * 200 * MS, W)
        q.finish(_box(355, 362) if n == 0 else np.zeros((0, 4)))
    cols = q.start(600 * MS, W)
    assert cols is not None
    assert cols[[350, 0, 10]].all()
    assert not cols[[20, 340]].any()
    q.finish(np.zeros((0, 4)))
    for n in range(4, 7):
        q.start(n * 200 * MS, W)
        q.finish(np.zeros((0, 4)))
    assert not q.start(1400 * MS, W).any()  # nobody seen lately: no view needs to run


class _Seer:
    """A detector that can look at part of the panorama: it takes 0–40 ms at random and finds one person
    at columns 40–45 % of the width whenever it looks there."""

    looks_at_columns = True
    thread_safe = True

    def __init__(self, seed: int) -> None:
        self.rng = np.random.default_rng(seed)
        self.lock = threading.Lock()
        self.looks: dict[float, np.ndarray | None] = {}

    def detect(self, pano: np.ndarray, *, columns: np.ndarray | None = None) -> ImageDetections:
        with self.lock:
            wait = float(self.rng.uniform(0.0, 0.04))
            self.looks[float(pano.mean())] = None if columns is None else columns.copy()
        time.sleep(wait)
        h, w = pano.shape[:2]
        u1, u2 = w * 0.4, w * 0.45
        seen = columns is None or columns[int(u1) : int(u2)].any()
        box = np.array([[u1, h * 0.3, u2, h * 0.7]]) if seen else np.zeros((0, 4))
        return ImageDetections(box, np.full(len(box), 0.9), None, w, h)


def _run(recording: Path, monkeypatch: pytest.MonkeyPatch, seed: int, **options: float) -> tuple:
    det = _Seer(seed)
    monkeypatch.setattr(image_detectors, "get_image_detector", lambda *a, **k: det)
    frames, info = perceive(
        recording / "recording.mcap", load_rig(recording / "rig.yaml"), LabelOptions(**options)
    )
    return det, frames, info


def test_pass_one_looks_where_people_were_and_is_the_same_on_every_run(recording, monkeypatch):
    det, frames, info = _run(recording, monkeypatch, 0)
    looks = list(det.looks.values())
    partial = [c for c in looks if c is not None]
    assert info["image_looks"] == {"whole": len(looks) - len(partial), "partial": len(partial)}
    assert len(partial) >= len(looks) // 2 - 2  # every other image from the fourth on
    w = len(partial[0])
    for c in partial:  # the person's columns (and a margin) are looked at, the far side is not
        assert c[int(w * 0.4) : int(w * 0.45)].all()
        assert not c[int(w * 0.9)]
    assert all(len(f.image) == 1 for f in frames if f.image is not None)  # nobody missed
    # other timings, same choice of columns: it never depends on which detection finished first
    det2, _, _ = _run(recording, monkeypatch, 1)
    assert det2.looks.keys() == det.looks.keys()
    for k, c in det.looks.items():
        assert (c is None and det2.looks[k] is None) or np.array_equal(c, det2.looks[k])


def test_quiet_views_off_looks_at_everything(recording, monkeypatch):
    det, _, info = _run(recording, monkeypatch, 0, quiet_view_period_s=0.2)
    assert info["image_looks"] is None
    assert all(c is None for c in det.looks.values())


def test_a_detection_lag_places_back_must_have_finished():
    q = QuietViews(10.0, lag=3)
    for n in range(3):
        q.start(n * 200 * MS, W)
    with pytest.raises(RuntimeError, match="is still running"):
        q.start(600 * MS, W)
