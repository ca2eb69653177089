"""Shared fixtures for end-to-end tests: one short simulated recording per session."""

from __future__ import annotations

from pathlib import Path

import pytest

SCENARIO = ("moving", 15.0, 13)  # scenario, seconds, seed (one person enters mid-run: review points)


@pytest.fixture(scope="session")
def sim_moving(tmp_path_factory: pytest.TempPathFactory) -> Path:
    from studio.sim import simulate

    out = tmp_path_factory.mktemp("sim") / "moving"
    scenario, seconds, seed = SCENARIO
    simulate(scenario, out=out, seconds=seconds, seed=seed)
    return out


@pytest.fixture(scope="session")
def shared_data() -> Path:
    data = Path(__file__).resolve().parents[2] / ".." / "shared" / "data" / "leg_tracker"
    if not data.is_dir():
        pytest.skip("../shared/data/leg_tracker is not present")
    return data.resolve()
