"""Shared fixtures of the pass-one tests."""

from __future__ import annotations

from pathlib import Path

import pytest


@pytest.fixture(scope="package")
def recording(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A 2 s simulated ``moving`` recording (camera, two lasers, odometry)."""
    from studio.sim import simulate

    out = tmp_path_factory.mktemp("sim") / "moving"
    simulate("moving", out=out, seconds=2.0, seed=3)
    return out
