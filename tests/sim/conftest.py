"""Shared short simulations (a few seconds each, built once per test session)."""

from __future__ import annotations

import pytest

from studio.sim import SimResult, simulate


@pytest.fixture(scope="session")
def moving_sim(tmp_path_factory: pytest.TempPathFactory) -> SimResult:
    """2.5 s of the ``moving`` scenario, seed 3 (the robot starts driving after 1 s)."""
    return simulate("moving", out=tmp_path_factory.mktemp("sim") / "moving", seconds=2.5, seed=3)
