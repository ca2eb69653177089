"""``bench/bench_real_labels.py --every K``: a real bag as a scanner with K times coarser beams sees it."""

from __future__ import annotations

from pathlib import Path

import numpy as np
from bench_loader import load_bench

from studio.io import decode_scan, open_recording


def _scans(bag: Path) -> list[tuple[int, np.ndarray, float, float]]:
    out = []
    with open_recording(bag) as rec:
        for raw in rec.messages(["/training_scan"]):
            s = decode_scan(rec.decode(raw), raw.log_ns)
            out.append((s.stamp_ns, np.asarray(s.ranges), s.angle_min, s.angle_increment))
    return out


def _counts(bag: Path) -> dict[str, int]:
    with open_recording(bag) as rec:
        return {t: info.count for t, info in rec.topics.items()}


def test_thinned_bag_keeps_every_kth_beam_and_everything_else(shared_data: Path, tmp_path: Path) -> None:
    src = shared_data / "legs_labelled" / "positive_2_extracted.bag"
    dst = load_bench("bench_real_labels").thinned_bag(src, tmp_path / "thin.bag", 3)
    before, after = _scans(src), _scans(dst)
    assert len(after) == len(before) > 0
    for (t0, r0, a0, d0), (t1, r1, a1, d1) in zip(before, after, strict=True):
        assert t1 == t0
        np.testing.assert_array_equal(r1, r0[::3])
        assert a1 == a0
        assert np.isclose(d1, 3 * d0)
    assert _counts(dst) == _counts(src)


def test_a_bag_resampled_to_a_coarser_step_keeps_the_nearest_beams(shared_data: Path, tmp_path: Path) -> None:
    src = shared_data / "legs_labelled" / "positive_2_extracted.bag"
    dst = load_bench("bench_real_labels").thinned_bag(src, tmp_path / "half.bag", step_deg=0.5)
    for (t0, r0, a0, d0), (t1, r1, a1, d1) in zip(_scans(src), _scans(dst), strict=True):
        assert (t1, a1) == (t0, a0)
        assert np.isclose(d1, np.radians(0.5))
        keep = np.round(np.arange(len(r1)) * d1 / d0).astype(int)
        assert keep[-1] < len(r0) <= keep[-1] + d1 / d0 + 1
        np.testing.assert_array_equal(r1, r0[keep])
    assert _counts(dst) == _counts(src)
