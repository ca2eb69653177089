"""Shared fixtures of the annotation tests: a small generated run (labels.jsonl written by studio.labels)."""

from __future__ import annotations

import math
from collections.abc import Callable
from pathlib import Path

import pytest

from studio.geometry.se import Pose2
from studio.labels import LabelFrame, LabelPerson, write_labels_jsonl

__all__ = ["build_run", "track_position"]


def track_position(k: int, n: int) -> tuple[float, float]:
    """Position of auto-label track ``k`` in frame ``n`` (base frame, metres): people far apart (> 1 m)."""
    return (1.0 + 2.0 * k + 0.01 * n, -1.0 + 0.5 * math.sin(0.1 * n + k))


def build_run(
    run_dir: Path,
    *,
    num_frames: int = 10,
    tracks: dict[int, tuple[int, int]] | None = None,
    start_ns: int = 1_700_000_000_000_000_000,
    dt_ns: int = 100_000_000,
) -> Path:
    """Write ``run_dir/labels.jsonl``: ``tracks`` = id → (first, last) frame (inclusive).

    Default tracks: id 1 in frames 0..9, id 2 in 0..4, id 5 in 3..9. The robot drives along x at
    0.1 m per frame and turns 0.01 rad per frame, so odom positions differ from base positions.
    """
    tracks = {1: (0, num_frames - 1), 2: (0, 4), 5: (3, num_frames - 1)} if tracks is None else tracks
    frames = []
    for n in range(num_frames):
        pose = Pose2(0.1 * n, 0.0, 0.01 * n)
        people = []
        for k, (a, b) in sorted(tracks.items()):
            if a <= n <= b:
                x, y = track_position(k, n)
                xo, yo = pose.apply((x, y))
                people.append(
                    LabelPerson(
                        id=k,
                        x=x,
                        y=y,
                        x_odom=float(xo),
                        y_odom=float(yo),
                        cov=((0.01, 0.0), (0.0, 0.01)),
                        source="fused",
                        box=(100.0 * k, 50.0, 100.0 * k + 40.0, 200.0),
                        score=0.9,
                    )
                )
        frames.append(
            LabelFrame(frame=n, people=tuple(people), stamp_ns=start_ns + n * dt_ns, robot_pose=pose)
        )
    run_dir.mkdir(parents=True, exist_ok=True)
    write_labels_jsonl(run_dir / "labels.jsonl", frames)
    return run_dir


@pytest.fixture
def run_dir(tmp_path: Path) -> Path:
    """A 10-frame run directory with the default tracks of :func:`build_run`."""
    return build_run(tmp_path / "run")


@pytest.fixture(name="make_run")
def make_run_fixture() -> Callable[..., Path]:
    """:func:`build_run` (tests use fixtures, not imports, so that no two ``conftest`` modules clash)."""
    return build_run


@pytest.fixture(name="track_xy")
def track_xy_fixture() -> Callable[[int, int], tuple[float, float]]:
    """:func:`track_position`."""
    return track_position
