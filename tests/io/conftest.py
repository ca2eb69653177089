"""Fixtures of the studio.io tests."""

from __future__ import annotations

from pathlib import Path

import pytest
from io_testdata import write_synthetic


@pytest.fixture(scope="session")
def synthetic(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The synthetic camera + 2 lasers + odometry + TF recording (see io_testdata.write_synthetic)."""
    return write_synthetic(tmp_path_factory.mktemp("syn") / "recording.mcap")
