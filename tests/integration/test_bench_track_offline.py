"""The offline-tracking scaling benchmark runs and its walkers are tracked as who they are."""

from __future__ import annotations

import sys

import numpy as np
from bench_loader import load_bench


def test_the_benchmark_prints_one_line_per_length(monkeypatch, capsys):
    bench = load_bench("bench_track_offline")
    monkeypatch.setattr(sys, "argv", ["bench_track_offline.py", "--minutes", "0.2", "0.3", "--people", "3"])
    bench.main()
    lines = capsys.readouterr().out.strip().splitlines()
    assert [line.split(":")[0] for line in lines] == [
        "0.2 min, 3 people, 120 frames",
        "0.3 min, 3 people, 180 frames",
    ]
    assert all(line.endswith(", 3 tracks") for line in lines)  # three walkers apart: three tracks


def test_walkers_are_seen_nine_times_in_ten():
    obs = load_bench("bench_track_offline").walkers(1.0, 4)
    assert len(obs) == 600
    seen = sum(len(o.xy) for o in obs) / (600 * 4)
    assert 0.85 < seen < 0.95
    described = sum(int(np.isfinite(o.appearance[:, 0]).sum()) for o in obs) / sum(len(o.xy) for o in obs)
    assert 0.4 < described < 0.6
