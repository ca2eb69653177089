"""Atomic writers: all or nothing, and files get the usual permissions."""

from __future__ import annotations

import os
import stat

import pytest

from studio.atomic import atomic_dir, atomic_write_text


def test_file_mode_follows_umask(tmp_path) -> None:
    old = os.umask(0o022)
    try:
        atomic_write_text(tmp_path / "a.txt", "x")
    finally:
        os.umask(old)
    assert stat.S_IMODE((tmp_path / "a.txt").stat().st_mode) == 0o644
    assert not [p for p in tmp_path.iterdir() if p.name.startswith(".")]


def test_atomic_dir_keeps_old_content_on_failure(tmp_path) -> None:
    out = tmp_path / "run"
    with atomic_dir(out) as d:
        (d / "labels.yaml").write_text("old")

    def half_written() -> None:
        with atomic_dir(out) as d:
            (d / "labels.yaml").write_text("half")
            raise RuntimeError("boom")

    with pytest.raises(RuntimeError):
        half_written()
    assert (out / "labels.yaml").read_text() == "old"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["run"]
    with atomic_dir(out) as d:
        (d / "labels.yaml").write_text("new")
    assert (out / "labels.yaml").read_text() == "new"
